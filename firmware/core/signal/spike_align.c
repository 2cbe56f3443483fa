/// @file spike_align.c
/// Template alignment of an interval's spike windows (see spike_align.h).
#include "signal/spike_align.h"

#include <math.h>
#include <stdbool.h>
#include <string.h>

_Static_assert(SA_MARGIN >= 2u, "Keys' kernel reads two samples past a shift just below one sample");

double sa_trough_offset(const int16_t *x, size_t i)
{
    const double a = (double)x[i - 1u];
    const double b = (double)x[i];
    const double c = (double)x[i + 1u];
    const double curv = a - 2.0 * b + c;
    if (!(curv > 0.0)) {
        return 0.0;
    }
    const double d = 0.5 * (a - c) / curv;
    return (d < -0.5) ? -0.5 : ((d > 0.5) ? 0.5 : d);
}

void sa_resample(const int16_t *raw, size_t d_w, double delta, double *out)
{
    const size_t base = (delta < 0.0) ? ((size_t)SA_MARGIN - 1u) : (size_t)SA_MARGIN;
    const double f = (delta < 0.0) ? (1.0 + delta) : delta;
    for (size_t j = 0u; j < d_w; ++j) {
        const size_t i = base + j;
        const double p0 = (double)raw[i - 1u];
        const double p1 = (double)raw[i];
        const double p2 = (double)raw[i + 1u];
        const double p3 = (double)raw[i + 2u];
        out[j] = p1 +
                 0.5 * f * ((p2 - p0) + f * ((2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3) + f * (3.0 * (p1 - p2) + p3 - p0)));
    }
}

/* Step 2: the template T (mean of the windows resampled at δ0) and its slope T'. */
static void sa_template(const sx_windows_t *w, sa_work_t *k)
{
    const size_t d_w = w->d_w;
    memset(k->tmpl, 0, sizeof k->tmpl);
    for (size_t i = 0u; i < w->n; ++i) {
        sa_resample(w->wave[i], d_w, sa_trough_offset(w->wave[i], SA_MARGIN + w->pre_peak), k->row);
        for (size_t j = 0u; j < d_w; ++j) {
            k->tmpl[j] += k->row[j];
        }
    }
    for (size_t j = 0u; j < d_w; ++j) {
        k->tmpl[j] /= (double)w->n;
    }
    k->slope[0] = k->tmpl[1] - k->tmpl[0];
    k->slope[d_w - 1u] = k->tmpl[d_w - 1u] - k->tmpl[d_w - 2u];
    for (size_t j = 1u; j + 1u < d_w; ++j) {
        k->slope[j] = 0.5 * (k->tmpl[j + 1u] - k->tmpl[j - 1u]);
    }
}

/* Step 3: δ0 plus one Gauss-Newton step of the least-squares shift against a·T
 * (the window k->row is resampled at δ0); *clamped when it reached [−1, SA_SHIFT_MAX]. */
static double sa_shift(const sa_work_t *k, size_t d_w, double delta0, double tt, double ss, int *clamped)
{
    double wt = 0.0;
    for (size_t j = 0u; j < d_w; ++j) {
        wt += k->row[j] * k->tmpl[j];
    }
    const double a = wt / tt;
    if (!(a > 0.0)) {
        return delta0; /* not the template's polarity: no shape to align on */
    }
    double rs = 0.0;
    for (size_t j = 0u; j < d_w; ++j) {
        rs += (a * k->tmpl[j] - k->row[j]) * k->slope[j];
    }
    const double d = delta0 + rs / (a * ss);
    *clamped = (d < -1.0) || (d > SA_SHIFT_MAX) || !isfinite(d);
    if (!isfinite(d)) {
        return delta0;
    }
    return (d < -1.0) ? -1.0 : ((d > SA_SHIFT_MAX) ? SA_SHIFT_MAX : d);
}

uint32_t sa_round_i16(const double *y, size_t n, int16_t *out)
{
    uint32_t clipped = 0u;
    for (size_t j = 0u; j < n; ++j) {
        const double r = nearbyint(y[j]);
        const bool over = (r < (double)INT16_MIN) || (r > (double)INT16_MAX);
        clipped += over ? 1u : 0u;
        const double sat = (r < (double)INT16_MIN) ? (double)INT16_MIN
                                                   : ((r > (double)INT16_MAX) ? (double)INT16_MAX : r);
        out[j] = (int16_t)sat;
    }
    return clipped;
}

/* Row i := its d_w samples at shift δ, whole counts, saturated. */
static void sa_store(sx_windows_t *w, size_t i, double delta, sa_work_t *k)
{
    sa_resample(w->wave[i], w->d_w, delta, k->row); /* every read before the first write */
    w->n_clipped += sa_round_i16(k->row, w->d_w, w->wave[i]);
}

md_status_t sa_align_windows(sx_windows_t *w, sa_work_t *work)
{
    if ((w == NULL) || (work == NULL) || (w->margin != SA_MARGIN) || (w->d_w < 3u) || (w->pre_peak < 1u) ||
        (w->pre_peak + 1u >= w->d_w) || (w->d_w + 2u * (size_t)SA_MARGIN > MD_WAVE_LEN_MAX) || (w->n > MD_MAX_SPIKES)) {
        return MD_E_ARG;
    }
    double tt = 0.0;
    double ss = 0.0;
    if (w->n >= 2u) {
        sa_template(w, work);
        for (size_t j = 0u; j < w->d_w; ++j) {
            tt += work->tmpl[j] * work->tmpl[j];
            ss += work->slope[j] * work->slope[j];
        }
    }
    const bool use_template = (tt > 0.0) && (ss > 0.0);
    for (size_t i = 0u; i < w->n; ++i) {
        double delta = sa_trough_offset(w->wave[i], SA_MARGIN + w->pre_peak);
        if (use_template) {
            int clamped = 0;
            sa_resample(w->wave[i], w->d_w, delta, work->row);
            delta = sa_shift(work, w->d_w, delta, tt, ss, &clamped);
            w->n_align_clamped += (clamped != 0) ? 1u : 0u;
        }
        sa_store(w, i, delta, work);
    }
    w->margin = 0u;
    return MD_OK;
}
