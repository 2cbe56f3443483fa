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
    if ((x == NULL) || (work == NULL) || (k >= n) || (n > RS_MAX_N) || (offset < -32768) || (offset > 32767)) {
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

/* The two middle ranks k and k + 1 of |x - offset| (n even) from one coarse
 * and one fine pass: values as rs_abs_kth_i16 gives them. If the ranks fall
 * in different coarse bins, rank k + 1 is the least value of its bin. */
static void rs_abs_kth2_i16(const int16_t *x, size_t n, int32_t offset, size_t k, rs_hist_t *work, uint32_t *lo,
                            uint32_t *hi)
{
    *lo = 0u;
    *hi = 0u;
    if ((x == NULL) || (work == NULL) || (k + 1u >= n) || (n > RS_MAX_N) || (offset < -32768) || (offset > 32767)) {
        return;
    }
    memset(work->bins, 0, sizeof work->bins);
    for (size_t i = 0u; i < n; ++i) {
        work->bins[rs_absdiff(x[i], offset) >> 8u]++;
    }
    uint64_t before[2] = {0u, 0u};
    const size_t coarse0 = rs_rank_bin(work->bins, RS_LEVEL_BINS, (uint64_t)k, &before[0]);
    const size_t coarse1 = rs_rank_bin(work->bins, RS_LEVEL_BINS, (uint64_t)k + 1u, &before[1]);
    memset(work->bins, 0, sizeof work->bins);
    uint32_t least = RS_LEVEL_BINS - 1u; /* fine value of rank k + 1 when it is alone in its coarse bin */
    for (size_t i = 0u; i < n; ++i) {
        const uint32_t v = rs_absdiff(x[i], offset);
        const uint32_t hb = v >> 8u;
        if ((size_t)hb == coarse0) {
            work->bins[v & 0xFFu]++;
        } else if (((size_t)hb == coarse1) && ((v & 0xFFu) < least)) {
            least = v & 0xFFu;
        } else {
            /* outside both coarse bins */
        }
    }
    const size_t fine0 = rs_rank_bin(work->bins, RS_LEVEL_BINS, (uint64_t)k - before[0], NULL);
    const size_t fine1 = (coarse1 == coarse0)
                             ? rs_rank_bin(work->bins, RS_LEVEL_BINS, (uint64_t)k + 1u - before[1], NULL)
                             : least;
    const uint32_t c0 = (uint32_t)coarse0;
    const uint32_t c1 = (uint32_t)coarse1;
    *lo = (c0 << 8u) | (uint32_t)fine0;
    *hi = (c1 << 8u) | (uint32_t)fine1;
}

double rs_abs_median_i16(const int16_t *x, size_t n, int32_t offset, rs_hist_t *work)
{
    if (n == 0u) {
        return 0.0;
    }
    if ((n % 2u) == 1u) {
        return (double)rs_abs_kth_i16(x, n, offset, (n - 1u) / 2u, work);
    }
    uint32_t lo = 0u;
    uint32_t hi = 0u;
    rs_abs_kth2_i16(x, n, offset, (n - 1u) / 2u, work, &lo, &hi);
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
