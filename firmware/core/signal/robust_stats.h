/// @file robust_stats.h
/// Exact order statistics of large int16 buffers without sorting or heap,
/// and quantiles from a histogram of doubles.
///
/// The spike detectors need median(|x|) over a whole recording interval
/// (hundreds of thousands of samples). Sorting a copy is out (no heap, no
/// second buffer); a two-level histogram of |x - offset| is exact and O(n):
/// the first pass finds the coarse bin (value >> 8) that holds the wanted
/// rank, the second resolves it inside that bin.
#ifndef ROBUST_STATS_H
#define ROBUST_STATS_H

#include <stddef.h>
#include <stdint.h>

#define RS_LEVEL_BINS 256u   ///< bins per histogram level; 256 * 256 covers |int16 - int16|
#define RS_MAX_N (1u << 28)  ///< most values per call (32-bit bin counts cannot overflow)

/// Caller-owned histogram storage for rs_abs_kth_i16 / rs_abs_median_i16.
typedef struct {
    uint32_t bins[RS_LEVEL_BINS];
} rs_hist_t;

/// Exact k-th smallest (0-based) value of |x[i] - offset| over i < n.
/// Preconditions: x != NULL, k < n <= RS_MAX_N, -32768 <= offset <= 32767.
/// Returns 0 on a precondition violation. Two passes over x: O(n).
uint32_t rs_abs_kth_i16(const int16_t *x, size_t n, int32_t offset, size_t k, rs_hist_t *work);

/// Exact median of |x[i] - offset| (mean of the two middle values when n is
/// even). Same preconditions as rs_abs_kth_i16 with n >= 1; 0.0 otherwise.
/// Up to four passes over x: O(n).
double rs_abs_median_i16(const int16_t *x, size_t n, int32_t offset, rs_hist_t *work);

/// Bin holding 0-based rank k of a histogram (the last bin if k exceeds
/// the counts); *before receives the count of the lower bins. Building block
/// of exact selection by successive histogram levels. O(bins).
size_t rs_rank_bin(const uint32_t *bins, size_t n_bins, uint64_t k, uint64_t *before);

/// Value of 0-based rank k among the `total` values counted in a histogram
/// whose bin b covers [b*bin_width, (b+1)*bin_width). Values are assumed
/// spread evenly inside a bin, so the error is below one bin width.
/// Returns 0.0 if k >= total or hist is NULL. O(bins).
double rs_hist_rank_value(const uint32_t *hist, size_t bins, double bin_width, uint64_t total, uint64_t k);

#endif
