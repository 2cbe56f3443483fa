/// @file cc_io.c
/// Simulator export reader for the clustering-consistency experiment.
#include "cc_io.h"

#include <cjson/cJSON.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static char *read_text(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (f == NULL) {
        return NULL;
    }
    char *buf = NULL;
    if (fseek(f, 0L, SEEK_END) == 0) {
        const long len = ftell(f);
        if ((len > 0L) && (len < (1L << 26)) && (fseek(f, 0L, SEEK_SET) == 0)) {
            buf = malloc((size_t)len + 1u);
            if ((buf != NULL) && (fread(buf, 1u, (size_t)len, f) != (size_t)len)) {
                free(buf);
                buf = NULL;
            } else if (buf != NULL) {
                buf[len] = '\0';
            }
        }
    }
    (void)fclose(f);
    return buf;
}

static int get_number(const cJSON *obj, const char *key, double *out)
{
    const cJSON *it = cJSON_GetObjectItemCaseSensitive(obj, key);
    if (!cJSON_IsNumber(it)) {
        return -1;
    }
    *out = it->valuedouble;
    return 0;
}

static md_status_t parse_interval(const cJSON *it, uint32_t n_channels, cc_interval_t *iv)
{
    double start = 0.0;
    double num = 0.0;
    if ((get_number(it, "start_sample", &start) != 0) || (get_number(it, "num_samples", &num) != 0) ||
        (get_number(it, "start_s", &iv->start_s) != 0) || (get_number(it, "duration_s", &iv->duration_s) != 0)) {
        return MD_E_FRAME;
    }
    if (!(start >= 0.0) || !(num >= 1.0) || (num > 4.0e9)) {
        return MD_E_FRAME;
    }
    iv->start_sample = (uint64_t)start;
    iv->num_samples = (uint32_t)num;
    const cJSON *depth = cJSON_GetObjectItemCaseSensitive(it, "depth_um");
    if (!cJSON_IsArray(depth) || (cJSON_GetArraySize(depth) != (int)n_channels)) {
        return MD_E_FRAME;
    }
    for (uint32_t c = 0u; c < n_channels; ++c) {
        const cJSON *v = cJSON_GetArrayItem(depth, (int)c);
        iv->depth_um[c] = cJSON_IsNumber(v) ? v->valuedouble : 0.0;
    }
    return MD_OK;
}

static md_status_t parse_sidecar(const cJSON *root, cc_recording_t *rec, char *err, size_t errlen)
{
    double nch = 0.0;
    double seed = 0.0;
    if ((get_number(root, "sampling_frequency", &rec->fs_hz) != 0) || (get_number(root, "num_channels", &nch) != 0) ||
        (get_number(root, "gain_uV", &rec->gain_uv) != 0)) {
        (void)snprintf(err, errlen, "sidecar: sampling_frequency, num_channels or gain_uV missing");
        return MD_E_FRAME;
    }
    if (!(nch >= 1.0) || (nch > (double)CC_MAX_CHANNELS) || !(rec->fs_hz >= 1000.0) || !(rec->gain_uv > 0.0)) {
        (void)snprintf(err, errlen, "sidecar: num_channels, sampling_frequency or gain_uV out of range");
        return MD_E_FRAME;
    }
    rec->n_channels = (uint32_t)nch;
    rec->seed = (get_number(root, "seed", &seed) == 0) ? (uint64_t)seed : 0u;
    const cJSON *name = cJSON_GetObjectItemCaseSensitive(root, "scenario");
    (void)snprintf(rec->scenario, sizeof rec->scenario, "%s", cJSON_IsString(name) ? name->valuestring : "?");
    const cJSON *ivs = cJSON_GetObjectItemCaseSensitive(root, "intervals");
    const int n = cJSON_IsArray(ivs) ? cJSON_GetArraySize(ivs) : -1;
    if ((n < 1) || (n > (int)CC_MAX_INTERVALS)) {
        (void)snprintf(err, errlen, "sidecar: intervals missing or more than %u", CC_MAX_INTERVALS);
        return MD_E_FRAME;
    }
    rec->n_intervals = (uint32_t)n;
    for (int k = 0; k < n; ++k) {
        if (parse_interval(cJSON_GetArrayItem(ivs, k), rec->n_channels, &rec->iv[k]) != MD_OK) {
            (void)snprintf(err, errlen, "sidecar: interval %d malformed", k);
            return MD_E_FRAME;
        }
    }
    return MD_OK;
}

md_status_t cc_read_sidecar(const char *dir, cc_recording_t *rec, char *err, size_t errlen)
{
    char path[4096];
    (void)snprintf(path, sizeof path, "%s/recording.json", dir);
    char *text = read_text(path);
    if (text == NULL) {
        (void)snprintf(err, errlen, "cannot read %s", path);
        return MD_E_IO;
    }
    cJSON *root = cJSON_Parse(text);
    free(text);
    if (root == NULL) {
        (void)snprintf(err, errlen, "%s: not valid JSON", path);
        return MD_E_FRAME;
    }
    memset(rec, 0, sizeof *rec);
    const md_status_t st = parse_sidecar(root, rec, err, errlen);
    cJSON_Delete(root);
    return st;
}

md_status_t cc_read_interval(const char *dir, const cc_recording_t *rec, uint32_t k, uint32_t ch, int16_t *x,
                             size_t cap)
{
    if ((k >= rec->n_intervals) || (ch >= rec->n_channels) || (cap < rec->iv[k].num_samples)) {
        return MD_E_ARG;
    }
    char path[4096];
    (void)snprintf(path, sizeof path, "%s/recording.bin", dir);
    FILE *f = fopen(path, "rb");
    if (f == NULL) {
        return MD_E_IO;
    }
    const size_t frame = 2u * (size_t)rec->n_channels;
    md_status_t st = MD_OK;
    if (fseeko(f, (off_t)(rec->iv[k].start_sample * frame), SEEK_SET) != 0) {
        st = MD_E_IO;
    }
    uint8_t buf[2u * CC_MAX_CHANNELS];
    for (uint32_t i = 0u; (st == MD_OK) && (i < rec->iv[k].num_samples); ++i) {
        if (fread(buf, 1u, frame, f) != frame) {
            st = MD_E_IO;
            break;
        }
        /* little-endian int16, independent of the host's byte order */
        const uint16_t u = (uint16_t)((uint16_t)buf[2u * ch] | (uint16_t)((uint16_t)buf[2u * ch + 1u] << 8u));
        x[i] = (int16_t)u;
    }
    (void)fclose(f);
    return st;
}

static md_status_t truth_push(cc_truth_t *t, size_t *cap, uint64_t s, int32_t id)
{
    if (t->n == *cap) {
        const size_t nc = (*cap == 0u) ? 4096u : 2u * *cap;
        uint64_t *ns = realloc(t->sample, nc * sizeof *ns);
        if (ns == NULL) {
            return MD_E_CAPACITY;
        }
        t->sample = ns;
        int32_t *nn = realloc(t->neuron, nc * sizeof *nn);
        if (nn == NULL) {
            return MD_E_CAPACITY;
        }
        t->neuron = nn;
        *cap = nc;
    }
    t->sample[t->n] = s;
    t->neuron[t->n] = id;
    t->n++;
    if (id > t->max_neuron) {
        t->max_neuron = id;
    }
    return MD_OK;
}

md_status_t cc_read_truth(const char *dir, uint32_t ch, cc_truth_t *truth)
{
    memset(truth, 0, sizeof *truth);
    truth->max_neuron = -1;
    char path[4096];
    (void)snprintf(path, sizeof path, "%s/ground_truth.csv", dir);
    FILE *f = fopen(path, "r");
    if (f == NULL) {
        return MD_OK;
    }
    char line[256];
    size_t cap = 0u;
    md_status_t st = MD_OK;
    uint64_t last = 0u;
    while ((st == MD_OK) && (fgets(line, (int)sizeof line, f) != NULL)) {
        unsigned long long s = 0u;
        unsigned c = 0u;
        int id = 0;
        if (sscanf(line, "%llu,%u,%d", &s, &c, &id) != 3) {
            continue; /* header */
        }
        if ((c != ch) || (id < 0)) {
            continue;
        }
        if ((uint64_t)s < last) {
            st = MD_E_FRAME; /* the exporter writes ascending samples */
            break;
        }
        last = (uint64_t)s;
        st = truth_push(truth, &cap, (uint64_t)s, (int32_t)id);
    }
    (void)fclose(f);
    return st;
}

void cc_truth_free(cc_truth_t *truth)
{
    free(truth->sample);
    free(truth->neuron);
    memset(truth, 0, sizeof *truth);
    truth->max_neuron = -1;
}

size_t cc_truth_lower_bound(const cc_truth_t *truth, uint64_t s)
{
    size_t lo = 0u;
    size_t hi = truth->n;
    while (lo < hi) {
        const size_t mid = lo + (hi - lo) / 2u;
        if (truth->sample[mid] < s) {
            lo = mid + 1u;
        } else {
            hi = mid;
        }
    }
    return lo;
}
