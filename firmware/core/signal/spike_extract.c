/// @file spike_extract.c
/// Spike windows and noise snippets, streaming and offline (see spike_extract.h).
#include "signal/spike_extract.h"

#include <math.h>
#include <string.h>

#include "signal/spike_align.h"

#define SX_RES_SEED_MIX 0x9E3779B97F4A7C15ull /* decorrelates the reservoir stream from the gap stream */

typedef enum { SX_CUT_OK = 0, SX_CUT_EDGE = 1, SX_CUT_LOST = 2 } sx_cut_t;
typedef enum { SX_NOISE_ACCEPT = 0, SX_NOISE_REJECT = 1, SX_NOISE_EXPIRED = 2 } sx_noise_verdict_t;

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
    cfg->spacing = (uint32_t)lround(10.0 * fs / (4.0 * 128.0));
    cfg->subsample = true;
    cfg->margin = 0u;
}

static int sx_config_valid(const sx_config_t *c)
{
    return (c->d_w >= 4u) && (c->d_w <= MD_WAVE_LEN_MAX) && (c->pre_peak < c->d_w) && (c->realign <= 1000u) &&
           (!c->subsample || (c->pre_peak >= 1u)) && (c->gain > 0.0) && isfinite(c->gain) &&
           (c->n_noise <= MD_MAX_NOISE_SNIPPETS) && (c->guard <= 100000u) && (c->spacing <= SD_MAX_INTERVAL_SAMPLES) &&
           (c->margin <= SX_MARGIN_MAX) && ((c->margin == 0u) || !c->subsample) &&
           (c->d_w + 2u * (size_t)c->margin <= MD_WAVE_LEN_MAX);
}

/* ---- window cutter (shared) --------------------------------------------- */

/* Copies d_w samples of the view from `start` into row, offset removed and
 * saturated to int16; returns the number of saturated samples. */
static uint32_t sx_copy16(const sd_view_t *v, uint32_t start, size_t d_w, int32_t offset, int16_t *row)
{
    const uint32_t mask = v->mask;
    const uint32_t first = start & mask;
    uint32_t clipped = 0u;
    if ((uint64_t)first + d_w - 1u <= (uint64_t)mask) { /* the window does not wrap the ring: no masking */
        const int16_t *x = &v->x[first];
        for (size_t j = 0u; j < d_w; ++j) {
            const int32_t d = (int32_t)x[j] - offset;
            clipped += (((uint32_t)d + 32768u) > 0xFFFFu) ? 1u : 0u; /* d outside the int16 range */
            row[j] = (int16_t)((d < INT16_MIN) ? INT16_MIN : ((d > INT16_MAX) ? INT16_MAX : d));
        }
        return clipped;
    }
    for (size_t j = 0u; j < d_w; ++j) {
        const int32_t d = (int32_t)v->x[(start + (uint32_t)j) & mask] - offset;
        clipped += (((uint32_t)d + 32768u) > 0xFFFFu) ? 1u : 0u;
        row[j] = (int16_t)((d < INT16_MIN) ? INT16_MIN : ((d > INT16_MAX) ? INT16_MAX : d));
    }
    return clipped;
}

_Static_assert(SX_INTERP_MARGIN == SA_MARGIN, "the resampling reads the alignment's margin");

/* The window resampled on the sub-sample minimum (spike_align.h: the parabola's vertex,
 * Keys' cubic convolution), offset removed, into row16 (rounded, saturated) or rowd
 * (times gain); returns the saturated samples. */
static uint32_t sx_resample(const sd_view_t *v, uint32_t start, const sx_config_t *c, int32_t offset, int16_t *row16,
                            double *rowd)
{
    int16_t raw[MD_WAVE_LEN_MAX + 2u * SA_MARGIN];
    double y[MD_WAVE_LEN_MAX];
    /* raw samples, offset removed: saturation here is counted on the output */
    (void)sx_copy16(v, start - SA_MARGIN, c->d_w + 2u * (size_t)SA_MARGIN, offset, raw);
    sa_resample(raw, c->d_w, sa_trough_offset(raw, SA_MARGIN + c->pre_peak), y);
    if (rowd == NULL) {
        return sa_round_i16(y, c->d_w, row16);
    }
    for (size_t j = 0u; j < c->d_w; ++j) {
        rowd[j] = c->gain * (nearbyint(y[j]) + 0.0); /* whole counts as the int16 path; + 0.0: no negative zero */
    }
    return 0u;
}

/* Realigns t to the first minimum within +-realign (thesis: align by the
 * waveform minimum) and copies the window, offset removed, into row16
 * (saturated, *clipped counts saturations) or rowd (times gain); with
 * c->subsample the window is resampled on the sub-sample minimum, with
 * c->margin it is copied raw with that many samples more on each side. */
static sx_cut_t sx_cut(const sd_view_t *v, uint32_t t, const sx_config_t *c, int32_t offset, int16_t *row16,
                       double *rowd, uint32_t *t_out, uint32_t *clipped)
{
    if (c->realign > 0u) {
        t = sd_view_argmin(v, (t > c->realign) ? (t - c->realign) : 0u, t + c->realign);
    }
    *t_out = t;
    const uint32_t m = c->subsample ? SX_INTERP_MARGIN : c->margin;
    if ((t < c->pre_peak + m) || ((uint64_t)t - c->pre_peak + c->d_w + m > (uint64_t)v->hi)) {
        return SX_CUT_EDGE;
    }
    const uint32_t start = t - (uint32_t)c->pre_peak;
    if (start - m < v->lo) {
        return SX_CUT_LOST;
    }
    if (c->subsample) {
        *clipped += sx_resample(v, start, c, offset, row16, rowd);
        return SX_CUT_OK;
    }
    if (rowd != NULL) {
        for (size_t j = 0u; j < c->d_w; ++j) {
            const int32_t d = (int32_t)v->x[(start + (uint32_t)j) & v->mask] - offset;
            rowd[j] = c->gain * (double)d;
        }
    } else {
        *clipped += sx_copy16(v, start - m, c->d_w + 2u * (size_t)m, offset, row16); /* raw, with the margin */
    }
    return SX_CUT_OK;
}

/* ---- snippet picker (shared) -------------------------------------------- */

static void sx_pick_init(sx_picker_t *p, const sx_config_t *c)
{
    md_rng_seed(&p->pos_rng, c->seed);
    md_rng_seed(&p->res_rng, c->seed ^ SX_RES_SEED_MIX);
    p->min_gap = (c->d_w > SX_MIN_SPACING) ? (uint32_t)c->d_w : SX_MIN_SPACING;
    p->span = (c->spacing > p->min_gap) ? 2u * (c->spacing - p->min_gap) : 0u;
    p->next = md_rng_below(&p->pos_rng, (c->spacing > 0u) ? c->spacing : 1u);
    p->cursor = 0u;
}

/* Next candidate start; gaps are min_gap + U[0, span] (mean `spacing`), so
 * candidates never overlap and at most SX_QUEUE_MAX fit in the delay line. */
static uint32_t sx_pick_advance(sx_picker_t *p)
{
    const uint32_t s = p->next;
    p->next = s + p->min_gap + md_rng_below(&p->pos_rng, p->span + 1u);
    return s;
}

/* Verdict for candidate s against the committed events (ascending; the
 * candidates are ascending too, so one cursor scans them once). */
static sx_noise_verdict_t sx_pick_check(sx_picker_t *p, const sd_events_t *ev, const sd_view_t *v, uint32_t s,
                                        const sx_config_t *c)
{
    if (s < v->lo) {
        return SX_NOISE_EXPIRED;
    }
    const uint64_t zone_end = (uint64_t)s + c->d_w + c->guard;
    if ((ev->n_overflow > 0u) && (ev->n > 0u) && ((uint64_t)s + c->d_w > (uint64_t)ev->t[ev->n - 1u])) {
        return SX_NOISE_REJECT; /* events after the last stored one are unknown */
    }
    for (; (p->cursor < ev->n) && ((uint64_t)ev->t[p->cursor] + c->guard < (uint64_t)s); ++p->cursor) {
    }
    return ((p->cursor < ev->n) && ((uint64_t)ev->t[p->cursor] < zone_end)) ? SX_NOISE_REJECT : SX_NOISE_ACCEPT;
}

/* Reservoir sampling: the i-th confirmed candidate (0-based) takes slot i
 * while there is room, else replaces a uniform slot with probability cap/(i+1). */
static bool sx_pick_slot(sx_picker_t *p, uint32_t i, size_t cap, size_t *slot)
{
    if (i < cap) {
        *slot = i;
        return true;
    }
    const uint32_t j = md_rng_below(&p->res_rng, i + 1u);
    *slot = j;
    return j < cap;
}

/* ---- streaming ------------------------------------------------------------ */

md_status_t sx_stream_restart(sx_stream_t *sx)
{
    if ((sx == NULL) || (sx->win == NULL) || (sx->noise == NULL)) {
        return MD_E_STATE;
    }
    sx_pick_init(&sx->pick, &sx->cfg);
    sx->q_head = 0u;
    sx->q_count = 0u;
    sx->ev_cursor = 0u;
    sx->win->n = 0u;
    sx->win->d_w = sx->cfg.d_w;
    sx->win->margin = sx->cfg.margin;
    sx->win->pre_peak = sx->cfg.pre_peak;
    sx->win->n_align_clamped = 0u;
    sx->win->gain = sx->cfg.gain;
    sx->win->offset = 0;
    sx->win->n_edge_skipped = 0u;
    sx->win->n_duplicate = 0u;
    sx->win->n_overflow = 0u;
    sx->win->n_lost = 0u;
    sx->win->n_clipped = 0u;
    sx->win->flags = 0u;
    sx->noise->n = 0u;
    sx->noise->d_w = sx->cfg.d_w;
    sx->noise->gain = sx->cfg.gain;
    sx->noise->offset = 0;
    sx->noise->n_candidates = 0u;
    sx->noise->n_confirmed = 0u;
    sx->noise->n_rejected = 0u;
    sx->noise->n_expired = 0u;
    sx->noise->n_queue_full = 0u;
    sx->noise->flags = 0u;
    return MD_OK;
}

md_status_t sx_stream_init(sx_stream_t *sx, const sx_config_t *cfg, const sd_stream_t *det, sx_windows_t *win,
                           sx_snippets_t *noise)
{
    if ((sx == NULL) || (cfg == NULL) || (det == NULL) || (win == NULL) || (noise == NULL) || !sx_config_valid(cfg)) {
        return MD_E_ARG;
    }
    /* a window (with realignment) or a candidate's guard zone must still be in
     * the delay line when the detector lets it go */
    const uint64_t need = (uint64_t)sd_stream_latency(det) + cfg->pre_peak + cfg->d_w + (2u * (uint64_t)cfg->realign) +
                          (2u * ((uint64_t)SX_INTERP_MARGIN + cfg->margin)) + cfg->guard + SX_SERVICE_MAX +
                          SD_STEP_SAMPLES;
    if (need > SD_RING_SAMPLES) {
        return MD_E_ARG;
    }
    sx->cfg = *cfg;
    sx->win = win;
    sx->noise = noise;
    return sx_stream_restart(sx);
}

static void sx_service_spikes(sx_stream_t *sx, const sd_events_t *ev, const sd_view_t *v, bool final)
{
    sx_windows_t *w = sx->win;
    const sx_config_t *c = &sx->cfg;
    for (size_t k = 0u; (k < MD_MAX_SPIKES) && (sx->ev_cursor < ev->n); ++k) {
        const uint32_t t = ev->t[sx->ev_cursor];
        const uint64_t need = (uint64_t)t + c->realign + c->d_w +
                              (c->subsample ? SX_INTERP_MARGIN : c->margin); /* >= last sample read + 1 */
        if (!final && (need > (uint64_t)v->hi + c->pre_peak)) {
            break; /* its samples have not all arrived */
        }
        sx->ev_cursor++;
        if (w->n >= MD_MAX_SPIKES) {
            w->n_overflow++;
            continue;
        }
        uint32_t tt = t;
        const sx_cut_t r = sx_cut(v, t, c, ev->offset, w->wave[w->n], NULL, &tt, &w->n_clipped);
        if (r == SX_CUT_EDGE) {
            w->n_edge_skipped++;
        } else if (r == SX_CUT_LOST) {
            w->n_lost++;
        } else if ((w->n > 0u) && (w->t[w->n - 1u] == tt)) {
            w->n_duplicate++;
        } else {
            w->t[w->n] = tt;
            w->n++;
        }
    }
}

static void sx_noise_take(sx_stream_t *sx, const sd_events_t *ev, const sd_view_t *v, uint32_t s)
{
    sx_snippets_t *z = sx->noise;
    const sx_noise_verdict_t verdict = sx_pick_check(&sx->pick, ev, v, s, &sx->cfg);
    if (verdict == SX_NOISE_EXPIRED) {
        z->n_expired++;
        return;
    }
    if (verdict == SX_NOISE_REJECT) {
        z->n_rejected++;
        return;
    }
    size_t slot = 0u;
    const uint32_t i = z->n_confirmed++;
    if (!sx_pick_slot(&sx->pick, i, sx->cfg.n_noise, &slot)) {
        return;
    }
    uint32_t t_unused = 0u, clipped = 0u;
    sx_config_t c = sx->cfg;
    c.realign = 0u;
    c.subsample = false; /* noise windows are cut as they are, without a margin */
    c.margin = 0u;
    (void)sx_cut(v, s + (uint32_t)c.pre_peak, &c, ev->offset, z->wave[slot], NULL, &t_unused, &clipped);
    z->start[slot] = s;
    z->n = (slot >= z->n) ? (slot + 1u) : z->n;
}

static void sx_service_noise(sx_stream_t *sx, const sd_stream_t *det, const sd_events_t *ev, const sd_view_t *v)
{
    sx_snippets_t *z = sx->noise;
    const uint32_t d_w = (uint32_t)sx->cfg.d_w;
    for (uint32_t k = 0u; (k <= SD_RING_SAMPLES) && ((uint64_t)sx->pick.next + d_w <= (uint64_t)v->hi); ++k) {
        const uint32_t s = sx_pick_advance(&sx->pick);
        z->n_candidates++;
        if (sx->q_count >= SX_QUEUE_MAX) {
            z->n_queue_full++;
            continue;
        }
        sx->queue[(sx->q_head + sx->q_count) % SX_QUEUE_MAX] = s;
        sx->q_count++;
    }
    if (sx->q_count == 0u) {
        return; /* nothing waits for confirmation (the usual case) */
    }
    bool has_pend = false;
    uint32_t pend_t = 0u;
    const uint32_t horizon = sd_stream_horizon(det, &has_pend, &pend_t);
    for (uint32_t k = 0u; (k < SX_QUEUE_MAX) && (sx->q_count > 0u); ++k) {
        const uint32_t s = sx->queue[sx->q_head];
        const uint64_t zone_end = (uint64_t)s + d_w + sx->cfg.guard;
        /* confirm only once every detection that could touch the zone is
         * final; the pending event can only move later, so it matters only
         * while it sits before the zone's end */
        if ((zone_end > (uint64_t)horizon) || (has_pend && ((uint64_t)pend_t < zone_end))) {
            break;
        }
        sx->q_head = (sx->q_head + 1u) % SX_QUEUE_MAX;
        sx->q_count--;
        sx_noise_take(sx, ev, v, s);
    }
}

md_status_t sx_stream_service(sx_stream_t *sx, const sd_stream_t *det, bool final)
{
    if ((sx == NULL) || (det == NULL) || (sx->win == NULL) || (sx->noise == NULL)) {
        return MD_E_ARG;
    }
    const sd_events_t *ev = sd_stream_events(det);
    sx->win->offset = ev->offset;
    sx->noise->offset = ev->offset;
    if (!final && (sx->ev_cursor >= ev->n) && (sx->q_count == 0u) &&
        ((uint64_t)sx->pick.next + sx->cfg.d_w > (uint64_t)sd_stream_processed(det))) {
        return MD_OK; /* most calls: no new event to cut, no candidate to draw or to confirm */
    }
    const sd_view_t v = sd_stream_view(det);
    sx_service_spikes(sx, ev, &v, final);
    sx_service_noise(sx, det, ev, &v);
    if (!final) {
        return MD_OK;
    }
    if (sx->q_count > 0u) {
        return MD_E_STATE; /* sd_stream_finish() was not called: events are not final */
    }
    sx->win->n_overflow += ev->n_overflow;
    sx->win->flags |= (ev->n_overflow > 0u) ? SX_FLAG_OVERFLOW : 0u;
    sx->noise->flags |= (ev->n_overflow > 0u) ? SX_FLAG_OVERFLOW : 0u;
    if (sx->noise->n < sx->cfg.n_noise) {
        sx->noise->flags |= SX_FLAG_NOISE_SHORT;
        if (sx->noise->n == 0u) {
            return MD_E_DEGENERATE;
        }
    }
    return MD_OK;
}

md_status_t sx_window_to_double(const sx_windows_t *w, size_t i, double *dst)
{
    if ((w == NULL) || (dst == NULL) || (i >= w->n) || (w->d_w > MD_WAVE_LEN_MAX)) {
        return MD_E_ARG;
    }
    for (size_t j = 0u; j < w->d_w; ++j) {
        dst[j] = w->gain * (double)w->wave[i][j];
    }
    return MD_OK;
}

md_status_t sx_snippet_to_double(const sx_snippets_t *s, size_t i, double *dst)
{
    if ((s == NULL) || (dst == NULL) || (i >= s->n) || (s->d_w > MD_WAVE_LEN_MAX)) {
        return MD_E_ARG;
    }
    for (size_t j = 0u; j < s->d_w; ++j) {
        dst[j] = s->gain * (double)s->wave[i][j];
    }
    return MD_OK;
}

/* ---- offline convenience path ------------------------------------------- */

md_status_t sx_extract_spikes(const int16_t *x, size_t n, const sd_events_t *ev, const sx_config_t *cfg,
                              sx_spikes_t *out)
{
    if ((x == NULL) || (ev == NULL) || (cfg == NULL) || (out == NULL) || !sx_config_valid(cfg) || (cfg->margin > 0u) ||
        (ev->n > MD_MAX_SPIKES) || (n > SD_MAX_INTERVAL_SAMPLES)) {
        return MD_E_ARG; /* raw windows with a margin are the streaming path's */
    }
    const sd_view_t v = {x, UINT32_MAX, 0u, (uint32_t)n};
    out->n = 0u;
    out->d_w = cfg->d_w;
    out->n_edge_skipped = 0u;
    out->n_duplicate = 0u;
    out->n_overflow = ev->n_overflow;
    out->flags = (ev->n_overflow > 0u) ? SX_FLAG_OVERFLOW : 0u;
    for (size_t k = 0u; k < ev->n; ++k) {
        if (ev->t[k] >= n) {
            return MD_E_ARG;
        }
        uint32_t t = ev->t[k], clipped = 0u;
        const sx_cut_t r = sx_cut(&v, ev->t[k], cfg, ev->offset, NULL, out->wave[out->n], &t, &clipped);
        if (r != SX_CUT_OK) {
            out->n_edge_skipped++;
        } else if ((out->n > 0u) && (out->t[out->n - 1u] == t)) {
            out->n_duplicate++;
        } else {
            out->t[out->n] = t;
            out->n++;
        }
    }
    return MD_OK;
}

md_status_t sx_extract_noise(const int16_t *x, size_t n, const sd_events_t *ev, const sx_config_t *cfg, sx_noise_t *out)
{
    if ((x == NULL) || (ev == NULL) || (cfg == NULL) || (out == NULL) || !sx_config_valid(cfg) ||
        (ev->n > MD_MAX_SPIKES) || (n > SD_MAX_INTERVAL_SAMPLES)) {
        return MD_E_ARG;
    }
    const sd_view_t v = {x, UINT32_MAX, 0u, (uint32_t)n};
    sx_picker_t p;
    sx_pick_init(&p, cfg);
    sx_config_t c = *cfg;
    c.realign = 0u;
    c.subsample = false; /* noise windows are cut as they are */
    out->n = 0u;
    out->d_w = cfg->d_w;
    out->n_rejected = 0u;
    out->flags = (ev->n_overflow > 0u) ? SX_FLAG_OVERFLOW : 0u;
    uint32_t confirmed = 0u;
    for (size_t it = 0u; (it <= n) && ((uint64_t)p.next + cfg->d_w <= (uint64_t)n); ++it) {
        const uint32_t s = sx_pick_advance(&p);
        size_t slot = 0u;
        if (sx_pick_check(&p, ev, &v, s, cfg) != SX_NOISE_ACCEPT) {
            out->n_rejected++;
        } else if (sx_pick_slot(&p, confirmed++, cfg->n_noise, &slot)) {
            uint32_t t_unused = 0u, clipped = 0u;
            (void)sx_cut(&v, s + (uint32_t)c.pre_peak, &c, ev->offset, NULL, out->wave[slot], &t_unused, &clipped);
            out->start[slot] = s;
            out->n = (slot >= out->n) ? (slot + 1u) : out->n;
        } else {
            /* confirmed but not kept by the reservoir */
        }
    }
    if (out->n < cfg->n_noise) {
        out->flags |= SX_FLAG_NOISE_SHORT;
        if (out->n == 0u) {
            return MD_E_DEGENERATE;
        }
    }
    return MD_OK;
}
