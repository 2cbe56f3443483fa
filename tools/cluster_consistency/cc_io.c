/// @file cc_io.c
/// Ground truth of a simulator export for the clustering-consistency experiment.
#include "cc_io.h"

#include <stdio.h>
#include <sys/types.h>
#include <stdlib.h>
#include <string.h>

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

/* Digits at *p as an unsigned value <= max; advances *p. 0 or -1. */
static int cc_digits(const char **p, uint64_t max, uint64_t *v)
{
    const char *q = *p;
    uint64_t x = 0u;
    if ((*q < '0') || (*q > '9')) {
        return -1;
    }
    for (; (*q >= '0') && (*q <= '9'); ++q) {
        const uint64_t d = (uint64_t)(*q - '0');
        if (x > (max - d) / 10u) {
            return -1; /* beyond max */
        }
        x = x * 10u + d;
    }
    *p = q;
    *v = x;
    return 0;
}

/* One record "SAMPLE,CHANNEL,NEURON" (decimal; NEURON may be negative), the whole line. */
static int cc_record(const char *line, uint64_t *s, uint32_t *c, int32_t *id)
{
    const char *p = line;
    uint64_t cv = 0u;
    uint64_t iv = 0u;
    const int neg = (cc_digits(&p, UINT64_MAX, s) == 0) && (*p++ == ',') && (cc_digits(&p, UINT32_MAX, &cv) == 0) &&
                            (*p++ == ',')
                        ? ((*p == '-') ? 1 : 0)
                        : -1;
    if (neg < 0) {
        return -1;
    }
    p += neg;
    if ((cc_digits(&p, neg ? 2147483648u : 2147483647u, &iv) != 0) || (*p != '\0')) {
        return -1;
    }
    *c = (uint32_t)cv;
    *id = neg ? (int32_t)(-(int64_t)iv) : (int32_t)iv;
    return 0;
}

/* Strips the line end (\n or \r\n) of a getline() result of n bytes: the length left. */
static size_t cc_chomp(char *line, size_t n)
{
    size_t len = n;
    if ((len > 0u) && (line[len - 1u] == '\n')) {
        line[--len] = '\0';
    }
    if ((len > 0u) && (line[len - 1u] == '\r')) {
        line[--len] = '\0';
    }
    return len;
}

/* One line of ground_truth.csv (line_no from 1, len its length without the line end): a record of
 * channel ch appended to *truth (its samples ascending after *last); the header, an empty line or
 * another channel's record skipped. MD_E_FRAME or the append's status, with *why. */
static md_status_t cc_truth_line(cc_truth_t *truth, size_t *cap, const char *line, size_t len, size_t line_no,
                                 uint32_t ch, uint64_t *last, const char **why)
{
    if (strlen(line) != len) {
        *why = "NUL byte in the line";
        return MD_E_FRAME;
    }
    if ((len == 0u) || ((line_no == 1u) && (strcmp(line, CC_TRUTH_HEADER) == 0))) {
        return MD_OK;
    }
    uint64_t s = 0u;
    uint32_t c = 0u;
    int32_t id = 0;
    if (cc_record(line, &s, &c, &id) != 0) {
        *why = "not a record SAMPLE,CHANNEL,NEURON (decimal integers: uint64, uint32, int32)";
        return MD_E_FRAME;
    }
    if ((c != ch) || (id < 0)) {
        return MD_OK;
    }
    if (s < *last) {
        *why = "samples of the channel not ascending"; /* the exporter writes them ascending */
        return MD_E_FRAME;
    }
    *last = s;
    const md_status_t st = truth_push(truth, cap, s, id);
    *why = (st != MD_OK) ? "out of memory" : NULL;
    return st;
}

md_status_t cc_read_truth(const char *dir, uint32_t ch, cc_truth_t *truth, char *err, size_t errlen)
{
    memset(truth, 0, sizeof *truth);
    truth->max_neuron = -1;
    if ((err != NULL) && (errlen > 0u)) {
        err[0] = '\0';
    }
    char path[4096];
    (void)snprintf(path, sizeof path, "%s/ground_truth.csv", dir);
    FILE *f = fopen(path, "r");
    if (f == NULL) {
        return MD_OK;
    }
    char *line = NULL;
    size_t line_cap = 0u;
    size_t cap = 0u;
    md_status_t st = MD_OK;
    uint64_t last = 0u;
    const char *why = NULL;
    size_t line_no = 0u;
    ssize_t n = 0;
    while ((st == MD_OK) && ((n = getline(&line, &line_cap, f)) >= 0)) {
        line_no++;
        st = cc_truth_line(truth, &cap, line, cc_chomp(line, (size_t)n), line_no, ch, &last, &why);
    }
    const int read_error = ferror(f);
    free(line);
    (void)fclose(f);
    if ((st == MD_OK) && (read_error != 0)) {
        why = "read error";
        st = MD_E_IO;
    }
    if (st != MD_OK) {
        cc_truth_free(truth);
        if ((err != NULL) && (errlen > 0u)) {
            (void)snprintf(err, errlen, "%s:%zu: %s", path, line_no, why);
        }
    }
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
