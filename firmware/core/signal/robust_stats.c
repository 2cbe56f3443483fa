/// @file robust_stats.c
/// Two-level histogram selection (see robust_stats.h).
#include "signal/robust_stats.h"

#include <string.h>

static uint32_t rs_absdiff(int16_t v, int32_t offset)
{
    const int32_t d = (int32_t)v - offset;
    return (uint32_t)((d < 0) ? -d : d);
}

size_t rs_rank_bin(const uint32_t *bins, size_t n_bins, uint64_t k, uint64_t *before)
{
    uint64_t dummy = 0u;
    before = (before != NULL) ? before : &dummy;
    if ((bins == NULL) || (n_bins == 0u)) {
        *before = 0u;
        return 0u;
    }
    uint64_t cum = 0u;
    for (size_t b = 0u; b < n_bins; ++b) {
        if (k < cum + bins[b]) {
            *before = cum;
            return b;
        }
        cum += bins[b];
    }
    *before = cum;
    return n_bins - 1u;
}

uint32_t rs_abs_kth_i16(const int16_t *x, size_t n, int32_t offset, size_t k, rs_hist_t *work)
{
    if ((x == NULL) || (work == NULL) || (k >= n) || (n > RS_MAX_N) || (offset < -32768) ||
        (offset > 32767)) {
        return 0u;
    }
    /* |x - offset| <= 65535: the coarse level is the high byte. */
    memset(work->bins, 0, sizeof work->bins);
    for (size_t i = 0u; i < n; ++i) {
        work->bins[rs_absdiff(x[i], offset) >> 8u]++;
    }
    uint64_t before = 0u;
    const size_t coarse = rs_rank_bin(work->bins, RS_LEVEL_BINS, (uint64_t)k, &before);
    memset(work->bins, 0, sizeof work->bins);
    for (size_t i = 0u; i < n; ++i) {
        const uint32_t v = rs_absdiff(x[i], offset);
        if ((size_t)(v >> 8u) == coarse) {
            work->bins[v & 0xFFu]++;
        }
    }
    uint64_t before_fine = 0u;
    const size_t fine = rs_rank_bin(work->bins, RS_LEVEL_BINS, (uint64_t)k - before, &before_fine);
    return (uint32_t)((coarse << 8u) | fine);
}

double rs_abs_median_i16(const int16_t *x, size_t n, int32_t offset, rs_hist_t *work)
{
    if (n == 0u) {
        return 0.0;
    }
    const uint32_t lo = rs_abs_kth_i16(x, n, offset, (n - 1u) / 2u, work);
    if ((n % 2u) == 1u) {
        return (double)lo;
    }
    const uint32_t hi = rs_abs_kth_i16(x, n, offset, n / 2u, work);
    return 0.5 * ((double)lo + (double)hi);
}

double rs_hist_rank_value(const uint32_t *hist, size_t bins, double bin_width, uint64_t total, uint64_t k)
{
    if ((hist == NULL) || (bins == 0u) || (k >= total)) {
        return 0.0;
    }
    uint64_t before = 0u;
    const size_t b = rs_rank_bin(hist, bins, k, &before);
    if (hist[b] == 0u) {
        return (double)bins * bin_width; /* total exceeded the histogram's counts */
    }
    /* rank k sits at fraction (k - before + 0.5)/count of the way through bin b */
    const double frac = ((double)(k - before) + 0.5) / (double)hist[b];
    return ((double)b + frac) * bin_width;
}
