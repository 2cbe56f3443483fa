/// @file fuzz_ground_truth_csv.c
/// Fuzz target: the ground_truth.csv reader of cluster-consistency
/// (tools/cluster_consistency/cc_io.h, cc_read_truth), through a real file in
/// a private folder (/dev/shm, else /tmp).
///   byte 0    channel asked for (0..3)
///   the rest  ground_truth.csv
/// Invariants: a documented status; a refusal names "PATH:LINE: " and leaves
/// an empty truth; an accepted file gives exactly the records of an
/// independent reading of the documented format (strtoull/strtol on each
/// line): the channel's records with neuron >= 0, in file order, samples
/// ascending, max_neuron their largest id; lower_bound agrees with a scan.
#include <errno.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cc_io.h"
#include "fuzz_input.h"

static char g_dir[64];
static char g_csv[128];

static void cleanup(void)
{
    (void)unlink(g_csv);
    (void)rmdir(g_dir);
}

static void setup_once(void)
{
    if (g_dir[0] != '\0') {
        return;
    }
    (void)snprintf(g_dir, sizeof g_dir, "/dev/shm/fuzz_gt_csv.XXXXXX");
    if (mkdtemp(g_dir) == NULL) {
        (void)snprintf(g_dir, sizeof g_dir, "/tmp/fuzz_gt_csv.XXXXXX");
        FUZZ_CHECK(mkdtemp(g_dir) != NULL);
    }
    (void)snprintf(g_csv, sizeof g_csv, "%s/ground_truth.csv", g_dir);
    (void)atexit(cleanup);
}

/* One decimal field of s (no sign, no space, no '+'), [lo, hi]; NULL if not. */
static const char *field(const char *s, char stop, long long lo, unsigned long long hi, bool is_signed,
                         unsigned long long *u, long long *i)
{
    const char *digits = (is_signed && *s == '-') ? s + 1 : s;
    if (*digits < '0' || *digits > '9') {
        return NULL;
    }
    char *end = NULL;
    errno = 0;
    if (is_signed) {
        *i = strtoll(s, &end, 10);
        if (errno != 0 || *i < lo || *i > (long long)hi) {
            return NULL;
        }
    } else {
        *u = strtoull(s, &end, 10);
        if (errno != 0 || *u > hi) {
            return NULL;
        }
    }
    return (*end == stop) ? end : NULL;
}

typedef struct {
    int status; /* 0 ok, 1 bad line, 2 not ascending */
    size_t n;
    uint64_t sample[4096];
    int32_t neuron[4096];
} model_t;

static model_t g_m;

static void model(const uint8_t *text, size_t len, uint32_t ch)
{
    memset(&g_m, 0, sizeof g_m);
    uint64_t last = 0u;
    size_t at = 0u;
    for (size_t line_no = 1u; at < len; ++line_no) {
        const uint8_t *nl = memchr(&text[at], '\n', len - at);
        size_t n = (nl != NULL) ? (size_t)(nl - &text[at]) : len - at;
        const size_t next = at + n + 1u;
        if (n > 0u && text[at + n - 1u] == '\r') {
            n--;
        }
        if (memchr(&text[at], '\0', n) != NULL) {
            g_m.status = 1; /* a NUL byte: refused */
            return;
        }
        char *buf = (char *)malloc(n + 1u);
        FUZZ_CHECK(buf != NULL);
        memcpy(buf, &text[at], n);
        buf[n] = '\0';
        at = next;
        if (n == 0u || (line_no == 1u && strcmp(buf, "sample_index,channel,neuron_id") == 0)) {
            free(buf);
            continue;
        }
        unsigned long long s = 0u, c = 0u, unused_u = 0u;
        long long id = 0, unused_i = 0;
        const char *p = field(buf, ',', 0, UINT64_MAX, false, &s, &unused_i);
        p = (p != NULL) ? field(p + 1, ',', 0, UINT32_MAX, false, &c, &unused_i) : NULL;
        p = (p != NULL) ? field(p + 1, '\0', INT32_MIN, INT32_MAX, true, &unused_u, &id) : NULL;
        free(buf);
        if (p == NULL) {
            g_m.status = 1;
            return;
        }
        if (c != ch || id < 0) {
            continue;
        }
        if ((uint64_t)s < last) {
            g_m.status = 2;
            return;
        }
        last = (uint64_t)s;
        FUZZ_CHECK(g_m.n < 4096u);
        g_m.sample[g_m.n] = (uint64_t)s;
        g_m.neuron[g_m.n] = (int32_t)id;
        g_m.n++;
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    setup_once();
    if (size == 0u) {
        return 0;
    }
    const uint32_t ch = data[0] & 3u;
    FILE *f = fopen(g_csv, "wb");
    FUZZ_CHECK(f != NULL);
    FUZZ_CHECK(size == 1u || fwrite(&data[1], 1u, size - 1u, f) == size - 1u);
    FUZZ_CHECK(fclose(f) == 0);

    cc_truth_t t;
    char err[4400];
    const md_status_t st = cc_read_truth(g_dir, ch, &t, err, sizeof err);
    model(&data[1], size - 1u, ch);
    if (st != MD_OK) {
        FUZZ_CHECK(st == MD_E_FRAME);
        FUZZ_CHECK(g_m.status != 0);
        FUZZ_CHECK(strncmp(err, g_csv, strlen(g_csv)) == 0 && err[strlen(g_csv)] == ':');
        FUZZ_CHECK(t.n == 0u && t.sample == NULL && t.neuron == NULL && t.max_neuron == -1);
        return 0;
    }
    FUZZ_CHECK(g_m.status == 0);
    FUZZ_CHECK(t.n == g_m.n);
    int32_t max_id = -1;
    for (size_t i = 0u; i < t.n; ++i) {
        FUZZ_CHECK(t.sample[i] == g_m.sample[i] && t.neuron[i] == g_m.neuron[i]);
        max_id = (t.neuron[i] > max_id) ? t.neuron[i] : max_id;
    }
    FUZZ_CHECK(t.max_neuron == max_id);
    for (size_t i = 0u; i < t.n; ++i) {
        const uint64_t s = t.sample[i];
        size_t want = 0u;
        while (want < t.n && t.sample[want] < s) {
            want++;
        }
        FUZZ_CHECK(cc_truth_lower_bound(&t, s) == want);
    }
    cc_truth_free(&t);
    return 0;
}
