/// @file fuzz_truth.c
/// Fuzz target: the ground-truth JSON-lines reader of the LCM bridge
/// (tools/lcm_bridge/lb_truth.c: lb_truth_time_us and lb_feed_truth_line,
/// cJSON), the only C code that parses the simulator's truth.jsonl. The
/// input is the file: it is cut at '\n' and every line goes, as its own
/// exact-size NUL-terminated heap copy, first to lb_truth_time_us (what the
/// bridge does to schedule it) and then to lb_feed_truth_line; lb_flush
/// ends the input. Every message the bridge publishes is decoded again with
/// its lcm-gen type.
/// Invariants: returns 0 or -1; truth_records + truth_errors = non-blank lines
/// fed; truth_ignored <= truth_records; no frame counter moves; every
/// published message is on a MD_TRUTH_* channel, decodes to exactly its
/// encoded length, and its arrays hold at most their capacity (the
/// sink sees each message once: messages = sink calls).
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "fuzz_input.h"
#include "lcm_bridge.h"
#include "mdlcm_truth_death_t.h"
#include "mdlcm_truth_session_t.h"
#include "mdlcm_truth_spikes_t.h"
#include "mdlcm_truth_state_t.h"

static uint64_t g_sink_calls;

/* Big-endian integers of an LCM encoding (bounds checked by the caller). */
static int64_t be(const uint8_t *p, size_t n)
{
    uint64_t v = 0u;
    for (size_t i = 0u; i < n; ++i) {
        v = (v << 8) | p[i];
    }
    return (n == 2u) ? (int64_t)(int16_t)v : (n == 4u) ? (int64_t)(int32_t)v : (int64_t)v;
}

/* The array counts of a message read from its encoding (fingerprint first, then
 * the fields in .lcm order). lcm-gen's decoder memcpy()s into a NULL array when
 * a count is 0 (undefined behaviour inside LCM's lcm_coretypes.h, not the
 * bridge's), so messages with an empty array are checked through these
 * counts instead of a decode. */
static void session_counts(const uint8_t *d, size_t len, int64_t *ne, int64_t *nn)
{
    FUZZ_CHECK(len >= 8u + 24u + 2u);
    *ne = be(&d[32], 2u);
    FUZZ_CHECK(*ne >= 0 && len >= 34u + 4u * (size_t)*ne + 4u);
    *nn = be(&d[34u + 4u * (size_t)*ne], 4u);
}

static int64_t state_count(const uint8_t *d, size_t len)
{
    FUZZ_CHECK(len >= 8u + 9u + 4u);
    const int64_t label_len = be(&d[17], 4u);
    FUZZ_CHECK(label_len >= 1 && len >= 21u + (size_t)label_len + 8u + 4u);
    return be(&d[21u + (size_t)label_len + 8u], 4u);
}

static int sink(void *ctx, const char *channel, int64_t utime, const uint8_t *data, size_t len)
{
    (void)ctx;
    (void)utime;
    g_sink_calls++;
    FUZZ_CHECK(data != NULL && len > 0u && len < (1u << 24));
    const int n = (int)len;
    if (strcmp(channel, LB_CH_TRUTH_SESSION) == 0) {
        int64_t ne = 0;
        int64_t nn = 0;
        session_counts(data, len, &ne, &nn);
        FUZZ_CHECK(ne >= 0 && ne <= (int64_t)LB_MAX_ELECTRODES);
        FUZZ_CHECK(nn >= 0 && nn <= (int64_t)LB_TRUTH_MAX_NEURONS);
        if (ne > 0 && nn > 0) {
            mdlcm_truth_session_t m;
            FUZZ_CHECK(mdlcm_truth_session_t_decode(data, 0, n, &m) == n);
            FUZZ_CHECK(m.num_electrodes == ne && m.num_neurons == nn);
            mdlcm_truth_session_t_decode_cleanup(&m);
        }
    } else if (strcmp(channel, LB_CH_TRUTH_SPIKES) == 0) {
        mdlcm_truth_spikes_t m; /* a batch is published only when it holds a spike */
        FUZZ_CHECK(mdlcm_truth_spikes_t_decode(data, 0, n, &m) == n);
        FUZZ_CHECK(m.num_spikes >= 1 && m.num_spikes <= (int32_t)LB_TRUTH_SPIKE_BATCH);
        mdlcm_truth_spikes_t_decode_cleanup(&m);
    } else if (strcmp(channel, LB_CH_TRUTH_STATE) == 0) {
        const int64_t nn = state_count(data, len);
        FUZZ_CHECK(nn >= 0 && nn <= (int64_t)LB_TRUTH_MAX_NEURONS);
        if (nn > 0) {
            mdlcm_truth_state_t m;
            FUZZ_CHECK(mdlcm_truth_state_t_decode(data, 0, n, &m) == n);
            FUZZ_CHECK(m.num_neurons == nn);
            mdlcm_truth_state_t_decode_cleanup(&m);
        }
    } else {
        FUZZ_CHECK(strcmp(channel, LB_CH_TRUTH_DEATH) == 0);
        mdlcm_truth_death_t m;
        FUZZ_CHECK(mdlcm_truth_death_t_decode(data, 0, n, &m) == n);
        mdlcm_truth_death_t_decode_cleanup(&m);
    }
    return 0;
}

static bool blank(const char *s, size_t n)
{
    for (size_t i = 0u; i < n; ++i) {
        if (s[i] != ' ' && s[i] != '\t' && s[i] != '\r' && s[i] != '\n') {
            return false;
        }
    }
    return true;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static lb_t *st;
    if (st == NULL) {
        st = (lb_t *)aligned_alloc(_Alignof(max_align_t), (lb_size() + 15u) & ~(size_t)15u);
        FUZZ_CHECK(st != NULL);
    }
    FUZZ_CHECK(lb_init(st, LB_TIME_SIM, sink, NULL) == 0);
    g_sink_calls = 0u;
    uint64_t fed = 0u;
    size_t at = 0u;
    while (at < size) {
        const uint8_t *nl = memchr(&data[at], '\n', size - at);
        const size_t end = (nl != NULL) ? (size_t)(nl - data) : size;
        const size_t n = end - at;
        char *line = (char *)malloc(n + 1u);
        FUZZ_CHECK(line != NULL);
        memcpy(line, &data[at], n);
        line[n] = '\0';
        const size_t effective = strlen(line); /* a NUL byte ends the C string early */
        (void)lb_truth_time_us(st, line);
        const int rc = lb_feed_truth_line(st, line);
        FUZZ_CHECK(rc == 0 || rc == -1);
        fed += blank(line, effective) ? 0u : 1u;
        free(line);
        at = end + 1u;
    }
    lb_flush(st);
    const lb_stats_t *s = lb_stats(st);
    FUZZ_CHECK(s->truth_records + s->truth_errors == fed);
    FUZZ_CHECK(s->truth_ignored <= s->truth_records);
    FUZZ_CHECK(s->frames == 0u && s->telemetry == 0u && s->malformed == 0u && s->late == 0u);
    FUZZ_CHECK(s->sink_errors == 0u);
    FUZZ_CHECK(s->messages == g_sink_calls);
    return 0;
}
