/// @file spike_align.h
/// Sub-sample alignment of one interval's spike windows on their common
/// template (ours; the thesis aligns on the sample of the minimum, §2.2.2.1).
///
/// Why: a spike's trough falls between samples, and a window cut on the
/// sample of the minimum is up to half a sample early or late. The change
/// this makes to the window lies along the waveform's time derivative, and
/// for a sharp trough it is larger than the noise: one neuron becomes a
/// cluster stretched along that direction in PCA space, wide enough that
/// MAP-EM splits it in two halves that then compete for its track.
/// Locating the trough by the parabola through the three samples around it
/// (the extractor's single-window method) removes part of that spread, but
/// its estimate rests on the two neighbours of the minimum and their noise.
/// Measured on `single_neuron` seed 3, the neuron at a standstill
/// (tools/alignment/alignment_spread.py, docs/detector.md): the window
/// covariance whitened by the noise's keeps its amplitude direction (7.7)
/// with either method, and its second direction, along the slope, falls
/// from 5.53 with the parabola to 1.30 with the template step below.
///
/// Method, per interval (windows cut raw, with SA_MARGIN samples on each
/// side, by the extractor's `margin`):
///  1. each window's trough offset δ0 ∈ [−½, ½] from the parabola through
///     the minimum and its two neighbours, and the window resampled at
///     δ0 with Keys' cubic convolution (a = −½);
///  2. the template T: the mean of those windows, and its slope T';
///  3. one Gauss-Newton step of the least-squares shift of each window
///     against its scaled template a·T (a = ⟨w, T⟩ / ⟨T, T⟩, so a quieter
///     unit of the same shape aligns alike): δ = δ0 + ⟨aT − w, T'⟩ /
///     (a ⟨T', T'⟩), clamped to [−1, 1), and the window resampled at δ.
/// The step uses every sample of the window, so its estimate is far less
/// noisy than the parabola's; one step is enough from δ0 (in the tool's
/// numpy copy a second step left the spread as it was). With several units
/// the template is their mixture:
/// each unit is then aligned consistently against it, which is what the
/// features need. A window whose scale a is not positive keeps δ0.
///
/// Memory: sa_work_t (caller-owned, < 1 kB). No heap, no I/O; O(n d_w).
#ifndef SPIKE_ALIGN_H
#define SPIKE_ALIGN_H

#include <stddef.h>
#include <stdint.h>

#include "md_config.h"
#include "md_status.h"
#include "signal/spike_extract.h"

#define SA_MARGIN 2u        ///< raw samples a window needs on each side for shifts in [−1, 1)
#define SA_SHIFT_MAX 0.999  ///< largest shift, samples (Keys reads one sample before and two after)

/// Scratch of one alignment (caller-owned).
typedef struct {
    double tmpl[MD_WAVE_LEN_MAX];   ///< T
    double slope[MD_WAVE_LEN_MAX];  ///< T'
    double row[MD_WAVE_LEN_MAX];    ///< one resampled window
} sa_work_t;

/// Offset δ ∈ [−½, ½] of the vertex of the parabola through x[i−1], x[i],
/// x[i+1] (0 unless x[i] is a strict local minimum of the three). O(1).
double sa_trough_offset(const int16_t *x, size_t i);

/// out[j] = the raw row at SA_MARGIN + j + δ, j < d_w, by Keys' cubic
/// convolution (a = −½: four samples, exact for quadratics); raw holds
/// d_w + 2·SA_MARGIN samples and δ ∈ [−1, SA_SHIFT_MAX]. O(d_w).
void sa_resample(const int16_t *raw, size_t d_w, double delta, double *out);

/// out[j] = y[j] rounded to whole counts and saturated to int16, j < n;
/// returns the number of saturated values. O(n).
uint32_t sa_round_i16(const double *y, size_t n, int16_t *out);

/// Aligns the windows of `w`, cut with w->margin == SA_MARGIN raw samples on
/// each side of d_w (trough at index SA_MARGIN + w->pre_peak of each row), in
/// place: afterwards row i holds its d_w aligned samples from index 0 and
/// w->margin is 0. Resampled values are rounded to whole counts and
/// saturated to int16 (counted in w->n_clipped); shifts that reach the clamp
/// are counted in w->n_align_clamped. With fewer than 2 windows, or a flat
/// template, every window keeps δ0. MD_E_ARG on NULL, a margin other than
/// SA_MARGIN, a trough on the window's first or last sample, or d_w +
/// 2·SA_MARGIN above MD_WAVE_LEN_MAX (nothing changed). O(n d_w).
md_status_t sa_align_windows(sx_windows_t *w, sa_work_t *work);

#endif
