/// @file spike_detect.c
/// Streaming spike detection (see spike_detect.h and docs/detector.md).
#include "signal/spike_detect.h"

#include <math.h>
#include <string.h>

#define SD_STATE_IDLE 0
#define SD_STATE_STREAMING 1
#define SD_STATE_DONE 2

#define SD_MAD_TO_SIGMA 0.6745  /* median(|N(0,1)|): robust sigma = MAD / 0.6745 */
#define SD_TRUNC_SIGMAS 4.0     /* wavelet support kept: +-4 envelope widths (envelope < 4e-4) */
/* Nenadic & Burdick's reference code scales the user's L in [-0.2, 0.2] by
 * ln of the largest cost ratio double precision can express (about 36.74), so
 * L = +-0.2 moves ln(cost ratio) by about +-7.3. */
#define SD_L_SCALE 36.7368

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
    cfg->wavelet = SD_WAVELET_MEXHAT;
    cfg->width_min_ms = 0.5;
    cfg->width_max_ms = 1.0;
    cfg->n_scales = 4u;
    cfg->cost_ratio_l = 0.05;
}

static int sd_in(double v, double lo, double hi)
{
    return (v >= lo) && (v <= hi); /* false for NaN */
}

static int sd_config_valid(const sd_config_t *c)
{
    const int common = (c->sample_rate_hz >= 1000u) && (c->sample_rate_hz <= 200000u) &&
                       sd_in(c->align_ms, 0.01, 5.0);
    switch (c->method) {
    case SD_METHOD_THRESHOLD:
        return common && sd_in(c->k_sigma, 1.0, 20.0) && sd_in(c->dead_time_ms, 0.0, 10.0) &&
               ((c->polarity == SD_POLARITY_NEG) || (c->polarity == SD_POLARITY_BOTH));
    case SD_METHOD_WAVELET:
        return common && ((c->wavelet == SD_WAVELET_MEXHAT) || (c->wavelet == SD_WAVELET_DOG1)) &&
               sd_in(c->width_min_ms, 0.05, 5.0) && sd_in(c->width_max_ms, c->width_min_ms, 5.0) &&
               (c->n_scales >= 1u) && (c->n_scales <= MD_WAVELET_SCALES_MAX) &&
               sd_in(c->cost_ratio_l, -0.2, 0.2);
    default:
        return 0;
    }
}

static double sd_scale_width_ms(const sd_config_t *c, unsigned s)
{
    if (c->n_scales < 2u) {
        return 0.5 * (c->width_min_ms + c->width_max_ms);
    }
    return c->width_min_ms + (c->width_max_ms - c->width_min_ms) * (double)s / (double)(c->n_scales - 1u);
}

/* Scale s of the bank: a spike of total width W has its main (negative) phase
 * over about W/2, which is the central lobe (2 s_env) of the Mexican hat, so
 * s_env = W/4. The filter is made exactly zero-mean (a DC offset gives no
 * response) and unit-L2 (its coefficient sigma equals the white-noise sigma). */
static md_status_t sd_build_filter(sd_detector_t *det, unsigned s)
{
    const double env = sd_scale_width_ms(&det->cfg, s) * 1e-3 * (double)det->cfg.sample_rate_hz / 4.0;
    const double half_d = ceil(SD_TRUNC_SIGMAS * env);
    if (!(env >= 0.5) || (2.0 * half_d + 1.0 > (double)SD_TAPS_MAX)) {
        return MD_E_ARG;
    }
    const size_t half = (size_t)half_d;
    const size_t taps = 2u * half + 1u;
    double *h = det->taps[s];
    double mean = 0.0;
    for (size_t j = 0u; j < taps; ++j) {
        const double u = ((double)j - (double)half) / env;
        const double g = exp(-0.5 * u * u);
        h[j] = (det->cfg.wavelet == SD_WAVELET_MEXHAT) ? (1.0 - u * u) * g : -u * g;
        mean += h[j];
    }
    mean /= (double)taps;
    double norm2 = 0.0;
    for (size_t j = 0u; j < taps; ++j) {
        h[j] -= mean;
        norm2 += h[j] * h[j];
    }
    const double inv = 1.0 / sqrt(norm2);
    for (size_t j = 0u; j < taps; ++j) {
        h[j] *= inv;
    }
    det->half[s] = half;
    if (half > det->half_max) {
        det->half_max = half;
    }
    return MD_OK;
}

static uint32_t sd_ms_to_samples(double ms, uint32_t rate_hz)
{
    return (uint32_t)lround(ms * 1e-3 * (double)rate_hz);
}

md_status_t sd_init(sd_detector_t *det, const sd_config_t *cfg, int16_t *buf, size_t cap)
{
    if ((det == NULL) || (cfg == NULL) || (buf == NULL) || (cap == 0u) || (cap > SD_MAX_INTERVAL_SAMPLES) ||
        !sd_config_valid(cfg)) {
        return MD_E_ARG;
    }
    memset(det, 0, sizeof *det);
    det->cfg = *cfg;
    det->buf = buf;
    det->cap = cap;
    det->dead_samples = sd_ms_to_samples(cfg->dead_time_ms, cfg->sample_rate_hz);
    det->align_samples = sd_ms_to_samples(cfg->align_ms, cfg->sample_rate_hz);
    if (det->align_samples == 0u) {
        det->align_samples = 1u;
    }
    if (cfg->method == SD_METHOD_WAVELET) {
        /* events closer than the mean expected width are one spike */
        det->merge_samples =
            sd_ms_to_samples(0.5 * (cfg->width_min_ms + cfg->width_max_ms), cfg->sample_rate_hz);
        for (unsigned s = 0u; s < cfg->n_scales; ++s) {
            const md_status_t st = sd_build_filter(det, s);
            if (st < 0) {
                return st;
            }
        }
    }
    det->state = SD_STATE_STREAMING;
    return MD_OK;
}

md_status_t sd_restart(sd_detector_t *det)
{
    if ((det == NULL) || (det->state == SD_STATE_IDLE)) {
        return MD_E_STATE;
    }
    det->n = 0u;
    det->sum = 0;
    det->n_chunks = 0u;
    det->n_dropped = 0u;
    det->state = SD_STATE_STREAMING;
    return MD_OK;
}

md_status_t sd_push(sd_detector_t *det, const int16_t *samples, size_t n)
{
    if ((det == NULL) || ((samples == NULL) && (n > 0u))) {
        return MD_E_ARG;
    }
    if (det->state != SD_STATE_STREAMING) {
        return MD_E_STATE;
    }
    const size_t room = det->cap - det->n;
    const size_t take = (n < room) ? n : room;
    for (size_t i = 0u; i < take; ++i) {
        det->buf[det->n + i] = samples[i];
        det->sum += samples[i];
    }
    det->n += take;
    det->n_chunks++;
    if (take < n) {
        const size_t lost = n - take;
        det->n_dropped += (lost > 0xFFFFFFFFu - det->n_dropped) ? (0xFFFFFFFFu - det->n_dropped) : (uint32_t)lost;
        return MD_E_CAPACITY;
    }
    return MD_OK;
}

const int16_t *sd_samples(const sd_detector_t *det, size_t *n)
{
    if (det == NULL) {
        return NULL;
    }
    if (n != NULL) {
        *n = det->n;
    }
    return det->buf;
}

/* Moves a candidate to the minimum of x in [t - before, t + after] (the
 * thesis aligns spikes by their minimum), then either merges it into the last
 * stored event (closer than `dedupe`; the deeper minimum wins) or appends it. */
static void sd_emit(const sd_detector_t *det, sd_events_t *ev, size_t t, size_t before, size_t after,
                    size_t dedupe)
{
    const size_t lo = (t > before) ? (t - before) : 0u;
    const size_t hi = (t + after < det->n) ? (t + after) : (det->n - 1u);
    size_t best = lo;
    for (size_t i = lo + 1u; i <= hi; ++i) {
        if (det->buf[i] < det->buf[best]) {
            best = i;
        }
    }
    const size_t last = (ev->n > 0u) ? (size_t)ev->t[ev->n - 1u] : 0u;
    if ((ev->n > 0u) && (best <= last + dedupe)) {
        ev->n_merged++;
        if ((best > last) && (det->buf[best] < det->buf[last])) {
            ev->t[ev->n - 1u] = (uint32_t)best;
        }
        return;
    }
    if (ev->n >= MD_MAX_SPIKES) {
        ev->n_overflow++;
        ev->flags |= SD_FLAG_OVERFLOW;
        return;
    }
    ev->t[ev->n] = (uint32_t)best;
    ev->n++;
}

static md_status_t sd_detect_threshold(sd_detector_t *det, sd_events_t *ev)
{
    ev->threshold = det->cfg.k_sigma * ev->noise_sigma;
    const double thr = ev->threshold;
    const int both = (det->cfg.polarity == SD_POLARITY_BOTH);
    const size_t before = both ? det->align_samples : 0u;
    int above_prev = 0;
    for (size_t i = 0u; i < det->n; ++i) {
        const double v = (double)((int32_t)det->buf[i] - ev->offset);
        const int above = (-v > thr) || (both && (v > thr));
        if (above && !above_prev) {
            sd_emit(det, ev, i, before, det->align_samples, det->dead_samples);
        }
        above_prev = above;
    }
    return MD_OK;
}

/* Wavelet coefficient of scale s centred on sample n (needs half_max <= n < N - half_max). */
static double sd_coef(const sd_detector_t *det, unsigned s, size_t n, int32_t offset)
{
    const size_t half = det->half[s];
    const int16_t *x = &det->buf[n - half];
    const double *h = det->taps[s];
    double c = 0.0;
    for (size_t j = 0u; j <= 2u * half; ++j) {
        c += h[j] * (double)((int32_t)x[j] - offset);
    }
    return c;
}

/* Per-scale statistics of Nenadic & Burdick: sigma = median(|c - mean c|)/0.6745,
 * hard threshold sigma*sqrt(2 ln N), M = mean |c| above it, prior P(spike) =
 * their fraction, decision threshold M/2 + sigma^2/M (L + ln(P(noise)/P(spike))).
 * Returns 0 if the scale carries no noise (flat signal) and must be skipped. */
static int sd_scale_threshold(sd_detector_t *det, unsigned s, sd_events_t *ev)
{
    const size_t lo = det->half_max;
    const size_t hi = det->n - det->half_max;
    const double n_eff = (double)(hi - lo);
    double sum = 0.0, cmin = 0.0, cmax = 0.0;
    for (size_t n = lo; n < hi; ++n) { /* pass 1: mean and range */
        const double c = sd_coef(det, s, n, ev->offset);
        sum += c;
        cmin = (n == lo) ? c : fmin(cmin, c);
        cmax = (n == lo) ? c : fmax(cmax, c);
    }
    const double mean = sum / n_eff;
    const double range = fmax(cmax - mean, mean - cmin);
    if (!(range > 0.0)) {
        return 0;
    }
    const double width = range * (1.0 + 1e-9) / (double)SD_HIST_BINS;
    memset(det->hist, 0, sizeof det->hist);
    for (size_t n = lo; n < hi; ++n) { /* pass 2: histogram of |c - mean| */
        const double b = fabs(sd_coef(det, s, n, ev->offset) - mean) / width;
        det->hist[(b < (double)(SD_HIST_BINS - 1u)) ? (size_t)b : (SD_HIST_BINS - 1u)]++;
    }
    const uint64_t total = (uint64_t)(hi - lo);
    const double med = 0.5 * (rs_hist_rank_value(det->hist, SD_HIST_BINS, width, total, (total - 1u) / 2u) +
                              rs_hist_rank_value(det->hist, SD_HIST_BINS, width, total, total / 2u));
    const double sigma = med / SD_MAD_TO_SIGMA;
    if (!(sigma > 0.0)) {
        return 0;
    }
    const double th = sigma * sqrt(2.0 * log(n_eff));
    double sum_sig = 0.0;
    uint32_t hits = 0u;
    for (size_t n = lo; n < hi; ++n) { /* pass 3: supra-threshold mean */
        const double a = fabs(sd_coef(det, s, n, ev->offset));
        if (a > th) {
            sum_sig += a;
            hits++;
        }
    }
    const double m = (hits > 0u) ? (sum_sig / (double)hits) : th;
    const double p_spike = (hits > 0u) ? ((double)hits / n_eff) : (1.0 / n_eff);
    ev->scale_sigma[s] = sigma;
    ev->scale_hits[s] = hits;
    const double dth = 0.5 * m + sigma * sigma / m * (SD_L_SCALE * det->cfg.cost_ratio_l + log((1.0 - p_spike) / p_spike));
    ev->scale_dth[s] = fmax(dth, 0.0);
    return 1;
}

/* Pass 4: a sample is spike-like if any active scale exceeds its decision
 * threshold; each run of such samples gives a candidate at its centre, and
 * candidates closer than the mean width are merged before alignment. */
static md_status_t sd_detect_wavelet(sd_detector_t *det, sd_events_t *ev)
{
    if (det->n < 4u * det->half_max + 8u) {
        return MD_E_DEGENERATE;
    }
    int active[MD_WAVELET_SCALES_MAX] = {0};
    int any_active = 0;
    ev->n_scales = det->cfg.n_scales;
    for (unsigned s = 0u; s < det->cfg.n_scales; ++s) {
        ev->scale_width_ms[s] = sd_scale_width_ms(&det->cfg, s);
        active[s] = sd_scale_threshold(det, s, ev);
        any_active |= active[s];
    }
    if (!any_active) {
        return MD_E_DEGENERATE;
    }
    const size_t lo = det->half_max;
    const size_t hi = det->n - det->half_max;
    const size_t merge = det->merge_samples;
    size_t run_start = 0u, pend_first = 0u, pend_last = 0u;
    int in_run = 0, pending = 0;
    for (size_t n = lo; n <= hi; ++n) {
        int hit = 0;
        for (unsigned s = 0u; (s < det->cfg.n_scales) && !hit && (n < hi); ++s) {
            hit = active[s] && (fabs(sd_coef(det, s, n, ev->offset)) > ev->scale_dth[s]);
        }
        if (hit && !in_run) {
            run_start = n;
        } else if (!hit && in_run) {
            const size_t mid = (run_start + n - 1u) / 2u;
            if (pending && (mid - pend_last < merge)) {
                pend_last = mid;
            } else {
                if (pending) {
                    sd_emit(det, ev, (pend_first + pend_last) / 2u, det->align_samples, det->align_samples, merge);
                }
                pend_first = mid;
                pend_last = mid;
                pending = 1;
            }
        } else {
            /* inside or outside a run: nothing changes */
        }
        in_run = hit;
    }
    if (pending) {
        sd_emit(det, ev, (pend_first + pend_last) / 2u, det->align_samples, det->align_samples, merge);
    }
    return MD_OK;
}

md_status_t sd_finish(sd_detector_t *det, sd_events_t *ev)
{
    if ((det == NULL) || (ev == NULL)) {
        return MD_E_ARG;
    }
    if (det->state != SD_STATE_STREAMING) {
        return MD_E_STATE;
    }
    det->state = SD_STATE_DONE;
    memset(ev, 0, sizeof *ev);
    ev->n_samples = (uint32_t)det->n;
    ev->flags = (det->n_dropped > 0u) ? SD_FLAG_TRUNCATED : 0u;
    if (det->n < 16u) {
        return MD_E_DEGENERATE;
    }
    ev->offset = (int32_t)lround((double)det->sum / (double)det->n);
    ev->noise_sigma = rs_abs_median_i16(det->buf, det->n, ev->offset, &det->rs) / SD_MAD_TO_SIGMA;
    if (det->cfg.method == SD_METHOD_WAVELET) {
        return sd_detect_wavelet(det, ev);
    }
    if (!(ev->noise_sigma > 0.0)) {
        return MD_E_DEGENERATE;
    }
    return sd_detect_threshold(det, ev);
}
