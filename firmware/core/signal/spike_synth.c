/// @file spike_synth.c
/// Synthetic spike trains in noise (see spike_synth.h).
#include "signal/spike_synth.h"

#include <math.h>

#include "numeric/md_rng.h"

#define SYNTH_PRE_MS 0.5
#define SYNTH_POST_MS 1.2

size_t synth_template(uint32_t sample_rate_hz, double *tmpl, size_t cap, size_t *trough)
{
    if ((tmpl == NULL) || (trough == NULL) || (sample_rate_hz < 5000u) || (sample_rate_hz > 50000u)) {
        return 0u;
    }
    const double dt_ms = 1000.0 / (double)sample_rate_hz;
    const size_t pre = (size_t)lround(SYNTH_PRE_MS / dt_ms);
    const size_t len = pre + (size_t)lround(SYNTH_POST_MS / dt_ms) + 1u;
    if (len > cap) {
        return 0u;
    }
    double lo = 0.0;
    double hi = 0.0;
    for (size_t i = 0u; i < len; ++i) {
        const double t = ((double)i - (double)pre) * dt_ms;
        const double a = t / 0.12;
        const double b = (t - 0.35) / 0.22;
        tmpl[i] = -exp(-0.5 * a * a) + 0.35 * exp(-0.5 * b * b);
        lo = fmin(lo, tmpl[i]);
        hi = fmax(hi, tmpl[i]);
    }
    for (size_t i = 0u; i < len; ++i) {
        tmpl[i] /= (hi - lo);
    }
    *trough = pre;
    return len;
}

static void synth_noise(const synth_config_t *cfg, double *out, size_t n, md_rng_t *rng)
{
    double w1 = md_rng_gauss(rng);
    double w2 = md_rng_gauss(rng);
    for (size_t i = 0u; i < n; ++i) {
        const double w0 = md_rng_gauss(rng);
        /* [1 2 1]/sqrt(6) keeps unit variance for white input */
        out[i] = cfg->band_limited ? (w0 + 2.0 * w1 + w2) / sqrt(6.0) : w0;
        w2 = w1;
        w1 = w0;
    }
}

md_status_t synth_trace(const synth_config_t *cfg, int16_t *out, size_t n, uint32_t *peaks, size_t peaks_cap,
                        size_t *n_peaks)
{
    double tmpl[SYNTH_TEMPLATE_MAX];
    size_t trough = 0u;
    if ((cfg == NULL) || (out == NULL) || (n_peaks == NULL) || ((peaks == NULL) && (peaks_cap > 0u)) ||
        !(cfg->noise_rms > 0.0) || !(cfg->snr >= 0.0) || !(cfg->rate_hz >= 0.0) || !(cfg->refractory_ms >= 0.0)) {
        return MD_E_ARG;
    }
    const size_t len = synth_template(cfg->sample_rate_hz, tmpl, SYNTH_TEMPLATE_MAX, &trough);
    if (len == 0u) {
        return MD_E_ARG;
    }
    md_rng_t rng;
    md_rng_seed(&rng, cfg->seed);
    const double amp = cfg->snr * cfg->noise_rms;
    const double fs = (double)cfg->sample_rate_hz;
    const double refr = cfg->refractory_ms * 1e-3 * fs;
    const double mean_gap = (cfg->rate_hz > 0.0) ? (fs / cfg->rate_hz) : 0.0;
    double t_next = (double)len + refr + fmax(mean_gap - refr, 0.0) * -log(1.0 - md_rng_uniform(&rng));
    *n_peaks = 0u;
    double noise[64];
    for (size_t base = 0u; base < n; base += 64u) {
        const size_t m = (n - base < 64u) ? (n - base) : 64u;
        synth_noise(cfg, noise, m, &rng);
        for (size_t i = 0u; i < m; ++i) {
            const double v = fmax(-32768.0, fmin(32767.0, round(noise[i] * cfg->noise_rms)));
            out[base + i] = (int16_t)v;
        }
    }
    /* Spikes: exponential gaps above the refractory period (Poisson-like). */
    for (size_t k = 0u; (cfg->rate_hz > 0.0) && (k < peaks_cap) && (t_next + (double)len < (double)n); ++k) {
        const size_t start = (size_t)t_next;
        for (size_t i = 0u; i < len; ++i) {
            const double v = fmax(-32768.0, fmin(32767.0, (double)out[start + i] + round(amp * tmpl[i])));
            out[start + i] = (int16_t)v;
        }
        peaks[k] = (uint32_t)(start + trough);
        *n_peaks = k + 1u;
        const double gap = refr + fmax(mean_gap - refr, 0.0) * -log(1.0 - md_rng_uniform(&rng));
        t_next += fmax(gap, 1.0);
    }
    return MD_OK;
}

void synth_match(const uint32_t *truth, size_t n_truth, const uint32_t *det, size_t n_det, uint32_t tol, size_t *hits,
                 size_t *false_pos)
{
    size_t h = 0u;
    size_t fp = 0u;
    size_t j = 0u;
    for (size_t i = 0u; (det != NULL) && (i < n_det); ++i) {
        /* skip true spikes that are too early for this or any later detection */
        while ((truth != NULL) && (j < n_truth) && (truth[j] + tol < det[i])) {
            ++j;
        }
        if ((truth != NULL) && (j < n_truth) && (truth[j] <= det[i] + tol)) {
            ++h;
            ++j;
        } else {
            ++fp;
        }
    }
    if (hits != NULL) {
        *hits = h;
    }
    if (false_pos != NULL) {
        *false_pos = fp;
    }
}
