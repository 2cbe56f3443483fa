/// @file spike_detect.c
/// Streaming spike detection (see spike_detect.h and docs/detector.md).
#include "signal/spike_detect.h"

#include <math.h>
#include <string.h>

#define SD_PHASE_IDLE 0
#define SD_PHASE_WARMUP 1
#define SD_PHASE_REPLAY 2
#define SD_PHASE_RUN 3
#define SD_PHASE_ENDED 4 /* input ended, replay (if any) pending or done */
#define SD_PHASE_DONE 5

#define SD_MAD_TO_SIGMA 0.6745 /* median(|N(0,1)|): robust sigma = MAD / 0.6745 */
/* Nenadic & Burdick's reference code scales the user's L in [-0.2, 0.2] by
 * ln of the largest cost ratio double precision can express (about 36.74), so
 * L = +-0.2 moves ln(cost ratio) by about +-7.3. */
#define SD_L_SCALE 36.7368
/* Box width of a scale tuned to spike width W: the FIR bank's Mexican hat has
 * envelope W/4; the second difference of a linear B-spline of box w
 * correlates best (>= 0.98) with a Mexican hat of envelope w/1.6, so
 * w = 1.6 * (W / 4) * fs = 0.4 W fs. */
#define SD_BOX_PER_WIDTH 0.4
#define SD_NONE 0xFFFFFFFFu
#define SD_DECIMATE_BOX 4u /* boxes this wide are evaluated at every 2nd centre */

#define SD_RING_MASK (SD_RING_SAMPLES - 1u)

_Static_assert(SD_WARMUP_MAX <= 65536u, "a warm-up sum of int16 samples fits int32");
_Static_assert(SD_SIGMA_STRIDE >= 1u, "sigma from every SD_SIGMA_STRIDE-th coefficient");

void sd_config_default(sd_config_t *cfg, sd_method_t method, uint32_t sample_rate_hz)
{
    if (cfg == NULL) {
        return;
    }
    cfg->method = method;
    cfg->sample_rate_hz = sample_rate_hz;
    cfg->align_ms = 0.5;
    cfg->k_sigma = 4.0;
    cfg->dead_time_ms = 1.0;
    cfg->polarity = SD_POLARITY_NEG;
    cfg->wavelet = SD_WAVELET_DOG1;
    cfg->width_min_ms = 0.5;
    cfg->width_max_ms = 1.0;
    cfg->n_scales = 2u;
    cfg->cost_ratio_l = 0.05;
    cfg->warmup_ms = 250.0;
    cfg->interval_s = 10.0;
    cfg->refine = true;
}

static int sd_in(double v, double lo, double hi)
{
    return (v >= lo) && (v <= hi); /* false for NaN */
}

static int sd_config_valid(const sd_config_t *c)
{
    const double warm = c->warmup_ms * 1e-3 * (double)c->sample_rate_hz;
    const int common = (c->sample_rate_hz >= 1000u) && (c->sample_rate_hz <= 200000u) &&
                       sd_in(c->align_ms, 0.01, 5.0) && sd_in(c->warmup_ms, 5.0, 1e6) &&
                       (warm <= (double)SD_WARMUP_MAX) && sd_in(c->interval_s, 0.01, 3600.0);
    switch (c->method) {
    case SD_METHOD_THRESHOLD:
        return common && sd_in(c->k_sigma, 1.0, 20.0) && sd_in(c->dead_time_ms, 0.0, 10.0) &&
               ((c->polarity == SD_POLARITY_NEG) || (c->polarity == SD_POLARITY_BOTH));
    case SD_METHOD_WAVELET:
        return common && ((c->wavelet == SD_WAVELET_MEXHAT) || (c->wavelet == SD_WAVELET_DOG1)) &&
               sd_in(c->width_min_ms, 0.05, 5.0) && sd_in(c->width_max_ms, c->width_min_ms, 5.0) &&
               (c->n_scales >= 1u) && (c->n_scales <= MD_WAVELET_SCALES_MAX) && sd_in(c->cost_ratio_l, -0.2, 0.2);
    default: return 0;
    }
}

static double sd_scale_width_ms(const sd_config_t *c, unsigned s)
{
    if (c->n_scales < 2u) {
        return 0.5 * (c->width_min_ms + c->width_max_ms);
    }
    return c->width_min_ms + (c->width_max_ms - c->width_min_ms) * (double)s / (double)(c->n_scales - 1u);
}

static uint32_t sd_ms_to_samples(double ms, uint32_t rate_hz)
{
    return (uint32_t)lround(ms * 1e-3 * (double)rate_hz);
}

/* Straight-code body of the whole-step scan of a scale, chosen at setup:
 * one per wavelet and stride, and chain bodies for the DOG1 boxes of the
 * usual sample rates (20, 30, 40 kHz: boxes 4, 6, 8, 12, 16; also 10). */
typedef enum {
    SD_SCAN_MEX_1 = 0,
    SD_SCAN_MEX_2 = 1,
    SD_SCAN_DOG_1 = 2,
    SD_SCAN_DOG_2 = 3,
    SD_SCAN_CHAIN_4 = 4,
    SD_SCAN_CHAIN_6 = 5,
    SD_SCAN_CHAIN_8 = 6,
    SD_SCAN_CHAIN_10 = 7,
    SD_SCAN_CHAIN_12 = 8,
    SD_SCAN_CHAIN_16 = 9
} sd_scan_kind_t;

static uint8_t sd_scan_kind(bool mexhat, uint32_t step, uint32_t w)
{
    if (mexhat) {
        return (step == 1u) ? (uint8_t)SD_SCAN_MEX_1 : (uint8_t)SD_SCAN_MEX_2;
    }
    if (step == 1u) {
        return (uint8_t)SD_SCAN_DOG_1;
    }
    const uint32_t chains[6] = {4u, 6u, 8u, 10u, 12u, 16u};
    for (uint32_t j = 0u; j < 6u; ++j) {
        if (w == chains[j]) {
            return (uint8_t)((uint32_t)SD_SCAN_CHAIN_4 + j);
        }
    }
    return (uint8_t)SD_SCAN_DOG_2;
}

/* Scale s: box width w, kernel = linear B-spline (box * box, support 2w-1)
 * convolved with a second (MEXHAT) or first (DOG1) difference at step w.
 * Computed as the 4th (3rd) w-difference of the second running sum P2, so the
 * kernel is exactly zero-mean and the arithmetic exact in 32 bits. Its L2 norm
 * turns integer coefficients into unit-L2 units for reporting. */
static md_status_t sd_build_scale(sd_stream_t *st, unsigned s, uint32_t *delay, uint32_t *first_valid)
{
    const double w_d = round(SD_BOX_PER_WIDTH * sd_scale_width_ms(&st->cfg, s) * 1e-3 * (double)st->cfg.sample_rate_hz);
    if (!(w_d >= 2.0) || (w_d > (double)SD_BOX_MAX)) {
        return MD_E_ARG;
    }
    const uint32_t w = (uint32_t)w_d;
    const int mexhat = (st->cfg.wavelet == SD_WAVELET_MEXHAT);
    const uint32_t support = (mexhat ? 4u : 3u) * w - 1u;
    double norm2 = 0.0;
    double norm1 = 0.0;
    for (uint32_t j = 0u; j < support; ++j) { /* kernel value at lag j: sum of shifted triangles */
        double k = 0.0;
        for (uint32_t d = 0u; d < (mexhat ? 3u : 2u); ++d) {
            const double wt = mexhat ? ((d == 1u) ? -2.0 : 1.0) : ((d == 1u) ? -1.0 : 1.0);
            const int64_t u = (int64_t)j - (int64_t)(d * w); /* triangle index 0..2w-2, peak w at w-1 */
            if ((u >= 0) && (u <= (int64_t)(2u * w - 2u))) {
                k += wt * (double)((u < (int64_t)w) ? (u + 1) : ((int64_t)(2u * w) - 1 - u));
            }
        }
        norm2 += k * k;
        norm1 += fabs(k);
    }
    st->box[s] = w;
    st->kl1[s] = (uint32_t)norm1;
    st->knorm[s] = sqrt(norm2);
    *delay = (support - 1u) / 2u;
    *first_valid = (support - 1u) - *delay; /* centre index of the first full kernel */
    return MD_OK;
}

static md_status_t sd_setup(sd_stream_t *st)
{
    const sd_config_t *c = &st->cfg;
    const uint32_t align = sd_ms_to_samples(c->align_ms, c->sample_rate_hz);
    st->after = (align == 0u) ? 1u : align;
    st->warm_target = sd_ms_to_samples(c->warmup_ms, c->sample_rate_hz);
    if ((st->after > SD_ALIGN_MAX) || (st->warm_target < 16u)) {
        return MD_E_ARG;
    }
    if (c->method == SD_METHOD_THRESHOLD) {
        st->before = (c->polarity == SD_POLARITY_BOTH) ? st->after : 0u;
        st->dedupe = sd_ms_to_samples(c->dead_time_ms, c->sample_rate_hz);
        st->dmax = 0u;
    } else {
        /* events closer than the mean expected width are one spike */
        st->before = st->after;
        st->merge = sd_ms_to_samples(0.5 * (c->width_min_ms + c->width_max_ms), c->sample_rate_hz);
        st->dedupe = st->merge;
        st->ns = c->n_scales;
        uint32_t delay[MD_WAVELET_SCALES_MAX];
        uint32_t first = 0u;
        for (unsigned s = 0u; s < st->ns; ++s) {
            uint32_t fv = 0u;
            const md_status_t r = sd_build_scale(st, s, &delay[s], &fv);
            if (r < 0) {
                return r;
            }
            st->dmax = (delay[s] > st->dmax) ? delay[s] : st->dmax;
            first = (fv > first) ? fv : first;
        }
        const uint32_t span = (c->wavelet == SD_WAVELET_MEXHAT) ? 4u : 3u;
        for (unsigned s = 0u; s < st->ns; ++s) {
            st->lag[s] = st->dmax - delay[s];
            /* a wide kernel varies slowly: its coefficient is evaluated at every
             * 2nd centre (peak loss <= 1 % for box >= 7, see docs/detector.md) */
            st->stride[s] = (st->box[s] >= SD_DECIMATE_BOX) ? 2u : 1u;
            st->kind[s] = sd_scan_kind(c->wavelet == SD_WAVELET_MEXHAT, st->stride[s], st->box[s]);
            st->back[s] = st->lag[s] + span * st->box[s]; /* oldest tap of the centre of step index 0 */
            st->hist_len = (st->back[s] > st->hist_len) ? st->back[s] : st->hist_len;
        }
        st->c_first = first;
    }
    /* Longest distance from the newest sample back to a sample still needed:
     * kernel delay, a capped run and a capped group, alignment, dedupe, one
     * step. Consumers (extractor) add their own window on top. */
    const uint64_t lat = (uint64_t)st->dmax + 2u * SD_RUN_MAX + st->merge + st->before + st->after + st->dedupe +
                         2u * SD_STEP_SAMPLES;
    st->latency = (uint32_t)lat;
    return (lat + 256u <= SD_RING_SAMPLES) ? MD_OK : MD_E_ARG;
}

static void sd_reset(sd_stream_t *st)
{
    st->phase = SD_PHASE_WARMUP;
    st->status = MD_OK;
    st->warm_n = 0u;
    st->replay_pos = 0u;
    st->warm_sum = 0;
    st->warm_min = INT16_MAX;
    st->warm_max = INT16_MIN;
    st->n = 0u;
    st->above_prev = false;
    st->n_coefs = 0u;
    st->p1 = 0u;
    st->p2 = 0u;
    st->in_run = false;
    st->grp_open = false;
    st->cand_head = 0u;
    st->cand_count = 0u;
    st->has_pend = false;
    st->due = SD_NONE;
    memset(st->sum_sig, 0, sizeof st->sum_sig);
    memset(st->hits, 0, sizeof st->hits);
    memset(st->p2lin, 0, sizeof st->p2lin);
    st->p2_base = st->hist_len;
    memset(&st->ev, 0, sizeof st->ev);
}

md_status_t sd_stream_init(sd_stream_t *st, const sd_config_t *cfg)
{
    if ((st == NULL) || (cfg == NULL) || !sd_config_valid(cfg)) {
        return MD_E_ARG;
    }
    memset(st, 0, sizeof *st);
    st->cfg = *cfg;
    const md_status_t r = sd_setup(st);
    if (r < 0) {
        st->phase = SD_PHASE_IDLE;
        return r;
    }
    sd_reset(st);
    return MD_OK;
}

md_status_t sd_stream_restart(sd_stream_t *st)
{
    if ((st == NULL) || (st->phase == SD_PHASE_IDLE)) {
        return MD_E_STATE;
    }
    sd_reset(st);
    return MD_OK;
}

bool sd_stream_busy(const sd_stream_t *st)
{
    return (st != NULL) && (st->phase == SD_PHASE_REPLAY || st->phase == SD_PHASE_ENDED) &&
           (st->replay_pos < st->warm_n) && (st->status == MD_OK);
}

const sd_events_t *sd_stream_events(const sd_stream_t *st)
{
    return (st == NULL) ? NULL : &st->ev;
}

uint32_t sd_stream_latency(const sd_stream_t *st)
{
    return (st == NULL) ? 0u : st->latency;
}

uint32_t sd_stream_processed(const sd_stream_t *st)
{
    return (st == NULL) ? 0u : st->n;
}

sd_view_t sd_stream_view(const sd_stream_t *st)
{
    sd_view_t v = {NULL, SD_RING_MASK, 0u, 0u};
    if (st != NULL) {
        v.x = st->buf;
        v.hi = st->n;
        v.lo = (st->n > SD_RING_SAMPLES) ? (st->n - SD_RING_SAMPLES) : 0u;
    }
    return v;
}

uint32_t sd_view_argmin(const sd_view_t *v, uint32_t lo, uint32_t hi)
{
    if ((v == NULL) || (v->hi == 0u)) {
        return lo;
    }
    lo = (lo < v->lo) ? v->lo : lo;
    hi = (hi >= v->hi) ? (v->hi - 1u) : hi;
    const int16_t *x = v->x;
    const uint32_t mask = v->mask;
    uint32_t best = lo;
    if (lo <= hi) {
        int16_t min = x[lo & mask];
        for (uint32_t i = lo + 1u; i <= hi; ++i) {
            const int16_t xi = x[i & mask];
            if (xi < min) {
                best = i;
                min = xi;
            }
        }
    }
    return best;
}

md_status_t sd_stream_copy(const sd_stream_t *st, uint32_t start, size_t len, int16_t *dst)
{
    if ((st == NULL) || (dst == NULL)) {
        return MD_E_ARG;
    }
    const sd_view_t v = sd_stream_view(st);
    if ((start < v.lo) || ((uint64_t)start + len > (uint64_t)v.hi)) {
        return MD_E_ARG;
    }
    for (size_t j = 0u; j < len; ++j) {
        dst[j] = v.x[(start + (uint32_t)j) & SD_RING_MASK];
    }
    return MD_OK;
}

/* ---- events: alignment, merging, commit -------------------------------- */

static void sd_commit(sd_stream_t *st, uint32_t t)
{
    if (st->ev.n >= MD_MAX_SPIKES) {
        st->ev.n_overflow++;
        st->ev.flags |= SD_FLAG_OVERFLOW;
        return;
    }
    st->ev.t[st->ev.n] = t;
    st->ev.n++;
}

/* Moves a candidate to the minimum of x in [t - before, t + after] (the
 * thesis aligns spikes by their minimum), then either merges it into the
 * pending event (closer than `dedupe`; the deeper minimum wins, so a pending
 * event only ever moves later) or commits the pending one and replaces it. */
static void sd_emit(sd_stream_t *st, uint32_t t)
{
    const sd_view_t v = sd_stream_view(st);
    const uint32_t lo = (t > st->before) ? (t - st->before) : 0u;
    const uint32_t best = sd_view_argmin(&v, lo, t + st->after);
    if (st->has_pend && (best <= st->pend_t + st->dedupe)) {
        st->ev.n_merged++;
        if ((best > st->pend_t) && (v.x[best & SD_RING_MASK] < v.x[st->pend_t & SD_RING_MASK])) {
            st->pend_t = best;
        }
        return;
    }
    if (st->has_pend) {
        sd_commit(st, st->pend_t);
    }
    st->pend_t = best;
    st->has_pend = true;
}

static void sd_cand_push(sd_stream_t *st, uint32_t t)
{
    if (st->cand_count >= SD_CAND_MAX) {
        st->ev.n_cand_dropped++;
        return;
    }
    st->cand[(st->cand_head + st->cand_count) % SD_CAND_MAX] = t;
    st->cand_count++;
}

/* Next centre (wavelet) or sample (threshold) the online detector will look
 * at: every future candidate lies at or after it. */
static uint32_t sd_next_centre(const sd_stream_t *st)
{
    return (st->n > st->dmax) ? (st->n - st->dmax) : 0u;
}

/* Lower bound on the aligned time of every future emission. */
static uint32_t sd_floor(const sd_stream_t *st)
{
    uint32_t f = st->in_run ? st->run_start : sd_next_centre(st);
    if (st->grp_open && (st->grp_first < f)) {
        f = st->grp_first;
    }
    if ((st->cand_count > 0u) && (st->cand[st->cand_head] < f)) {
        f = st->cand[st->cand_head];
    }
    return (f > st->before) ? (f - st->before) : 0u;
}

uint32_t sd_stream_horizon(const sd_stream_t *st, bool *has_pend, uint32_t *pend_t)
{
    if (st == NULL) {
        return 0u;
    }
    if (has_pend != NULL) {
        *has_pend = st->has_pend;
    }
    if (pend_t != NULL) {
        *pend_t = st->pend_t;
    }
    if (st->phase == SD_PHASE_DONE) {
        return SD_NONE;
    }
    return ((st->phase == SD_PHASE_RUN) || (st->phase == SD_PHASE_REPLAY) || (st->phase == SD_PHASE_ENDED))
               ? sd_floor(st)
               : 0u;
}

/* ---- wavelet statistics (Nenadic & Burdick) ----------------------------- */

/* Decision threshold of scale s from sigma, M (mean supra-threshold |c|) and
 * P(spike): M/2 + sigma^2/M (L + ln(P(noise)/P(spike))), clamped at 0. */
static void sd_scale_decision(sd_stream_t *st, unsigned s, uint64_t sum, uint32_t hits, uint32_t count)
{
    const double n_eff = (count > 0u) ? ((double)count / (double)st->stride[s]) : 1.0; /* coefficients evaluated */
    const double sigma = st->sigma_c[s];
    const double m = (hits > 0u) ? ((double)sum / (double)hits) : st->hard_c[s];
    const double p_spike = (hits > 0u) ? ((double)hits / n_eff) : (1.0 / n_eff);
    const double ln_prior = (p_spike < 1.0) ? log((1.0 - p_spike) / p_spike) : -30.0;
    double dth = 0.5 * m + sigma * sigma / m * (SD_L_SCALE * st->cfg.cost_ratio_l + ln_prior);
    dth = fmin(fmax(dth, 0.0), 4.0e9);
    st->dth_i[s] = (uint32_t)dth; /* |c| integer: |c| > dth  <=>  |c| > floor(dth) */
    st->lo_i[s] = (st->dth_i[s] < st->hard_i[s]) ? st->dth_i[s] : st->hard_i[s];
    st->ev.scale_dth[s] = dth / st->knorm[s];
}

/* Signed coefficient (two's complement in a uint32) whose oldest P2 tap is
 * q[0]: the 4th (3rd) w-difference of P2. */
static inline uint32_t sd_coef_at(const uint32_t *q, uint32_t w, bool mexhat)
{
    return mexhat ? (q[4u * w] - 4u * q[3u * w] + 6u * q[2u * w] - 4u * q[w] + q[0])
                  : (q[3u * w] - 3u * q[2u * w] + 3u * q[w] - q[0]);
}

/* Oldest tap of scale s for the centre whose newest sample is step index i. */
static const uint32_t *sd_taps(const sd_stream_t *st, unsigned s, uint32_t i)
{
    return &st->p2lin[st->p2_base + i - st->back[s]];
}

static uint32_t sd_abs_u32(uint32_t c)
{
    return ((c & 0x80000000u) != 0u) ? (0u - c) : c;
}

/* |c| for c >= 0, |c| - 1 for c < 0 (one instruction on Thumb-2). */
static inline uint32_t sd_mag_floor(uint32_t c)
{
    return c ^ (0u - (c >> 31u));
}

/* Slow path of one coefficient above the lower of the two thresholds:
 * counts it for M and P(spike) if above the hard threshold, and says
 * whether it exceeds the decision threshold. */
static uint32_t sd_scale_hit(sd_stream_t *st, unsigned s, uint32_t c)
{
    const uint32_t mag = sd_abs_u32(c);
    if (mag > st->hard_i[s]) {
        st->hits[s]++;
        st->sum_sig[s] += mag;
    }
    return (mag > st->dth_i[s]) ? 1u : 0u;
}

/* Running sums of x[0..k) into out, and x into dst unless dst is NULL; `k`
 * is a literal at the full-step call (the loop is then straight code). */
static inline void sd_sums(const int16_t *x, uint32_t *out, int16_t *dst, uint32_t k, uint32_t *p1, uint32_t *p2)
{
    uint32_t a = *p1, b = *p2;
#pragma GCC unroll 32
    for (uint32_t i = 0u; i < k; ++i) {
        const int16_t v = x[i];
        const int32_t xv = v;
        a += (uint32_t)xv;
        b += a;
        out[i] = b;
        if (dst != NULL) {
            dst[i] = v;
        }
    }
    *p1 = a;
    *p2 = b;
}

/* Running sums of x[0..k) (online indices n0..n0+k-1) into the P2 buffer at
 * p2_base and, if `ring`, the raw samples into the delay line in the same
 * pass. A step never wraps the delay line (SD_RING_SAMPLES is a multiple of
 * the step and steps end on multiples of it). Replayed warm-up samples are
 * copied down from buf[n0] to buf[n0 & mask] <= n0 - SD_RING_SAMPLES or read
 * in place, so the forward copy never overwrites a sample still to be read. */
static inline void sd_block_sums(sd_stream_t *st, const int16_t *x, uint32_t n0, uint32_t k, bool ring)
{
    uint32_t *out = &st->p2lin[st->p2_base];
    int16_t *dst = &st->buf[n0 & SD_RING_MASK];
    const bool copy = ring && (x != dst);
    if (k == SD_STEP_SAMPLES) {
        if (copy) {
            sd_sums(x, out, dst, SD_STEP_SAMPLES, &st->p1, &st->p2);
        } else {
            sd_sums(x, out, NULL, SD_STEP_SAMPLES, &st->p1, &st->p2);
        }
        return;
    }
    uint32_t p1 = st->p1, p2 = st->p2;
#pragma GCC unroll 4
    for (uint32_t i = 0u; i < k; ++i) {
        const int16_t v = x[i];
        const int32_t xv = v;
        p1 += (uint32_t)xv;
        p2 += p1;
        out[i] = p2;
        if (copy) {
            dst[i] = v;
        }
    }
    st->p1 = p1;
    st->p2 = p2;
}

/* Moves past a step of k sums. Once the next step would not fit, the last
 * hist_len sums (the history every tap of the next step reaches back into)
 * move to the buffer's start: one copy every few steps, not every step. */
static void sd_block_advance(sd_stream_t *st, uint32_t k)
{
    const uint32_t len = (uint32_t)(sizeof st->p2lin / sizeof st->p2lin[0]);
    st->p2_base += k;
    if (st->p2_base > len - SD_STEP_SAMPLES) {
        const uint32_t h = st->hist_len;
        memmove(&st->p2lin[0], &st->p2lin[st->p2_base - h], h * sizeof st->p2lin[0]);
        st->p2_base = h;
    }
}

/* Clears the running sums and their history (start of a pass): the taps of
 * the first step reach back into p2lin[0 .. hist_len); everything after it
 * is written before it is read. */
static void sd_sums_reset(sd_stream_t *st)
{
    st->p1 = 0u;
    st->p2 = 0u;
    memset(st->p2lin, 0, st->hist_len * sizeof st->p2lin[0]);
    st->p2_base = st->hist_len;
}

/* Largest (c + lo) mod 2^32 over the evaluated centres of a step: it
 * exceeds 2 lo iff some |c| > lo (lo < 2^31), so the hot loops carry no
 * branch, call or store; `step` is a literal at each call (1 or 2). */
static inline uint32_t sd_scan(const uint32_t *q, size_t w, bool mexhat, uint32_t i0, uint32_t k, uint32_t step,
                               uint32_t lo)
{
    uint32_t m = 0u;
    if (mexhat) {
        for (uint32_t i = i0; i < k; i += step) {
            const uint32_t *r = &q[i];
            const uint32_t v = ((r[4u * w] + r[0]) - 4u * (r[3u * w] + r[w]) + 6u * r[2u * w]) + lo;
            m = (v > m) ? v : m;
        }
    } else {
        for (uint32_t i = i0; i < k; i += step) {
            const uint32_t *r = &q[i];
            const uint32_t v = ((r[3u * w] - r[0]) - 3u * (r[2u * w] - r[w])) + lo;
            m = (v > m) ? v : m;
        }
    }
    return m;
}

/* A cheaper, looser test for a whole step (centres 0, step, ..., 31),
 * straight code: the OR over the centres of sd_mag_floor(c) is at least every
 * sd_mag_floor(c), and |c| > lo implies sd_mag_floor(c) >= lo, so OR < lo
 * proves that no |c| exceeds lo. Otherwise (a few per cent of the steps) the
 * exact pass decides. `mexhat` and `step` are literals at each call. */
static inline bool sd_scan_step(const uint32_t *q, size_t w, bool mexhat, uint32_t step, uint32_t lo)
{
    const uint32_t *q1 = &q[w];
    const uint32_t *q2 = &q[2u * w];
    const uint32_t *q3 = &q[3u * w];
    uint32_t acc = 0u;
    if (mexhat) {
        const uint32_t *q4 = &q[4u * w];
#pragma GCC unroll 32
        for (uint32_t i = 0u; i < SD_STEP_SAMPLES; i += step) {
            acc |= sd_mag_floor(((q4[i] + q[i]) - 4u * (q3[i] + q1[i])) + 6u * q2[i]);
        }
    } else {
#pragma GCC unroll 32
        for (uint32_t i = 0u; i < SD_STEP_SAMPLES; i += step) {
            acc |= sd_mag_floor((q3[i] - q[i]) - 3u * (q2[i] - q1[i]));
        }
    }
    return acc >= lo;
}

/* sd_scan_step of the DOG1 wavelet at stride 2 for an even box w that is a
 * literal at the call: the evaluated centres 0, 2, ..., 30 lie on the w/2
 * chains r, r + w, r + 2w, ... (r = 0, 2, ..., w - 2). Along a chain the
 * taps' first differences D are shared, c = D2 - 2 D1 + D0 (the third
 * difference), so each coefficient after a chain's first costs one load and
 * one subtraction more instead of four loads. Same coefficients, same
 * (loose) test. */
static inline bool sd_scan_chain(const uint32_t *q, uint32_t w, uint32_t lo)
{
    uint32_t acc = 0u;
#pragma GCC unroll 16
    for (uint32_t r = 0u; r < w; r += 2u) {
        uint32_t p = q[r + w];
        uint32_t d0 = p - q[r];
        uint32_t t = q[r + 2u * w];
        uint32_t d1 = t - p;
        p = t;
#pragma GCC unroll 16
        for (uint32_t i = r; i < SD_STEP_SAMPLES; i += w) {
            t = q[i + 3u * w];
            const uint32_t d2 = t - p;
            acc |= sd_mag_floor((d2 + d0) - 2u * d1); /* the coefficient of centre i */
            p = t;
            d0 = d1;
            d1 = d2;
        }
    }
    return acc >= lo;
}

/* The loose whole-step test of one scale with the body of its kind. */
static bool sd_scan_full(const uint32_t *q, size_t w, uint8_t kind, uint32_t lo)
{
    bool r;
    switch (kind) {
    case (uint8_t)SD_SCAN_MEX_1: r = sd_scan_step(q, w, true, 1u, lo); break;
    case (uint8_t)SD_SCAN_MEX_2: r = sd_scan_step(q, w, true, 2u, lo); break;
    case (uint8_t)SD_SCAN_DOG_1: r = sd_scan_step(q, w, false, 1u, lo); break;
    case (uint8_t)SD_SCAN_CHAIN_4: r = sd_scan_chain(q, 4u, lo); break;
    case (uint8_t)SD_SCAN_CHAIN_6: r = sd_scan_chain(q, 6u, lo); break;
    case (uint8_t)SD_SCAN_CHAIN_8: r = sd_scan_chain(q, 8u, lo); break;
    case (uint8_t)SD_SCAN_CHAIN_10: r = sd_scan_chain(q, 10u, lo); break;
    case (uint8_t)SD_SCAN_CHAIN_12: r = sd_scan_chain(q, 12u, lo); break;
    case (uint8_t)SD_SCAN_CHAIN_16: r = sd_scan_chain(q, 16u, lo); break;
    default: r = sd_scan_step(q, w, false, 2u, lo); break;
    }
    return r;
}

/* Exact pass over a step some coefficient of which may exceed lo: hit bits
 * (bit i: centre of step index i fires scale s) and the M / P(spike) counts.
 * `mexhat` and `step` are literals at each call. */
static inline uint32_t sd_mask_loop(sd_stream_t *st, unsigned s, const uint32_t *q, uint32_t i0, uint32_t k,
                                    bool mexhat, uint32_t step)
{
    const uint32_t lo = st->lo_i[s];
    const uint32_t w = st->box[s];
    uint32_t mask = 0u;
    for (uint32_t i = i0; i < k; i += step) { /* rare: some coefficient passed the lower threshold */
        const uint32_t c = sd_coef_at(&q[i], w, mexhat);
        if ((c + lo) > 2u * lo) {
            mask |= sd_scale_hit(st, s, c) << i;
        }
    }
    return mask;
}

static uint32_t sd_block_mask(sd_stream_t *st, unsigned s, const uint32_t *q, uint32_t i0, uint32_t k)
{
    const bool mexhat = (st->cfg.wavelet == SD_WAVELET_MEXHAT);
    if (st->stride[s] == 1u) {
        return mexhat ? sd_mask_loop(st, s, q, i0, k, true, 1u) : sd_mask_loop(st, s, q, i0, k, false, 1u);
    }
    const uint32_t mask = mexhat ? sd_mask_loop(st, s, q, i0, k, true, 2u) : sd_mask_loop(st, s, q, i0, k, false, 2u);
    /* a decimated scale's decision holds until its next evaluated centre */
    return mask | ((mask << 1u) & (0xFFFFFFFFu >> ((32u - k) & 31u))); /* bits below k (k >= 1) */
}

/* Hit bits of every scale for one step: bit i set if the centre of sample
 * n0 + i (i0 <= i < k <= 32) fires some scale. Wide scales (stride 2) are
 * evaluated at even centres, their decision held for the following odd one.
 * Steps start on multiples of 32, so the same centres are evaluated in
 * every pass and whatever the chunking. A scale's exact pass (sd_block_mask)
 * runs only if its scan says some |c| may exceed the lower threshold. */
static uint32_t sd_block_scales(sd_stream_t *st, uint32_t i0, uint32_t k)
{
    uint32_t hits = 0u;
    if ((i0 == 0u) && (k == SD_STEP_SAMPLES)) {
        for (unsigned s = 0u; s < st->ns; ++s) {
            const uint32_t lo = st->lo_i[s];
            const uint32_t *q = sd_taps(st, s, 0u);
            if ((lo < 0x7FFFFFFFu) && sd_scan_full(q, st->box[s], st->kind[s], lo)) {
                hits |= sd_block_mask(st, s, q, 0u, k);
            }
        }
        return hits;
    }
    const bool mexhat = (st->cfg.wavelet == SD_WAVELET_MEXHAT);
    for (unsigned s = 0u; s < st->ns; ++s) {
        const uint32_t lo = st->lo_i[s];
        const uint32_t *q = sd_taps(st, s, 0u);
        const uint32_t step = st->stride[s];
        const uint32_t j0 = (i0 + step - 1u) / step * step;
        if (lo >= 0x7FFFFFFFu) {
            continue; /* flat scale */
        }
        const uint32_t m = (step == 1u) ? sd_scan(q, st->box[s], mexhat, j0, k, 1u, lo)
                                        : sd_scan(q, st->box[s], mexhat, j0, k, 2u, lo);
        if (m > 2u * lo) {
            hits |= sd_block_mask(st, s, q, j0, k);
        }
    }
    return hits;
}

/* First step-local index whose centre has a full kernel. */
static uint32_t sd_block_first(const sd_stream_t *st, uint32_t n0, uint32_t k)
{
    const uint32_t first = st->dmax + st->c_first;
    if (n0 >= first) {
        return 0u;
    }
    return (first - n0 < k) ? (first - n0) : k;
}

/* M and P(spike) over every warm-up coefficient (hard threshold only). */
static void sd_warm_hits(sd_stream_t *st)
{
    sd_sums_reset(st);
    st->n_coefs = 0u;
    for (unsigned s = 0u; s < st->ns; ++s) {
        st->dth_i[s] = SD_NONE;
        st->lo_i[s] = st->hard_i[s];
    }
    for (uint32_t n0 = 0u; n0 < st->warm_n; n0 += SD_STEP_SAMPLES) {
        const uint32_t k = ((st->warm_n - n0) < SD_STEP_SAMPLES) ? (st->warm_n - n0) : SD_STEP_SAMPLES;
        sd_block_sums(st, &st->buf[n0], n0, k, false);
        const uint32_t i0 = sd_block_first(st, n0, k);
        (void)sd_block_scales(st, i0, k);
        st->n_coefs += k - i0;
        sd_block_advance(st, k);
    }
}

#define SD_WARM_GROUP 2u /* scales binned together by one warm-up pass (two histograms) */

/* Median search of the sigma_j: the bin shift of each scale, the coarse bins
 * of both middle ranks (and the ranks before them) and, in the fine pass,
 * the smallest low byte seen in the upper rank's coarse bin. */
typedef struct {
    uint32_t shift[MD_WAVELET_SCALES_MAX];
    size_t bin[MD_WAVELET_SCALES_MAX][2];
    uint64_t before[MD_WAVELET_SCALES_MAX][2];
    uint32_t fmin[SD_WARM_GROUP];
    uint64_t total;
} sd_warm_t;

/* Bins |c| >> shift of the eligible centres [i, k) (every 2nd, from i) of
 * one scale: the coarse pass (b == NULL) counts its high byte; the fine pass
 * counts the low byte of those in coarse bin b[0] and keeps the least low
 * byte of those in coarse bin b[1] (SD_NONE when both ranks share a coarse
 * bin). `mexhat` and whether b is NULL are literals at each call. */
static inline void sd_warm_bin_loop(const uint32_t *q, uint32_t w, bool mexhat, uint32_t i, uint32_t k, uint32_t shift,
                                    const size_t *b, uint32_t *bins, uint32_t *fmin)
{
    const uint32_t b0 = (b != NULL) ? (uint32_t)b[0] : 0u;
    const uint32_t b1 = (b != NULL) ? (uint32_t)b[1] : 0u;
    for (; i < k; i += SD_SIGMA_STRIDE) {
        const uint32_t u = sd_abs_u32(sd_coef_at(&q[i], w, mexhat)) >> shift;
        const uint32_t hb = u >> 8u;
        if (b == NULL) {
            bins[hb]++;
        } else {
            bins[u & 0xFFu] += (hb == b0) ? 1u : 0u;
            if ((hb == b1) && ((u & 0xFFu) < *fmin)) {
                *fmin = u & 0xFFu;
            }
        }
    }
}

static void sd_warm_bin(const uint32_t *q, uint32_t w, bool mexhat, uint32_t i, uint32_t k, uint32_t shift,
                        const size_t *b, uint32_t *bins, uint32_t *fmin)
{
    if (b == NULL) {
        if (mexhat) {
            sd_warm_bin_loop(q, w, true, i, k, shift, NULL, bins, fmin);
        } else {
            sd_warm_bin_loop(q, w, false, i, k, shift, NULL, bins, fmin);
        }
    } else if (mexhat) {
        sd_warm_bin_loop(q, w, true, i, k, shift, b, bins, fmin);
    } else {
        sd_warm_bin_loop(q, w, false, i, k, shift, b, bins, fmin);
    }
}

/* One pass over every SD_SIGMA_STRIDE-th warm-up coefficient of the scales
 * a .. a+ng-1 (ng <= SD_WARM_GROUP; histogram rs for the first, rs2 for the
 * second). Coarse pass if !fine, else the fine pass in the bins found. */
static void sd_warm_pass(sd_stream_t *st, bool fine, unsigned a, unsigned ng, sd_warm_t *w)
{
    const bool mexhat = (st->cfg.wavelet == SD_WAVELET_MEXHAT);
    const uint32_t first = st->dmax + st->c_first;
    uint32_t *const bins[SD_WARM_GROUP] = {st->rs.bins, st->rs2.bins};
    size_t b[SD_WARM_GROUP][2];
    sd_sums_reset(st);
    memset(st->rs.bins, 0, sizeof st->rs.bins);
    memset(st->rs2.bins, 0, sizeof st->rs2.bins);
    for (unsigned g = 0u; g < ng; ++g) {
        w->fmin[g] = RS_LEVEL_BINS - 1u;
        b[g][0] = w->bin[a + g][0];
        b[g][1] = (w->bin[a + g][1] == w->bin[a + g][0]) ? (size_t)SD_NONE : w->bin[a + g][1];
    }
    for (uint32_t n0 = 0u; n0 < st->warm_n; n0 += SD_STEP_SAMPLES) {
        const uint32_t k = ((st->warm_n - n0) < SD_STEP_SAMPLES) ? (st->warm_n - n0) : SD_STEP_SAMPLES;
        sd_block_sums(st, &st->buf[n0], n0, k, false);
        uint32_t i = sd_block_first(st, n0, k);
        if (i < k) { /* the first eligible centre: n0 + i - first a multiple of the stride */
            i += (SD_SIGMA_STRIDE - ((n0 + i - first) % SD_SIGMA_STRIDE)) % SD_SIGMA_STRIDE;
        }
        for (unsigned g = 0u; g < ng; ++g) {
            /* |c| < 2^31: a shift of 31 already gives 0, as 32 would */
            const uint32_t sh = (w->shift[a + g] < 31u) ? w->shift[a + g] : 31u;
            sd_warm_bin(sd_taps(st, a + g, 0u), st->box[a + g], mexhat, i, k, sh, fine ? b[g] : NULL, bins[g],
                        &w->fmin[g]);
        }
        sd_block_advance(st, k);
    }
}

/* sigma_j, the hard threshold and the reported figures of scale s from the
 * median |c|; 0 if the scale is flat (it then never fires). */
static int sd_scale_sigma(sd_stream_t *st, unsigned s, double med, double n_nom)
{
    st->sigma_c[s] = med / SD_MAD_TO_SIGMA;
    st->hard_c[s] = st->sigma_c[s] * sqrt(2.0 * log(n_nom));
    st->hard_i[s] = (uint32_t)fmin(st->hard_c[s], 4.0e9);
    st->ev.scale_width_ms[s] = sd_scale_width_ms(&st->cfg, s);
    st->ev.scale_sigma[s] = st->sigma_c[s] / st->knorm[s];
    if (!(st->sigma_c[s] > 0.0)) {
        st->hard_i[s] = SD_NONE;
        st->dth_i[s] = SD_NONE;
        st->lo_i[s] = SD_NONE;
        return 0;
    }
    return 1;
}

/* Exact medians (to 2^shift counts) of |c| for the scales a .. a+ng-1: one
 * coarse pass locates both middle ranks of each, one fine pass resolves
 * them. Ranks in different coarse bins are neighbours (total even), so the
 * upper one is the least value of its bin. */
static int sd_warm_medians(sd_stream_t *st, unsigned a, unsigned ng, sd_warm_t *w, double n_nom)
{
    const uint64_t k[2] = {(w->total - 1u) / 2u, w->total / 2u};
    sd_warm_pass(st, false, a, ng, w);
    for (unsigned g = 0u; g < ng; ++g) {
        const uint32_t *bins = (g == 0u) ? st->rs.bins : st->rs2.bins;
        for (unsigned r = 0u; r < 2u; ++r) {
            w->bin[a + g][r] = rs_rank_bin(bins, RS_LEVEL_BINS, k[r], &w->before[a + g][r]);
        }
    }
    sd_warm_pass(st, true, a, ng, w);
    int any = 0;
    for (unsigned g = 0u; g < ng; ++g) {
        const unsigned s = a + g;
        const uint32_t *bins = (g == 0u) ? st->rs.bins : st->rs2.bins;
        double v = 0.0;
        for (unsigned r = 0u; r < 2u; ++r) {
            const size_t fine = ((r == 0u) || (w->bin[s][1] == w->bin[s][0]))
                                    ? rs_rank_bin(bins, RS_LEVEL_BINS, k[r] - w->before[s][r], NULL)
                                    : (size_t)w->fmin[g];
            const size_t uv = (w->bin[s][r] << 8u) | fine;
            const double u = (double)uv;
            /* a shifted value u stands for [u, u+1) * 2^shift */
            v += 0.5 * ((w->shift[s] == 0u) ? u : ((u + 0.5) * ldexp(1.0, (int)w->shift[s])));
        }
        any |= sd_scale_sigma(st, s, v, n_nom);
    }
    return any;
}

/* Per-scale statistics of Nenadic & Burdick on the warm-up: sigma =
 * median(|c - mean c|)/0.6745, hard threshold sigma*sqrt(2 ln N) with N the
 * nominal interval length, M and P(spike) from the supra-threshold
 * coefficients. Returns 0 if no scale carries noise. */
static int sd_wavelet_stats(sd_stream_t *st)
{
    sd_warm_t w;
    memset(&w, 0, sizeof w);
    const uint32_t first = st->dmax + st->c_first;
    w.total = (st->warm_n > first) ? ((st->warm_n - first + SD_SIGMA_STRIDE - 1u) / SD_SIGMA_STRIDE) : 0u;
    if (w.total == 0u) {
        return 0;
    }
    const double n_nom = fmax(st->cfg.interval_s * (double)st->cfg.sample_rate_hz, (double)w.total + 2.0);
    for (unsigned s = 0u; s < st->ns; ++s) {
        /* The kernel sums to zero exactly, so mean(c) over the warm-up is a
         * boundary term of order range/N: it is taken as 0. A zero-sum kernel
         * bounds |c| by L1/2 * (max x - min x), which sets the bin shift. */
        const uint64_t range = ((uint64_t)st->kl1[s] / 2u + 1u) *
                               (uint64_t)((int64_t)st->warm_max - (int64_t)st->warm_min + 1);
        for (unsigned k = 0u; (k < 32u) && ((range >> w.shift[s]) > 0xFFFFu); ++k) {
            w.shift[s]++;
        }
    }
    int any = 0;
    for (unsigned a = 0u; a < st->ns; a += SD_WARM_GROUP) {
        const unsigned ng = ((st->ns - a) < SD_WARM_GROUP) ? (st->ns - a) : SD_WARM_GROUP;
        any |= sd_warm_medians(st, a, ng, &w, n_nom);
    }
    if (!any) {
        return 0;
    }
    sd_warm_hits(st);
    for (unsigned s = 0u; s < st->ns; ++s) {
        if (st->sigma_c[s] > 0.0) {
            sd_scale_decision(st, s, st->sum_sig[s], st->hits[s], st->n_coefs);
        }
    }
    /* the online pass (replay included) recounts from zero */
    memset(st->sum_sig, 0, sizeof st->sum_sig);
    memset(st->hits, 0, sizeof st->hits);
    sd_sums_reset(st);
    st->n_coefs = 0u;
    return 1;
}

static md_status_t sd_calibrate(sd_stream_t *st)
{
    const uint32_t n = st->warm_n;
    st->ev.warmup_samples = n;
    if (n < 16u) {
        return MD_E_DEGENERATE;
    }
    st->ev.offset = (int32_t)llround((double)st->warm_sum / (double)n);
    st->ev.noise_sigma = rs_abs_median_i16(st->buf, n, st->ev.offset, &st->rs) / SD_MAD_TO_SIGMA;
    if (st->cfg.method == SD_METHOD_THRESHOLD) {
        if (!(st->ev.noise_sigma > 0.0)) {
            return MD_E_DEGENERATE;
        }
        st->ev.threshold = st->cfg.k_sigma * st->ev.noise_sigma;
        /* integer x: offset - x > thr  <=>  x <= offset - floor(thr) - 1 */
        const int32_t k = (int32_t)fmin(floor(st->ev.threshold), 70000.0) + 1;
        st->thr_lo = st->ev.offset - k;
        st->thr_hi = (st->cfg.polarity == SD_POLARITY_BOTH) ? (st->ev.offset + k) : INT32_MAX;
        return MD_OK;
    }
    st->ev.n_scales = st->ns;
    if ((n < 2u * st->dmax + st->c_first + 8u) || !sd_wavelet_stats(st)) {
        return MD_E_DEGENERATE;
    }
    st->next_refine = SD_REFINE_SAMPLES * (st->warm_n / SD_REFINE_SAMPLES + 1u);
    return MD_OK;
}

/* ---- online detection ---------------------------------------------------- */

static void sd_group_add(sd_stream_t *st, uint32_t mid)
{
    if (st->grp_open && (mid - st->grp_last < st->merge) && (mid - st->grp_first <= SD_RUN_MAX)) {
        st->grp_last = mid;
        return;
    }
    if (st->grp_open) {
        sd_cand_push(st, (st->grp_first + st->grp_last) / 2u);
    }
    st->grp_first = mid;
    st->grp_last = mid;
    st->grp_open = true;
}

/* A run of spike-like centres (any scale above its decision threshold)
 * gives a candidate at its middle; runs closer than the merge distance form
 * one group, emitted at the group's middle (as in the reference code). */
static void sd_run_edge(sd_stream_t *st, uint32_t c, bool hit)
{
    if (hit && !st->in_run) {
        st->run_start = c;
        st->in_run = true;
    } else if (!hit && st->in_run) {
        sd_group_add(st, (st->run_start + c - 1u) / 2u);
        st->in_run = false;
    } else if (hit && (c - st->run_start >= SD_RUN_MAX)) {
        sd_group_add(st, (st->run_start + c - 1u) / 2u); /* split an endless run: bounded latency */
        st->run_start = c;
    } else {
        /* no change */
    }
    st->due = st->n; /* let the service look at groups and commits now */
}

/* Index of the lowest set bit of b != 0 (de Bruijn multiplication). */
static uint32_t sd_lowest_bit(uint32_t b)
{
    static const uint8_t pos[32] = {0u,  1u,  28u, 2u,  29u, 14u, 24u, 3u, 30u, 22u, 20u, 15u, 25u, 17u, 4u,  8u,
                                    31u, 27u, 13u, 23u, 21u, 19u, 16u, 7u, 26u, 12u, 18u, 6u,  11u, 5u,  10u, 9u};
    return pos[((b & (0u - b)) * 0x077CB531u) >> 27u];
}

/* The run logic of one step: sd_run_edge at every centre i0 <= i < k whose
 * hit bit differs from the run state, and at every SD_RUN_MAX-th centre of
 * a run (the split), in order, as a scan of every centre would call it;
 * the centres in between are skipped with bit operations. */
static void sd_step_runs(sd_stream_t *st, uint32_t n0, uint32_t i0, uint32_t k, uint32_t hits)
{
    const uint32_t valid = 0xFFFFFFFFu >> ((32u - k) & 31u); /* bits below k (k >= 1) */
    uint32_t i = i0;
    for (uint32_t it = 0u; (it <= 2u * SD_STEP_SAMPLES) && (i < k); ++it) {
        const uint32_t from = 0xFFFFFFFFu << i; /* bits i and above (i < k <= 32) */
        if (!st->in_run) {
            const uint32_t rest = hits & valid & from;
            if (rest == 0u) {
                return;
            }
            i = sd_lowest_bit(rest);
            sd_run_edge(st, n0 + i - st->dmax, true); /* a run starts */
        } else {
            const uint32_t gaps = ~hits & valid & from;
            const uint32_t end = (gaps != 0u) ? sd_lowest_bit(gaps) : k;            /* first centre without a hit */
            const uint32_t left = SD_RUN_MAX - (n0 + i - st->dmax - st->run_start); /* centres to the split */
            if ((n0 + i - st->dmax - st->run_start >= SD_RUN_MAX) || (left < end - i)) {
                i = ((n0 + i - st->dmax - st->run_start) >= SD_RUN_MAX) ? i : (i + left);
                sd_run_edge(st, n0 + i - st->dmax, true); /* split */
            } else if (end < k) {
                i = end;
                sd_run_edge(st, n0 + i - st->dmax, false); /* the run ends */
            } else {
                return; /* the run goes on into the next step */
            }
        }
        i++;
    }
}

static void sd_refine(sd_stream_t *st)
{
    for (unsigned s = 0u; s < st->ns; ++s) {
        if (st->sigma_c[s] > 0.0) {
            sd_scale_decision(st, s, st->sum_sig[s], st->hits[s], st->n_coefs);
        }
    }
}

static uint32_t sd_min_u32(uint32_t a, uint32_t b)
{
    return (a < b) ? a : b;
}

/* Slow path, run when the sample index reaches `due`: closes a group no
 * future run can join, aligns candidates whose look-ahead has arrived,
 * commits the pending event once no future candidate can merge with it,
 * refines the wavelet statistics, and computes the next `due`. */
static void sd_service(sd_stream_t *st)
{
    if (st->grp_open) {
        const uint32_t next_mid = st->in_run ? st->run_start : sd_next_centre(st);
        if (next_mid >= st->grp_last + st->merge) {
            sd_cand_push(st, (st->grp_first + st->grp_last) / 2u);
            st->grp_open = false;
        }
    }
    for (uint32_t k = 0u; (k < SD_CAND_MAX) && (st->cand_count > 0u); ++k) {
        const uint32_t t = st->cand[st->cand_head];
        if (t + st->after >= st->n) {
            break;
        }
        st->cand_head = (st->cand_head + 1u) % SD_CAND_MAX;
        st->cand_count--;
        sd_emit(st, t);
    }
    if (st->has_pend && (sd_floor(st) > st->pend_t + st->dedupe)) {
        sd_commit(st, st->pend_t);
        st->has_pend = false;
    }
    if ((st->cfg.method == SD_METHOD_WAVELET) && (st->n >= st->next_refine)) {
        if (st->cfg.refine && (st->n > st->warm_n)) {
            sd_refine(st);
        }
        st->next_refine += SD_REFINE_SAMPLES;
    }
    uint32_t due = (st->cfg.method == SD_METHOD_WAVELET) ? st->next_refine : SD_NONE;
    if (st->cand_count > 0u) {
        due = sd_min_u32(due, st->cand[st->cand_head] + st->after + 1u);
    }
    if (st->grp_open) {
        due = sd_min_u32(due, st->grp_last + st->merge + st->dmax);
    }
    if (st->has_pend) {
        due = sd_min_u32(due, st->pend_t + st->dedupe + st->before + st->dmax + 1u);
    }
    st->due = (due > st->n) ? due : (st->n + 1u);
}

static void sd_step_threshold(sd_stream_t *st, const int16_t *x, uint32_t k)
{
    for (uint32_t i = 0u; i < k; ++i) {
        const int32_t v = x[i];
        const uint32_t n = st->n;
        st->buf[n & SD_RING_MASK] = x[i];
        const bool above = (v <= st->thr_lo) || (v >= st->thr_hi);
        if (above && !st->above_prev) {
            sd_cand_push(st, n);
            st->due = sd_min_u32(st->due, n + st->after + 1u);
        }
        st->above_prev = above;
        st->n = n + 1u;
        if (st->n >= st->due) {
            sd_service(st);
        }
    }
}

/* One step (k <= SD_STEP_SAMPLES samples, never across a multiple of it):
 * coefficients of every scale into a hit mask, then the run logic only if
 * something fired or a run is open. */
static void sd_step_wavelet(sd_stream_t *st, const int16_t *x, uint32_t k)
{
    const uint32_t n0 = st->n;
    sd_block_sums(st, x, n0, k, true);
    const uint32_t i0 = sd_block_first(st, n0, k);
    const uint32_t hits = sd_block_scales(st, i0, k);
    sd_block_advance(st, k);
    st->n_coefs += k - i0;
    st->n = n0 + k;
    if ((hits != 0u) || st->in_run) {
        sd_step_runs(st, n0, i0, k, hits);
    }
    if (st->n >= st->due) {
        sd_service(st);
    }
}

static void sd_step(sd_stream_t *st, const int16_t *x, uint32_t k)
{
    if (st->cfg.method == SD_METHOD_THRESHOLD) {
        sd_step_threshold(st, x, k);
    } else {
        sd_step_wavelet(st, x, k);
    }
}

/* Samples to the next multiple of SD_STEP_SAMPLES of the online index. */
static uint32_t sd_step_room(const sd_stream_t *st)
{
    return SD_STEP_SAMPLES - (st->n % SD_STEP_SAMPLES);
}

static void sd_replay_some(sd_stream_t *st)
{
    const uint32_t left = st->warm_n - st->replay_pos;
    const uint32_t k = sd_min_u32(left, sd_step_room(st));
    /* buf[replay_pos..] is read before the delay line (aliased on buf's
     * start) overwrites index n & mask <= n: nothing unread is clobbered. */
    sd_step(st, &st->buf[st->replay_pos], k);
    st->replay_pos += k;
    if ((st->replay_pos >= st->warm_n) && (st->phase == SD_PHASE_REPLAY)) {
        st->phase = SD_PHASE_RUN;
    }
}

static md_status_t sd_warm_take(sd_stream_t *st, const int16_t *x, size_t n, size_t *used)
{
    const uint32_t room = st->warm_target - st->warm_n;
    const uint32_t k = (n < (size_t)room) ? (uint32_t)n : room;
    int16_t *dst = &st->buf[st->warm_n];
    int32_t sum = 0; /* at most SD_WARMUP_MAX samples of 2^15: no overflow */
    int16_t lo = st->warm_min;
    int16_t hi = st->warm_max;
    for (uint32_t i = 0u; i < k; ++i) {
        const int16_t v = x[i];
        dst[i] = v;
        sum += v;
        lo = (v < lo) ? v : lo;
        hi = (v > hi) ? v : hi;
    }
    st->warm_sum += sum;
    st->warm_min = lo;
    st->warm_max = hi;
    st->warm_n += k;
    *used = k;
    if (st->warm_n >= st->warm_target) {
        st->status = sd_calibrate(st);
        st->phase = SD_PHASE_REPLAY;
    }
    return st->status;
}

/* Online samples after the replay: at most to the next step boundary. */
static md_status_t sd_run_some(sd_stream_t *st, const int16_t *x, size_t n, size_t *used)
{
    if ((uint64_t)st->n + n > SD_MAX_INTERVAL_SAMPLES) {
        return MD_E_CAPACITY;
    }
    const uint32_t k = sd_min_u32((n < SD_STEP_SAMPLES) ? (uint32_t)n : SD_STEP_SAMPLES, sd_step_room(st));
    sd_step(st, x, k);
    *used = k;
    return MD_OK;
}

md_status_t sd_stream_push(sd_stream_t *st, const int16_t *x, size_t n, size_t *used)
{
    if ((st == NULL) || (used == NULL) || ((x == NULL) && (n > 0u))) {
        return MD_E_ARG;
    }
    *used = 0u;
    if (st->phase == SD_PHASE_RUN) { /* the common case: warm-up replayed, status MD_OK */
        return sd_run_some(st, x, n, used);
    }
    if ((st->phase == SD_PHASE_IDLE) || (st->phase == SD_PHASE_DONE) || ((st->phase == SD_PHASE_ENDED) && (n > 0u))) {
        return MD_E_STATE;
    }
    if (st->status < 0) {
        *used = n; /* a flat warm-up: the interval is consumed, detection is off */
        return st->status;
    }
    if (st->phase == SD_PHASE_WARMUP) {
        return sd_warm_take(st, x, n, used);
    }
    if (st->replay_pos < st->warm_n) {
        sd_replay_some(st);
        return MD_OK;
    }
    return sd_run_some(st, x, n, used);
}

md_status_t sd_stream_end(sd_stream_t *st)
{
    if (st == NULL) {
        return MD_E_ARG;
    }
    if ((st->phase == SD_PHASE_IDLE) || (st->phase == SD_PHASE_ENDED) || (st->phase == SD_PHASE_DONE)) {
        return MD_E_STATE;
    }
    if ((st->phase == SD_PHASE_WARMUP) && (st->status == MD_OK)) {
        st->ev.flags |= SD_FLAG_SHORT;
        st->status = sd_calibrate(st);
    }
    st->phase = SD_PHASE_ENDED;
    return (st->status < 0) ? st->status : MD_OK;
}

md_status_t sd_stream_finish(sd_stream_t *st)
{
    if (st == NULL) {
        return MD_E_ARG;
    }
    if ((st->phase != SD_PHASE_ENDED) || sd_stream_busy(st)) {
        return MD_E_STATE;
    }
    st->phase = SD_PHASE_DONE;
    st->ev.n_samples = st->n;
    if (st->status < 0) {
        st->ev.n_samples = st->warm_n;
        return st->status;
    }
    if (st->cfg.method == SD_METHOD_WAVELET) {
        if (st->in_run) { /* the centre after the last valid one ends the run */
            sd_run_edge(st, sd_next_centre(st), false);
        }
        if (st->grp_open) {
            sd_cand_push(st, (st->grp_first + st->grp_last) / 2u);
            st->grp_open = false;
        }
        for (unsigned s = 0u; s < st->ns; ++s) {
            st->ev.scale_hits[s] = st->hits[s];
        }
    }
    for (uint32_t k = 0u; (k < SD_CAND_MAX) && (st->cand_count > 0u); ++k) {
        sd_emit(st, st->cand[st->cand_head]); /* look-ahead clamped to the last sample */
        st->cand_head = (st->cand_head + 1u) % SD_CAND_MAX;
        st->cand_count--;
    }
    if (st->has_pend) {
        sd_commit(st, st->pend_t);
        st->has_pend = false;
    }
    return MD_OK;
}
