/// @file rp_io.c
/// Sidecar, samples and ground truth of a recording (see rp_io.h).
#include "rp_io.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

static char *rp_slurp(const char *path, size_t *len_out, char *err, size_t errlen)
{
    FILE *f = fopen(path, "rb");
    if (f == NULL) {
        (void)snprintf(err, errlen, "%s: cannot open", path);
        return NULL;
    }
    char *buf = NULL;
    if ((fseeko(f, 0, SEEK_END) == 0)) {
        const off_t len = ftello(f);
        if ((len >= 0) && (len < (off_t)(64 << 20)) && (fseeko(f, 0, SEEK_SET) == 0)) {
            buf = malloc((size_t)len + 1u);
            if ((buf != NULL) && (fread(buf, 1u, (size_t)len, f) == (size_t)len)) {
                buf[len] = '\0';
                *len_out = (size_t)len;
            } else {
                free(buf);
                buf = NULL;
            }
        }
    }
    (void)fclose(f);
    if (buf == NULL) {
        (void)snprintf(err, errlen, "%s: cannot read (or larger than 64 MB)", path);
    }
    return buf;
}

/* Copies at most `max` bytes of s (n bytes) into dst as printable ASCII, other bytes as \xNN. */
static void rp_printable(const char *s, size_t n, size_t max, char *dst, size_t dstlen)
{
    size_t o = 0u;
    dst[0] = '\0';
    for (size_t i = 0u; (i < n) && (i < max) && (o + 5u < dstlen); ++i) {
        const unsigned char c = (unsigned char)s[i];
        const int w = ((c >= 0x20u) && (c < 0x7fu) && (c != '\\'))
                          ? snprintf(&dst[o], dstlen - o, "%c", (char)c)
                          : snprintf(&dst[o], dstlen - o, "\\x%02x", (unsigned)c);
        o += (w > 0) ? (size_t)w : 0u;
    }
}

static int rp_is_space(char c)
{
    return (c == ' ') || (c == '\t') || (c == '\n') || (c == '\r');
}

/* The key whose value starts at text[pos] ("key": <pos>), or "" if pos is not after a key. */
static void rp_key_before(const char *text, size_t pos, char *key, size_t keylen)
{
    key[0] = '\0';
    size_t i = pos;
    while ((i > 0u) && rp_is_space(text[i - 1u])) {
        --i;
    }
    if ((i == 0u) || (text[i - 1u] != ':')) {
        return;
    }
    --i;
    while ((i > 0u) && rp_is_space(text[i - 1u])) {
        --i;
    }
    if ((i < 2u) || (text[i - 1u] != '"')) {
        return;
    }
    const size_t end = i - 1u; /* the closing quote */
    size_t start = end;
    while ((start > 0u) && (text[start - 1u] != '"')) {
        --start;
    }
    if (start > 0u) {
        rp_printable(&text[start], end - start, 48u, key, keylen);
    }
}

/* Parses the sidecar text (len bytes, NUL-terminated) into a JSON object, or
 * NULL with "path: not a JSON object: ..." in err: the byte offset (0-based),
 * line and column (1-based) of the first byte the parser could not take, the
 * key whose value it was in, and what is there. Reads `text` only before it
 * returns; the caller may free it right after. */
static cJSON *rp_parse_object(const char *path, const char *text, size_t len, char *err, size_t errlen)
{
    if (len == 0u) {
        (void)snprintf(err, errlen, "%s: empty file", path);
        return NULL;
    }
    if (strlen(text) < len) {
        (void)snprintf(err, errlen, "%s: not a JSON object: NUL byte at byte offset %zu", path, strlen(text));
        return NULL;
    }
    const char *end = NULL;
    cJSON *root = cJSON_ParseWithOpts(text, &end, 0);
    size_t pos = ((end != NULL) && (end >= text) && (end <= text + len)) ? (size_t)(end - text) : len;
    char what[96];
    if (root != NULL) {
        while ((pos < len) && rp_is_space(text[pos])) {
            ++pos;
        }
        if (pos >= len) {
            if (cJSON_IsObject(root)) {
                return root;
            }
            (void)snprintf(err, errlen, "%s: not a JSON object: the top level is %s", path,
                           cJSON_IsArray(root) ? "an array" : (cJSON_IsString(root) ? "a string" : "a scalar"));
            cJSON_Delete(root);
            return NULL;
        }
        cJSON_Delete(root);
        (void)snprintf(what, sizeof what, "text after the JSON value");
    } else {
        const char *p = &text[(pos < len) ? pos : len];
        const char *q = ((*p == '-') || (*p == '+')) ? p + 1 : p;
        if (pos >= len) {
            (void)snprintf(what, sizeof what, "unexpected end of file");
        } else if ((strncmp(q, "NaN", 3u) == 0) || (strncmp(q, "nan", 3u) == 0)) {
            (void)snprintf(what, sizeof what, "NaN is not a JSON number");
        } else if ((strncmp(q, "Infinity", 8u) == 0) || (strncmp(q, "inf", 3u) == 0)) {
            (void)snprintf(what, sizeof what, "Infinity is not a JSON number");
        } else {
            char c[8];
            rp_printable(p, 1u, 1u, c, sizeof c);
            (void)snprintf(what, sizeof what, "unexpected character '%s'", c);
        }
    }
    size_t line = 1u;
    size_t col = 1u;
    for (size_t i = 0u; i < pos; ++i) {
        line += (text[i] == '\n') ? 1u : 0u;
        col = (text[i] == '\n') ? 1u : col + 1u;
    }
    char key[200];
    rp_key_before(text, pos, key, sizeof key);
    (void)snprintf(err, errlen,
                   "%s: not a JSON object: invalid JSON at byte offset %zu (line %zu, column %zu)%s%s%s: %s", path,
                   pos, line, col, (key[0] != '\0') ? ", in \"" : "", key, (key[0] != '\0') ? "\"" : "", what);
    return NULL;
}

static int rp_number(const cJSON *obj, const char *name, int required, double *v, const char *path, char *err,
                     size_t errlen)
{
    const cJSON *it = cJSON_GetObjectItemCaseSensitive(obj, name);
    if (it == NULL) {
        if (required) {
            (void)snprintf(err, errlen, "%s: field \"%s\": missing", path, name);
            return -1;
        }
        return 1;
    }
    if (!cJSON_IsNumber(it) || !isfinite(it->valuedouble)) {
        (void)snprintf(err, errlen, "%s: field \"%s\": not a finite number", path, name);
        return -1;
    }
    *v = it->valuedouble;
    return 0;
}

static void rp_dirname(const char *path, char *dir, size_t len)
{
    (void)snprintf(dir, len, "%s", path);
    char *slash = strrchr(dir, '/');
    if (slash == NULL) {
        (void)snprintf(dir, len, ".");
    } else if (slash == dir) {
        dir[1] = '\0';
    } else {
        *slash = '\0';
    }
}

/* The "intervals" list of the simulator export. */
static int rp_parse_intervals(const cJSON *list, const char *path, rp_recording_t *rec, uint32_t channel,
                              char *err, size_t errlen)
{
    rec->n_intervals = 0u;
    const cJSON *it = NULL;
    cJSON_ArrayForEach(it, list)
    {
        char where[RP_PATH_MAX + 32u];
        (void)snprintf(where, sizeof where, "%s: intervals[%u]", path, rec->n_intervals);
        if (rec->n_intervals >= RP_MAX_INTERVALS) {
            (void)snprintf(err, errlen, "%s: more than %u intervals", path, RP_MAX_INTERVALS);
            return -1;
        }
        rp_interval_t *iv = &rec->iv[rec->n_intervals];
        double start = 0.0, n = 0.0;
        if ((rp_number(it, "start_sample", 1, &start, where, err, errlen) != 0) ||
            (rp_number(it, "num_samples", 1, &n, where, err, errlen) != 0)) {
            return -1;
        }
        if ((start < 0.0) || (n < 1.0) || (start + n > (double)rec->total_samples)) {
            (void)snprintf(err, errlen, "%s: start_sample/num_samples outside the %llu samples of %s", where,
                           (unsigned long long)rec->total_samples, rec->bin_path);
            return -1;
        }
        iv->start_sample = (uint64_t)start;
        iv->num_samples = (uint64_t)n;
        iv->duration_s = (double)iv->num_samples / rec->fs_hz;
        (void)rp_number(it, "duration_s", 0, &iv->duration_s, where, err, errlen);
        iv->depth_um = NAN;
        const cJSON *dep = cJSON_GetObjectItemCaseSensitive(it, "depth_um");
        const cJSON *dc = cJSON_IsArray(dep) ? cJSON_GetArrayItem(dep, (int)channel) : dep;
        if (cJSON_IsNumber(dc)) {
            iv->depth_um = dc->valuedouble;
        }
        rec->n_intervals++;
    }
    return 0;
}

static void rp_cut_intervals(rp_recording_t *rec, double interval_s)
{
    const uint64_t len = (uint64_t)llround(interval_s * rec->fs_hz);
    rec->n_intervals = 0u;
    for (uint64_t s = 0u; (len > 0u) && (s + len / 2u <= rec->total_samples) && (rec->n_intervals < RP_MAX_INTERVALS);
         s += len) {
        rp_interval_t *iv = &rec->iv[rec->n_intervals++];
        iv->start_sample = s;
        iv->num_samples = (s + len <= rec->total_samples) ? len : rec->total_samples - s;
        iv->duration_s = (double)iv->num_samples / rec->fs_hz;
        iv->depth_um = NAN;
    }
}

static int rp_header(const cJSON *root, const char *path, rp_recording_t *rec, char *err, size_t errlen)
{
    double nch = 0.0;
    if ((rp_number(root, "sampling_frequency", 1, &rec->fs_hz, path, err, errlen) != 0) ||
        (rp_number(root, "num_channels", 1, &nch, path, err, errlen) != 0)) {
        return -1;
    }
    if (!(rec->fs_hz >= 1000.0) || !(rec->fs_hz <= 200000.0)) {
        (void)snprintf(err, errlen, "%s: field \"sampling_frequency\": %g Hz outside 1000..200000", path, rec->fs_hz);
        return -1;
    }
    if ((nch < 1.0) || (nch > 1024.0) || (floor(nch) < nch)) {
        (void)snprintf(err, errlen, "%s: field \"num_channels\": must be an integer 1..1024", path);
        return -1;
    }
    rec->n_channels = (uint32_t)nch;
    const cJSON *dt = cJSON_GetObjectItemCaseSensitive(root, "dtype");
    if ((dt == NULL) || !cJSON_IsString(dt) || (strcmp(dt->valuestring, "int16") != 0)) {
        (void)snprintf(err, errlen, "%s: field \"dtype\": missing or not \"int16\"", path);
        return -1;
    }
    rec->gain_uv = 1.0;
    if (rp_number(root, "gain_uV", 0, &rec->gain_uv, path, err, errlen) < 0) {
        return -1;
    }
    if (!(rec->gain_uv > 0.0)) {
        (void)snprintf(err, errlen, "%s: field \"gain_uV\": must be > 0", path);
        return -1;
    }
    return 0;
}

static int rp_size_binary(const cJSON *root, rp_recording_t *rec, char *err, size_t errlen)
{
    const cJSON *file = cJSON_GetObjectItemCaseSensitive(root, "file");
    const char *name = (cJSON_IsString(file) && (file->valuestring[0] != '\0')) ? file->valuestring : "recording.bin";
    if (strlen(rec->dir) + strlen(name) + 2u > sizeof rec->bin_path) {
        (void)snprintf(err, errlen, "path of the sample file is longer than %zu characters", sizeof rec->bin_path);
        return -1;
    }
    memcpy(rec->bin_path, rec->dir, strlen(rec->dir));
    rec->bin_path[strlen(rec->dir)] = '/';
    memcpy(&rec->bin_path[strlen(rec->dir) + 1u], name, strlen(name) + 1u);
    struct stat sb;
    if (stat(rec->bin_path, &sb) != 0) {
        (void)snprintf(err, errlen, "%s: cannot open the sample file", rec->bin_path);
        return -1;
    }
    rec->total_samples = (uint64_t)sb.st_size / (2u * (uint64_t)rec->n_channels);
    if (rec->total_samples == 0u) {
        (void)snprintf(err, errlen, "%s: no samples", rec->bin_path);
        return -1;
    }
    return 0;
}

int rp_read_recording(const char *json_path, double interval_s, uint32_t channel, rp_recording_t *rec, char *err,
                      size_t errlen)
{
    memset(rec, 0, sizeof *rec);
    size_t len = 0u;
    char *text = rp_slurp(json_path, &len, err, errlen);
    if (text == NULL) {
        return -1;
    }
    cJSON *root = rp_parse_object(json_path, text, len, err, errlen);
    free(text); /* the error message is complete: nothing points into the text any more */
    if (root == NULL) {
        return -1;
    }
    rp_dirname(json_path, rec->dir, sizeof rec->dir);
    int rc = rp_header(root, json_path, rec, err, errlen);
    if ((rc == 0) && (channel >= rec->n_channels)) {
        (void)snprintf(err, errlen, "%s: --channel %u but the recording has %u channel(s)", json_path, channel,
                       rec->n_channels);
        rc = -1;
    }
    if (rc == 0) {
        rc = rp_size_binary(root, rec, err, errlen);
    }
    const cJSON *list = cJSON_GetObjectItemCaseSensitive(root, "intervals");
    if ((rc == 0) && cJSON_IsArray(list) && (cJSON_GetArraySize(list) > 0)) {
        rc = rp_parse_intervals(list, json_path, rec, channel, err, errlen);
    } else if (rc == 0) {
        rp_cut_intervals(rec, interval_s);
    }
    cJSON_Delete(root);
    if ((rc == 0) && (rec->n_intervals == 0u)) {
        (void)snprintf(err, errlen, "%s: no interval of %g s fits in %llu samples", json_path, interval_s,
                       (unsigned long long)rec->total_samples);
        rc = -1;
    }
    return rc;
}

int rp_read_interval(const rp_recording_t *rec, uint32_t k, uint32_t ch, int16_t *x, char *err, size_t errlen)
{
    const rp_interval_t *iv = &rec->iv[k];
    FILE *f = fopen(rec->bin_path, "rb");
    if (f == NULL) {
        (void)snprintf(err, errlen, "%s: cannot open", rec->bin_path);
        return -1;
    }
    const size_t frame = rec->n_channels;
    int16_t *buf = malloc(4096u * frame * sizeof *buf);
    int rc = ((buf != NULL) && (fseeko(f, (off_t)(iv->start_sample * frame * 2u), SEEK_SET) == 0)) ? 0 : -1;
    for (uint64_t done = 0u; (rc == 0) && (done < iv->num_samples);) {
        const size_t want = (size_t)((iv->num_samples - done < 4096u) ? iv->num_samples - done : 4096u);
        if (fread(buf, 2u * frame, want, f) != want) {
            rc = -1;
            break;
        }
        for (size_t i = 0u; i < want; ++i) {
            const uint8_t *b = (const uint8_t *)&buf[i * frame + ch];
            x[done + i] = (int16_t)(uint16_t)((uint16_t)b[0] | (uint16_t)((uint16_t)b[1] << 8)); /* little-endian */
        }
        done += want;
    }
    if (rc != 0) {
        (void)snprintf(err, errlen, "%s: short read in interval %u", rec->bin_path, k);
    }
    free(buf);
    (void)fclose(f);
    return rc;
}
