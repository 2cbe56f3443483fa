/// @file spike_extract.c
/// Spike windows and noise snippets (see spike_extract.h).
#include "signal/spike_extract.h"

#include <math.h>
#include <string.h>

#include "common/md_rng.h"

#define SX_DRAWS_PER_SNIPPET 16u

void sx_config_default(sx_config_t *cfg, uint32_t sample_rate_hz)
{
    if (cfg == NULL) {
        return;
    }
    const double fs = (double)sample_rate_hz;
    cfg->d_w = (size_t)lround(1.15e-3 * fs);
    cfg->pre_peak = (size_t)lround(0.4e-3 * fs);
    cfg->realign = 0u;
    cfg->gain = 1.0;
    cfg->n_noise = 128u;
    cfg->guard = (uint32_t)cfg->d_w;
    cfg->seed = 1u;
}

static int sx_config_valid(const sx_config_t *c)
{
    return (c->d_w >= 4u) && (c->d_w <= MD_WAVE_LEN_MAX) && (c->pre_peak < c->d_w) && (c->realign <= 1000u) &&
           (c->gain > 0.0) && isfinite(c->gain) && (c->n_noise <= MD_MAX_NOISE_SNIPPETS) &&
           (c->guard <= 100000u);
}

static void sx_copy(const int16_t *x, size_t start, size_t d_w, int32_t offset, double gain, double *dst)
{
    for (size_t j = 0u; j < d_w; ++j) {
        dst[j] = gain * (double)((int32_t)x[start + j] - offset);
    }
}

md_status_t sx_extract_spikes(const int16_t *x, size_t n, const sd_events_t *ev, const sx_config_t *cfg,
                              sx_spikes_t *out)
{
    if ((x == NULL) || (ev == NULL) || (cfg == NULL) || (out == NULL) || !sx_config_valid(cfg) ||
        (ev->n > MD_MAX_SPIKES) || (n > SD_MAX_INTERVAL_SAMPLES)) {
        return MD_E_ARG;
    }
    out->n = 0u;
    out->d_w = cfg->d_w;
    out->n_edge_skipped = 0u;
    out->n_duplicate = 0u;
    out->n_overflow = ev->n_overflow;
    out->flags = (ev->n_overflow > 0u) ? SX_FLAG_OVERFLOW : 0u;
    for (size_t k = 0u; k < ev->n; ++k) {
        size_t t = ev->t[k];
        if (t >= n) {
            return MD_E_ARG;
        }
        if (cfg->realign > 0u) { /* thesis: align by the waveform minimum */
            const size_t lo = (t > cfg->realign) ? (t - cfg->realign) : 0u;
            const size_t hi = (t + cfg->realign < n) ? (t + cfg->realign) : (n - 1u);
            for (size_t i = lo; i <= hi; ++i) {
                t = (x[i] < x[t]) ? i : t;
            }
        }
        if ((t < cfg->pre_peak) || (t - cfg->pre_peak + cfg->d_w > n)) {
            out->n_edge_skipped++;
            continue;
        }
        if ((out->n > 0u) && (out->t[out->n - 1u] == (uint32_t)t)) {
            out->n_duplicate++;
            continue;
        }
        sx_copy(x, t - cfg->pre_peak, cfg->d_w, ev->offset, cfg->gain, out->wave[out->n]);
        out->t[out->n] = (uint32_t)t;
        out->n++;
    }
    return MD_OK;
}

/* True if [start, start + len) comes within `guard` of any event (ascending
 * times): binary search for the first event >= start - guard. */
static int sx_touches_event(const sd_events_t *ev, size_t start, size_t len, size_t guard)
{
    const size_t lo_t = (start > guard) ? (start - guard) : 0u;
    size_t lo = 0u;
    size_t hi = ev->n;
    for (unsigned it = 0u; (it < 64u) && (lo < hi); ++it) {
        const size_t mid = lo + (hi - lo) / 2u;
        if ((size_t)ev->t[mid] < lo_t) {
            lo = mid + 1u;
        } else {
            hi = mid;
        }
    }
    return (lo < ev->n) && ((size_t)ev->t[lo] < start + len + guard);
}

md_status_t sx_extract_noise(const int16_t *x, size_t n, const sd_events_t *ev, const sx_config_t *cfg,
                             sx_noise_t *out)
{
    if ((x == NULL) || (ev == NULL) || (cfg == NULL) || (out == NULL) || !sx_config_valid(cfg) ||
        (ev->n > MD_MAX_SPIKES) || (n > SD_MAX_INTERVAL_SAMPLES)) {
        return MD_E_ARG;
    }
    out->n = 0u;
    out->d_w = cfg->d_w;
    out->n_rejected = 0u;
    out->flags = 0u;
    /* Events past the last stored one are unknown after an overflow. */
    size_t limit = n;
    if ((ev->n_overflow > 0u) && (ev->n > 0u)) {
        limit = (size_t)ev->t[ev->n - 1u];
        out->flags |= SX_FLAG_OVERFLOW;
    }
    md_rng_t rng;
    md_rng_seed(&rng, cfg->seed);
    const size_t draws = SX_DRAWS_PER_SNIPPET * cfg->n_noise;
    for (size_t d = 0u; (d < draws) && (out->n < cfg->n_noise) && (limit >= cfg->d_w); ++d) {
        const size_t start = md_rng_below(&rng, (uint32_t)(limit - cfg->d_w + 1u));
        if (sx_touches_event(ev, start, cfg->d_w, cfg->guard)) {
            out->n_rejected++;
            continue;
        }
        sx_copy(x, start, cfg->d_w, ev->offset, cfg->gain, out->wave[out->n]);
        out->start[out->n] = (uint32_t)start;
        out->n++;
    }
    if (out->n < cfg->n_noise) {
        out->flags |= SX_FLAG_NOISE_SHORT;
        if (out->n == 0u) {
            return MD_E_DEGENERATE;
        }
    }
    return MD_OK;
}
