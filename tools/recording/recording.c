/// @file recording.c
/// Sidecar and samples of a raw recording (see recording.h).
#include "recording.h"

#include <cjson/cJSON.h>
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

_Static_assert(sizeof(float) == 4u, "float32 samples are read into float");

#define REC_JSON_MAX ((off_t)64 << 20)  ///< a sidecar larger than this is not one
#define REC_INT_MAX 9007199254740992.0  ///< 2^53: integers a JSON number holds exactly

/// Where messages go: "path: ..." into err.
typedef struct {
    const char *path;
    char *err;
    size_t errlen;
} rec_ctx_t;

__attribute__((format(printf, 3, 4))) static md_status_t rec_fail(const rec_ctx_t *c, md_status_t st, const char *fmt,
                                                                  ...)
{
    if ((c->err == NULL) || (c->errlen == 0u)) {
        return st;
    }
    char msg[REC_ERR_MAX];
    const int n = snprintf(msg, sizeof msg, "%s: ", c->path);
    if ((n > 0) && ((size_t)n < sizeof msg)) {
        va_list ap;
        va_start(ap, fmt);
        (void)vsnprintf(&msg[n], sizeof msg - (size_t)n, fmt, ap);
        va_end(ap);
    }
    /* One line: control bytes of a path (a "file" field may hold any) as \xNN. */
    size_t o = 0u;
    for (size_t i = 0u; (msg[i] != '\0') && (o + 1u < c->errlen); ++i) {
        const unsigned char ch = (unsigned char)msg[i];
        if ((ch >= 0x20u) && (ch != 0x7fu)) {
            c->err[o++] = (char)ch;
        } else if (o + 5u < c->errlen) {
            o += (size_t)snprintf(&c->err[o], c->errlen - o, "\\x%02x", (unsigned)ch);
        } else {
            break;
        }
    }
    c->err[o] = '\0';
    return st;
}

const char *rec_dtype_name(rec_dtype_t dtype)
{
    return (dtype == REC_DTYPE_FLOAT32) ? "float32" : "int16";
}

/* ------------------------------------------------------------ the text */

/* The whole file, NUL-terminated (heap), its length in *len. */
static char *rec_slurp(const rec_ctx_t *c, size_t *len, md_status_t *st)
{
    struct stat sb;
    if (stat(c->path, &sb) != 0) {
        *st = rec_fail(c, MD_E_IO, "cannot open: %s", strerror(errno));
        return NULL;
    }
    if (!S_ISREG(sb.st_mode)) {
        *st = rec_fail(c, MD_E_IO, "not a regular file");
        return NULL;
    }
    FILE *f = fopen(c->path, "rb");
    if (f == NULL) {
        *st = rec_fail(c, MD_E_IO, "cannot open: %s", strerror(errno));
        return NULL;
    }
    char *buf = NULL;
    off_t n = -1;
    if ((fseeko(f, 0, SEEK_END) == 0) && ((n = ftello(f)) >= 0) && (n <= REC_JSON_MAX) &&
        (fseeko(f, 0, SEEK_SET) == 0)) {
        buf = malloc((size_t)n + 1u);
        if ((buf != NULL) && (fread(buf, 1u, (size_t)n, f) == (size_t)n)) {
            buf[n] = '\0';
            *len = (size_t)n;
        } else {
            free(buf);
            buf = NULL;
        }
    }
    (void)fclose(f);
    if (buf == NULL) {
        *st = (n > REC_JSON_MAX)
                  ? rec_fail(c, MD_E_FRAME, "%lld bytes: larger than a sidecar can be (64 MiB)", (long long)n)
                  : rec_fail(c, MD_E_IO, "cannot read");
    }
    return buf;
}

/* At most `max` bytes of s (n bytes) as printable ASCII, other bytes as \xNN. */
static void rec_printable(const char *s, size_t n, size_t max, char *dst, size_t dstlen)
{
    size_t o = 0u;
    dst[0] = '\0';
    for (size_t i = 0u; (i < n) && (i < max) && (o + 5u < dstlen); ++i) {
        const unsigned char ch = (unsigned char)s[i];
        const int w = ((ch >= 0x20u) && (ch < 0x7fu) && (ch != '\\') && (ch != '"'))
                          ? snprintf(&dst[o], dstlen - o, "%c", (char)ch)
                          : snprintf(&dst[o], dstlen - o, "\\x%02x", (unsigned)ch);
        o += (w > 0) ? (size_t)w : 0u;
    }
    if (n > max) {
        (void)snprintf(&dst[o], dstlen - o, "...");
    }
}

/* A strict JSON syntax check (RFC 8259) in front of cJSON, which accepts more
 * (any byte <= 32 as space, "+1", "01", raw control bytes in strings) and
 * whose error position can be a byte past the fault. It finds the first byte
 * that cannot continue a JSON text and says why. */
#define REC_JSON_DEPTH_MAX 64u

typedef struct {
    const char *t;
    size_t len;
    size_t pos;
    const char *why;  ///< set at the first error
    char what[64];    ///< the unexpected character, for why
    const char *key;  ///< key of the member whose value holds the error (NULL: none)
    size_t key_len;
    int after;  ///< 1: the error follows the value of `key` instead
} rec_json_t;

static int rec_is_space(char ch)
{
    return (ch == ' ') || (ch == '\t') || (ch == '\n') || (ch == '\r');
}

static void rec_json_ws(rec_json_t *j)
{
    while ((j->pos < j->len) && rec_is_space(j->t[j->pos])) {
        j->pos++;
    }
}

static int rec_json_fail(rec_json_t *j, const char *key, size_t key_len, const char *why)
{
    j->why = why;
    j->key = key;
    j->key_len = key_len;
    return -1;
}

/* Error at j->pos: what is there, and what was expected. */
static int rec_json_unexpected(rec_json_t *j, const char *key, size_t key_len, const char *expected)
{
    if (j->pos >= j->len) {
        return rec_json_fail(j, key, key_len, "unexpected end of file");
    }
    const char *p = &j->t[j->pos];
    const char *q = ((*p == '-') || (*p == '+')) ? p + 1 : p;
    if ((strncmp(q, "NaN", 3u) == 0) || (strncmp(q, "nan", 3u) == 0)) {
        return rec_json_fail(j, key, key_len, "NaN is not a JSON number");
    }
    if ((strncmp(q, "Infinity", 8u) == 0) || (strncmp(q, "inf", 3u) == 0)) {
        return rec_json_fail(j, key, key_len, "Infinity is not a JSON number");
    }
    char ch[8];
    rec_printable(p, 1u, 1u, ch, sizeof ch);
    (void)snprintf(j->what, sizeof j->what, "unexpected character '%s', expected %s", ch, expected);
    return rec_json_fail(j, key, key_len, j->what);
}

static int rec_json_string(rec_json_t *j, const char *key, size_t key_len)
{
    j->pos++; /* the opening quote */
    while (j->pos < j->len) {
        const unsigned char ch = (unsigned char)j->t[j->pos];
        if (ch == '"') {
            j->pos++;
            return 0;
        }
        if (ch < 0x20u) {
            return rec_json_fail(j, key, key_len, "control character in a string (write it as an escape)");
        }
        if (ch == '\\') {
            j->pos++;
            const char e = (j->pos < j->len) ? j->t[j->pos] : '\0';
            int ok = (e != '\0') && (strchr("\"\\/bfnrtu", e) != NULL);
            for (size_t h = 1u; ok && (e == 'u') && (h <= 4u); ++h) {
                const char x = (j->pos + h < j->len) ? j->t[j->pos + h] : '\0';
                ok = ((x >= '0') && (x <= '9')) || ((x >= 'a') && (x <= 'f')) || ((x >= 'A') && (x <= 'F'));
            }
            if (!ok) {
                j->pos--;
                return rec_json_fail(j, key, key_len, "invalid escape in a string");
            }
            j->pos += (e == 'u') ? 5u : 1u;
            continue;
        }
        j->pos++;
    }
    return rec_json_fail(j, key, key_len, "unexpected end of file in a string");
}

static int rec_json_digits(rec_json_t *j, const char *key, size_t key_len)
{
    if ((j->pos >= j->len) || (j->t[j->pos] < '0') || (j->t[j->pos] > '9')) {
        return rec_json_unexpected(j, key, key_len, "a digit");
    }
    while ((j->pos < j->len) && (j->t[j->pos] >= '0') && (j->t[j->pos] <= '9')) {
        j->pos++;
    }
    return 0;
}

static int rec_json_number(rec_json_t *j, const char *key, size_t key_len)
{
    const size_t start = j->pos;
    if (j->t[j->pos] == '-') {
        j->pos++;
        if ((j->pos < j->len) && ((j->t[j->pos] == 'I') || (j->t[j->pos] == 'N'))) {
            j->pos = start;
            return rec_json_unexpected(j, key, key_len, "a value");
        }
    }
    if ((j->pos < j->len) && (j->t[j->pos] == '0') && (j->pos + 1u < j->len) && (j->t[j->pos + 1u] >= '0') &&
        (j->t[j->pos + 1u] <= '9')) {
        return rec_json_fail(j, key, key_len, "a number cannot start with 0 followed by digits");
    }
    if (rec_json_digits(j, key, key_len) != 0) {
        return -1;
    }
    if ((j->pos < j->len) && (j->t[j->pos] == '.')) {
        j->pos++;
        if (rec_json_digits(j, key, key_len) != 0) {
            return -1;
        }
    }
    if ((j->pos < j->len) && ((j->t[j->pos] == 'e') || (j->t[j->pos] == 'E'))) {
        j->pos++;
        j->pos += ((j->pos < j->len) && ((j->t[j->pos] == '+') || (j->t[j->pos] == '-'))) ? 1u : 0u;
        return rec_json_digits(j, key, key_len);
    }
    return 0;
}

static int rec_json_value(rec_json_t *j, unsigned depth, const char *key, size_t key_len);

/* An object or array at j->pos; key: the member holding it. */
static int rec_json_container(rec_json_t *j, unsigned depth, const char *key, size_t key_len)
{
    const char close = (j->t[j->pos] == '{') ? '}' : ']';
    if (depth >= REC_JSON_DEPTH_MAX) {
        return rec_json_fail(j, key, key_len, "nested more than 64 levels deep");
    }
    j->pos++;
    rec_json_ws(j);
    if ((j->pos < j->len) && (j->t[j->pos] == close)) {
        j->pos++;
        return 0;
    }
    for (;;) {
        const char *k = key;
        size_t kl = key_len;
        if (close == '}') {
            rec_json_ws(j);
            if ((j->pos >= j->len) || (j->t[j->pos] != '"')) {
                return rec_json_unexpected(j, key, key_len, "a key in double quotes");
            }
            const size_t ks = j->pos;
            if (rec_json_string(j, key, key_len) != 0) {
                return -1;
            }
            k = &j->t[ks + 1u];
            kl = j->pos - ks - 2u;
            rec_json_ws(j);
            if ((j->pos >= j->len) || (j->t[j->pos] != ':')) {
                return rec_json_unexpected(j, k, kl, "':' after the key");
            }
            j->pos++;
        }
        if (rec_json_value(j, depth + 1u, k, kl) != 0) {
            return -1;
        }
        rec_json_ws(j);
        if ((j->pos < j->len) && (j->t[j->pos] == ',')) {
            j->pos++;
            continue;
        }
        if ((j->pos < j->len) && (j->t[j->pos] == close)) {
            j->pos++;
            return 0;
        }
        if (close == '}') {
            (void)rec_json_unexpected(j, k, kl, "',' or '}'");
            j->after = 1;
            return -1;
        }
        return rec_json_unexpected(j, key, key_len, "',' or ']'");
    }
}

static int rec_json_value(rec_json_t *j, unsigned depth, const char *key, size_t key_len)
{
    rec_json_ws(j);
    if (j->pos >= j->len) {
        return rec_json_unexpected(j, key, key_len, "a value");
    }
    const char ch = j->t[j->pos];
    if ((ch == '{') || (ch == '[')) {
        return rec_json_container(j, depth, key, key_len);
    }
    if (ch == '"') {
        return rec_json_string(j, key, key_len);
    }
    if ((ch == '-') || ((ch >= '0') && (ch <= '9'))) {
        return rec_json_number(j, key, key_len);
    }
    const char *lit[3] = {"true", "false", "null"};
    for (size_t i = 0u; i < 3u; ++i) {
        const size_t n = strlen(lit[i]);
        if ((j->len - j->pos >= n) && (strncmp(&j->t[j->pos], lit[i], n) == 0)) {
            j->pos += n;
            return 0;
        }
    }
    return rec_json_unexpected(j, key, key_len, "a value");
}

/* The text (len bytes, NUL-terminated) as a JSON object, or NULL with
 * "not a JSON object: ..." in err: the byte offset (0-based), line and column
 * (1-based) of the first byte that cannot continue a JSON text, the key whose
 * value holds it, and why. */
static cJSON *rec_parse_object(const rec_ctx_t *c, const char *text, size_t len)
{
    if (len == 0u) {
        (void)rec_fail(c, MD_E_FRAME, "empty file");
        return NULL;
    }
    if (strlen(text) < len) {
        (void)rec_fail(c, MD_E_FRAME, "not a JSON object: NUL byte at byte offset %zu", strlen(text));
        return NULL;
    }
    rec_json_t j;
    memset(&j, 0, sizeof j);
    j.t = text;
    j.len = len;
    if (rec_json_value(&j, 0u, NULL, 0u) == 0) {
        rec_json_ws(&j);
        if (j.pos < len) {
            (void)rec_json_fail(&j, NULL, 0u, "text after the JSON value");
        }
    }
    if (j.why != NULL) {
        size_t line = 1u;
        size_t col = 1u;
        for (size_t i = 0u; i < j.pos; ++i) {
            line += (text[i] == '\n') ? 1u : 0u;
            col = (text[i] == '\n') ? 1u : col + 1u;
        }
        char key[200];
        rec_printable((j.key != NULL) ? j.key : "", j.key_len, 48u, key, sizeof key);
        (void)rec_fail(c, MD_E_FRAME,
                       "not a JSON object: invalid JSON at byte offset %zu (line %zu, column %zu)%s%s%s: %s", j.pos,
                       line, col, (j.key == NULL) ? "" : (j.after ? ", after \"" : ", in \""), key,
                       (j.key != NULL) ? "\"" : "", j.why);
        return NULL;
    }
    cJSON *root = cJSON_ParseWithOpts(text, NULL, 1);
    if (root == NULL) {
        (void)rec_fail(c, MD_E_FRAME, "not a JSON object: cJSON cannot parse it (out of memory?)");
        return NULL;
    }
    if (!cJSON_IsObject(root)) {
        (void)rec_fail(c, MD_E_FRAME, "not a JSON object: the top level is %s",
                       cJSON_IsArray(root) ? "an array" : (cJSON_IsString(root) ? "a string" : "a scalar"));
        cJSON_Delete(root);
        return NULL;
    }
    return root;
}

/* ------------------------------------------------------------ the fields */

static const char *rec_type_name(const cJSON *it)
{
    if (cJSON_IsString(it)) {
        return "a string";
    }
    if (cJSON_IsNumber(it)) {
        return "a number";
    }
    if (cJSON_IsBool(it)) {
        return "true/false";
    }
    if (cJSON_IsNull(it)) {
        return "null";
    }
    return cJSON_IsArray(it) ? "an array" : "an object";
}

static const char *const REC_TOP_KEYS[] = {
    "sampling_frequency", "num_channels", "dtype",    "gain_uV", "offset_uV", "byte_order", "layout",
    "num_samples",        "file",         "scenario", "seed",    "intervals"};
static const char *const REC_INTERVAL_KEYS[] = {"start_sample", "num_samples", "duration_s", "depth_um", "hall_code"};

/* A field this reader uses, given twice in one object: cJSON would silently take the first.
 * (Other keys are not read; a linear pass per field keeps a huge object cheap.) */
static md_status_t rec_unique_keys(const rec_ctx_t *c, const cJSON *obj, const char *where, const char *const *keys,
                                   size_t n_keys)
{
    for (size_t k = 0u; k < n_keys; ++k) {
        unsigned seen = 0u;
        for (const cJSON *a = obj->child; a != NULL; a = a->next) {
            seen += ((a->string != NULL) && (strcmp(a->string, keys[k]) == 0)) ? 1u : 0u;
        }
        if (seen > 1u) {
            return rec_fail(c, MD_E_FRAME, "field \"%s%s\": given %u times", where, keys[k], seen);
        }
    }
    return MD_OK;
}

/* A finite number obj[key]. MD_OK; 1 if absent and optional; MD_E_FRAME (message) otherwise.
 * `where` prefixes the field name in messages ("" or "intervals[3]."). */
static int rec_number(const rec_ctx_t *c, const cJSON *obj, const char *where, const char *key, int required, double *v)
{
    const cJSON *it = cJSON_GetObjectItemCaseSensitive(obj, key);
    if (it == NULL) {
        return required ? (int)rec_fail(c, MD_E_FRAME, "field \"%s%s\": missing", where, key) : 1;
    }
    if (!cJSON_IsNumber(it)) {
        return (int)rec_fail(c, MD_E_FRAME, "field \"%s%s\": not a number (%s)", where, key, rec_type_name(it));
    }
    if (!isfinite(it->valuedouble)) {
        return (int)rec_fail(c, MD_E_FRAME, "field \"%s%s\": %g is not a finite number", where, key, it->valuedouble);
    }
    *v = it->valuedouble;
    return MD_OK;
}

/* An integer lo..hi in obj[key] (same returns as rec_number). */
static int rec_integer(const rec_ctx_t *c, const cJSON *obj, const char *where, const char *key, int required,
                       double lo, double hi, uint64_t *v)
{
    double x = 0.0;
    const int rc = rec_number(c, obj, where, key, required, &x);
    if (rc != MD_OK) {
        return rc;
    }
    if ((floor(x) < x) || !(x >= lo) || !(x <= hi)) {
        return (int)rec_fail(c, MD_E_FRAME, "field \"%s%s\": %.15g is not an integer %.17g..%.17g", where, key, x, lo,
                             hi);
    }
    *v = (uint64_t)x;
    return MD_OK;
}

/* A string obj[key] (same returns as rec_number); *s is NULL when absent. */
static int rec_string(const rec_ctx_t *c, const cJSON *obj, const char *key, int required, const char **s)
{
    const cJSON *it = cJSON_GetObjectItemCaseSensitive(obj, key);
    *s = NULL;
    if (it == NULL) {
        return required ? (int)rec_fail(c, MD_E_FRAME, "field \"%s\": missing", key) : 1;
    }
    if (!cJSON_IsString(it) || (it->valuestring == NULL)) {
        return (int)rec_fail(c, MD_E_FRAME, "field \"%s\": not a string (%s)", key, rec_type_name(it));
    }
    *s = it->valuestring;
    return MD_OK;
}

/* An optional string field that, if present, must be `only`. */
static md_status_t rec_only(const rec_ctx_t *c, const cJSON *root, const char *key, const char *only)
{
    const char *s = NULL;
    const int rc = rec_string(c, root, key, 0, &s);
    if (rc < 0) {
        return (md_status_t)rc;
    }
    if ((s != NULL) && (strcmp(s, only) != 0)) {
        char v[200];
        rec_printable(s, strlen(s), 32u, v, sizeof v);
        return rec_fail(c, MD_E_FRAME, "field \"%s\": \"%s\" is not supported (only \"%s\")", key, v, only);
    }
    return MD_OK;
}

static md_status_t rec_header(const rec_ctx_t *c, const cJSON *root, rec_recording_t *rec)
{
    uint64_t nch = 0u;
    int rc = rec_number(c, root, "", "sampling_frequency", 1, &rec->fs_hz);
    if (rc != MD_OK) {
        return (md_status_t)rc;
    }
    if (!(rec->fs_hz > 0.0)) {
        return rec_fail(c, MD_E_FRAME, "field \"sampling_frequency\": must be > 0 Hz, got %g", rec->fs_hz);
    }
    if (!(rec->fs_hz >= REC_FS_MIN_HZ) || !(rec->fs_hz <= REC_FS_MAX_HZ)) {
        return rec_fail(c, MD_E_FRAME, "field \"sampling_frequency\": %g Hz is outside %g..%g Hz", rec->fs_hz,
                        REC_FS_MIN_HZ, REC_FS_MAX_HZ);
    }
    rc = rec_integer(c, root, "", "num_channels", 1, 1.0, (double)REC_MAX_CHANNELS, &nch);
    if (rc != MD_OK) {
        return (md_status_t)rc;
    }
    rec->n_channels = (uint32_t)nch;
    const char *dt = NULL;
    rc = rec_string(c, root, "dtype", 1, &dt);
    if (rc != MD_OK) {
        return (md_status_t)rc;
    }
    if (strcmp(dt, "int16") == 0) {
        rec->dtype = REC_DTYPE_INT16;
    } else if (strcmp(dt, "float32") == 0) {
        rec->dtype = REC_DTYPE_FLOAT32;
    } else {
        char v[200];
        rec_printable(dt, strlen(dt), 32u, v, sizeof v);
        return rec_fail(c, MD_E_FRAME, "field \"dtype\": \"%s\" is not supported (int16 or float32, little-endian)", v);
    }
    rec->gain_uv = 1.0;
    if (rec_number(c, root, "", "gain_uV", 0, &rec->gain_uv) < 0) {
        return MD_E_FRAME;
    }
    if (!(rec->gain_uv > 0.0)) {
        return rec_fail(c, MD_E_FRAME, "field \"gain_uV\": must be > 0, got %g", rec->gain_uv);
    }
    rec->count_uv = ((rec->dtype == REC_DTYPE_FLOAT32) && (rec->gain_uv > REC_F32_MAX_COUNT_UV)) ? REC_F32_MAX_COUNT_UV
                                                                                                 : rec->gain_uv;
    double offset = 0.0;
    if ((rec_number(c, root, "", "offset_uV", 0, &offset) < 0) ||
        (rec_only(c, root, "byte_order", "little") != MD_OK) || (rec_only(c, root, "layout", "interleaved") != MD_OK) ||
        (rec_integer(c, root, "", "seed", 0, 0.0, 18446744073709549568.0, &rec->seed) < 0)) {
        return MD_E_FRAME;
    }
    const char *name = NULL;
    if (rec_string(c, root, "scenario", 0, &name) < 0) {
        return MD_E_FRAME;
    }
    (void)snprintf(rec->scenario, sizeof rec->scenario, "%s", (name != NULL) ? name : "?");
    return MD_OK;
}

/* Path of the binary: "file" relative to the sidecar's folder (or absolute), else recording.bin there. */
static md_status_t rec_bin_path(const rec_ctx_t *c, const cJSON *root, rec_recording_t *rec)
{
    const char *name = "recording.bin";
    const char *file = NULL;
    const int rc = rec_string(c, root, "file", 0, &file);
    if (rc < 0) {
        return MD_E_FRAME;
    }
    if (file != NULL) {
        if (file[0] == '\0') {
            return rec_fail(c, MD_E_FRAME, "field \"file\": empty");
        }
        name = file;
    }
    const char *slash = strrchr(c->path, '/');
    const int n = ((name[0] == '/') || (slash == NULL))
                      ? snprintf(rec->bin_path, sizeof rec->bin_path, "%s", name)
                      : snprintf(rec->bin_path, sizeof rec->bin_path, "%.*s/%s", (int)(slash - c->path), c->path, name);
    if ((n < 0) || ((size_t)n >= sizeof rec->bin_path)) {
        return rec_fail(c, MD_E_FRAME, "field \"file\": the path of the binary is longer than %u bytes",
                        REC_PATH_MAX - 1u);
    }
    return MD_OK;
}

/* Samples per channel from the binary's size, checked against "num_samples". */
static md_status_t rec_size_binary(const rec_ctx_t *c, const cJSON *root, rec_recording_t *rec)
{
    const rec_ctx_t bc = {rec->bin_path, c->err, c->errlen};
    struct stat sb;
    if (stat(rec->bin_path, &sb) != 0) {
        return rec_fail(&bc, MD_E_IO, "cannot open: %s", strerror(errno));
    }
    if (!S_ISREG(sb.st_mode)) {
        return rec_fail(&bc, MD_E_IO, "not a regular file");
    }
    const uint64_t bytes = (uint64_t)sb.st_size;
    const uint64_t frame = (uint64_t)rec->n_channels * ((rec->dtype == REC_DTYPE_FLOAT32) ? 4u : 2u);
    if (bytes == 0u) {
        return rec_fail(&bc, MD_E_FRAME, "empty (0 bytes)");
    }
    if (bytes % frame != 0u) {
        return rec_fail(&bc, MD_E_FRAME,
                        "%llu bytes is not a whole number of %llu-byte frames (%u channel(s) of %s); %llu byte(s) "
                        "left over",
                        (unsigned long long)bytes, (unsigned long long)frame, rec->n_channels,
                        rec_dtype_name(rec->dtype), (unsigned long long)(bytes % frame));
    }
    rec->total_samples = bytes / frame;
    uint64_t declared = 0u;
    const int rc = rec_integer(c, root, "", "num_samples", 0, 0.0, REC_INT_MAX, &declared);
    if (rc < 0) {
        return MD_E_FRAME;
    }
    if ((rc == MD_OK) && (declared != rec->total_samples)) {
        return rec_fail(c, MD_E_FRAME, "field \"num_samples\": %llu, but %s holds %llu samples per channel",
                        (unsigned long long)declared, rec->bin_path, (unsigned long long)rec->total_samples);
    }
    return MD_OK;
}

/* A per-channel number of one interval (depth_um, hall_code): a number, or one
 * number per channel; null or absent: unknown (NaN). */
static md_status_t rec_per_channel(const rec_ctx_t *c, const cJSON *obj, const char *where, const char *key,
                                   uint32_t n_channels, uint32_t channel, double *v)
{
    const cJSON *dep = cJSON_GetObjectItemCaseSensitive(obj, key);
    *v = nan("");
    if ((dep == NULL) || cJSON_IsNull(dep)) {
        return MD_OK;
    }
    if (cJSON_IsArray(dep) && (cJSON_GetArraySize(dep) != (int)n_channels)) {
        return rec_fail(c, MD_E_FRAME, "field \"%s%s\": %d entries for %u channel(s)", where, key,
                        cJSON_GetArraySize(dep), n_channels);
    }
    const cJSON *list = cJSON_IsArray(dep) ? dep : NULL;
    const cJSON *it = NULL;
    uint32_t i = 0u;
    cJSON_ArrayForEach(it, list)
    {
        if (!cJSON_IsNull(it) && !(cJSON_IsNumber(it) && isfinite(it->valuedouble))) {
            return rec_fail(c, MD_E_FRAME, "field \"%s%s[%u]\": not a finite number or null (%s)", where, key, i,
                            rec_type_name(it));
        }
        *v = ((i == channel) && cJSON_IsNumber(it)) ? it->valuedouble : *v;
        ++i;
    }
    if (!cJSON_IsArray(dep) && (rec_number(c, obj, where, key, 1, v) != MD_OK)) {
        return MD_E_FRAME;
    }
    return MD_OK;
}

/* The sidecar's "intervals" list. */
static md_status_t rec_intervals(const rec_ctx_t *c, const cJSON *list, uint32_t channel, rec_recording_t *rec)
{
    rec->n_intervals = 0u;
    const cJSON *it = NULL;
    cJSON_ArrayForEach(it, list)
    {
        char where[48];
        (void)snprintf(where, sizeof where, "intervals[%u].", rec->n_intervals);
        if (rec->n_intervals >= REC_MAX_INTERVALS) {
            return rec_fail(c, MD_E_FRAME, "field \"intervals\": more than %u intervals", REC_MAX_INTERVALS);
        }
        if (!cJSON_IsObject(it)) {
            return rec_fail(c, MD_E_FRAME, "field \"intervals[%u]\": not an object (%s)", rec->n_intervals,
                            rec_type_name(it));
        }
        rec_interval_t *iv = &rec->iv[rec->n_intervals];
        if ((rec_unique_keys(c, it, where, REC_INTERVAL_KEYS, sizeof REC_INTERVAL_KEYS / sizeof REC_INTERVAL_KEYS[0]) !=
             MD_OK) ||
            (rec_integer(c, it, where, "start_sample", 1, 0.0, REC_INT_MAX, &iv->start_sample) != MD_OK) ||
            (rec_integer(c, it, where, "num_samples", 1, 1.0, REC_INT_MAX, &iv->num_samples) != MD_OK)) {
            return MD_E_FRAME;
        }
        if (iv->start_sample + iv->num_samples > rec->total_samples) {
            return rec_fail(c, MD_E_FRAME,
                            "field \"intervals[%u]\": samples %llu..%llu are past the end of %s (%llu samples per "
                            "channel)",
                            rec->n_intervals, (unsigned long long)iv->start_sample,
                            (unsigned long long)(iv->start_sample + iv->num_samples - 1u), rec->bin_path,
                            (unsigned long long)rec->total_samples);
        }
        iv->duration_s = (double)iv->num_samples / rec->fs_hz;
        const int rc = rec_number(c, it, where, "duration_s", 0, &iv->duration_s);
        if (rc < 0) {
            return MD_E_FRAME;
        }
        if (!(iv->duration_s > 0.0)) {
            return rec_fail(c, MD_E_FRAME, "field \"%sduration_s\": must be > 0, got %g", where, iv->duration_s);
        }
        if ((rec_per_channel(c, it, where, "depth_um", rec->n_channels, channel, &iv->depth_um) != MD_OK) ||
            (rec_per_channel(c, it, where, "hall_code", rec->n_channels, channel, &iv->hall_code) != MD_OK)) {
            return MD_E_FRAME;
        }
        rec->n_intervals++;
    }
    return MD_OK;
}

/* Consecutive intervals of interval_s seconds; a last partial one if at least half as long. */
static void rec_cut_intervals(rec_recording_t *rec, double interval_s)
{
    const double len_d = floor(interval_s * rec->fs_hz + 0.5);
    const uint64_t len = (len_d >= 1.0) ? (uint64_t)len_d : 0u;
    rec->n_intervals = 0u;
    for (uint64_t s = 0u; (len > 0u) && (s + len / 2u <= rec->total_samples) && (rec->n_intervals < REC_MAX_INTERVALS);
         s += len) {
        rec_interval_t *iv = &rec->iv[rec->n_intervals++];
        iv->start_sample = s;
        iv->num_samples = (s + len <= rec->total_samples) ? len : rec->total_samples - s;
        iv->duration_s = (double)iv->num_samples / rec->fs_hz;
        iv->depth_um = nan("");
        iv->hall_code = nan("");
    }
}

static md_status_t rec_check(const rec_ctx_t *c, const cJSON *root, const rec_options_t *opt, rec_recording_t *rec)
{
    md_status_t st = rec_unique_keys(c, root, "", REC_TOP_KEYS, sizeof REC_TOP_KEYS / sizeof REC_TOP_KEYS[0]);
    if (st == MD_OK) {
        st = rec_header(c, root, rec);
    }
    if ((st == MD_OK) && (opt->channel >= rec->n_channels)) {
        st = rec_fail(c, MD_E_ARG, "channel %u requested, but the recording has %u channel(s)", opt->channel,
                      rec->n_channels);
    }
    if (st == MD_OK) {
        st = rec_bin_path(c, root, rec);
    }
    if (st == MD_OK) {
        st = rec_size_binary(c, root, rec);
    }
    if (st != MD_OK) {
        return st;
    }
    const cJSON *list = cJSON_GetObjectItemCaseSensitive(root, "intervals");
    if ((list != NULL) && !cJSON_IsArray(list)) {
        return rec_fail(c, MD_E_FRAME, "field \"intervals\": not an array (%s)", rec_type_name(list));
    }
    rec->interval_list = (cJSON_GetArraySize(list) > 0);
    if (rec->interval_list) {
        return rec_intervals(c, list, opt->channel, rec);
    }
    if (!(opt->interval_s > 0.0)) {
        return rec_fail(c, MD_E_FRAME, "field \"intervals\": %s (this tool needs the list of intervals)",
                        (list == NULL) ? "missing" : "empty");
    }
    rec_cut_intervals(rec, opt->interval_s);
    if (rec->n_intervals == 0u) {
        return rec_fail(c, MD_E_FRAME, "no interval of %g s fits in the %llu samples per channel of %s",
                        opt->interval_s, (unsigned long long)rec->total_samples, rec->bin_path);
    }
    return MD_OK;
}

md_status_t rec_read_sidecar(const char *json_path, const rec_options_t *opt, rec_recording_t *rec, char *err,
                             size_t errlen)
{
    if ((err != NULL) && (errlen > 0u)) {
        err[0] = '\0';
    }
    const rec_ctx_t c = {json_path, err, errlen};
    if ((json_path == NULL) || (opt == NULL) || (rec == NULL)) {
        return rec_fail(&c, MD_E_ARG, "NULL argument");
    }
    memset(rec, 0, sizeof *rec);
    if (strlen(json_path) >= sizeof rec->json_path) {
        return rec_fail(&c, MD_E_ARG, "path longer than %u bytes", REC_PATH_MAX - 1u);
    }
    (void)snprintf(rec->json_path, sizeof rec->json_path, "%s", json_path);
    size_t len = 0u;
    md_status_t st = MD_OK;
    char *text = rec_slurp(&c, &len, &st);
    if (text == NULL) {
        return st;
    }
    cJSON *root = rec_parse_object(&c, text, len);
    free(text); /* the message is complete: nothing points into the text any more */
    if (root == NULL) {
        return MD_E_FRAME;
    }
    st = rec_check(&c, root, opt, rec);
    cJSON_Delete(root);
    return st;
}

/* ------------------------------------------------------------ the samples */

/* One float32 value as an int16 count (recording.h: rounding, clipping, non-finite). */
static int16_t rec_f32_count(float v, double scale, rec_conversion_t *conv)
{
    if (!isfinite(v)) {
        conv->non_finite++;
        return 0;
    }
    const double r = round((double)v * scale);
    if (r > 32767.0) {
        conv->clipped++;
        return INT16_MAX;
    }
    if (r < -32768.0) {
        conv->clipped++;
        return INT16_MIN;
    }
    return (int16_t)r;
}

md_status_t rec_read_interval(const rec_recording_t *rec, uint32_t k, uint32_t ch, int16_t *x, size_t cap,
                              rec_conversion_t *conv, char *err, size_t errlen)
{
    const rec_ctx_t c = {(rec != NULL) ? rec->bin_path : "recording", err, errlen};
    if ((rec == NULL) || (x == NULL) || (conv == NULL) || (k >= rec->n_intervals) || (ch >= rec->n_channels) ||
        (cap < rec->iv[k].num_samples)) {
        return rec_fail(&c, MD_E_ARG, "interval %u, channel %u: bad arguments", k, ch);
    }
    const rec_interval_t *iv = &rec->iv[k];
    const size_t bps = (rec->dtype == REC_DTYPE_FLOAT32) ? 4u : 2u;
    const size_t frame = (size_t)rec->n_channels * bps;
    const size_t chunk = (frame < (1u << 20)) ? (1u << 20) / frame : 1u; /* frames per read, about 1 MiB */
    const double scale = rec->gain_uv / rec->count_uv;
    FILE *f = fopen(rec->bin_path, "rb");
    if (f == NULL) {
        return rec_fail(&c, MD_E_IO, "cannot open: %s", strerror(errno));
    }
    uint8_t *buf = malloc(chunk * frame);
    md_status_t st = ((buf != NULL) && (fseeko(f, (off_t)(iv->start_sample * frame), SEEK_SET) == 0)) ? MD_OK : MD_E_IO;
    for (uint64_t done = 0u; (st == MD_OK) && (done < iv->num_samples);) {
        const size_t want = (size_t)((iv->num_samples - done < chunk) ? iv->num_samples - done : chunk);
        if (fread(buf, frame, want, f) != want) {
            st = MD_E_IO;
            break;
        }
        for (size_t i = 0u; i < want; ++i) {
            const uint8_t *b = &buf[i * frame + (size_t)ch * bps]; /* little-endian, whatever the host's order */
            if (rec->dtype == REC_DTYPE_FLOAT32) {
                const uint32_t u = (uint32_t)b[0] | ((uint32_t)b[1] << 8u) | ((uint32_t)b[2] << 16u) |
                                   ((uint32_t)b[3] << 24u);
                float v;
                memcpy(&v, &u, sizeof v);
                x[done + i] = rec_f32_count(v, scale, conv);
            } else {
                x[done + i] = (int16_t)(uint16_t)((uint16_t)b[0] | (uint16_t)((uint16_t)b[1] << 8u));
            }
        }
        done += want;
    }
    free(buf);
    (void)fclose(f);
    if (st != MD_OK) {
        return rec_fail(&c, MD_E_IO, "interval %u (samples %llu..%llu): short read; did the file change?", k,
                        (unsigned long long)iv->start_sample,
                        (unsigned long long)(iv->start_sample + iv->num_samples - 1u));
    }
    return MD_OK;
}
