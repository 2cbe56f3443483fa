/// @file fuzz_pca.c
/// Fuzz target 5b: PCA (firmware/core/features/pca.h) on arbitrary waveform
/// sets: any n, d, d_w and stride (valid or not), waveforms that are fresh,
/// duplicated, scaled copies (rank one) or constant, with values from small
/// integers to NaN, inf, 1e308 and denormals. Checks:
///  - status is one of the documented codes; non-finite input is never MD_OK;
///  - on MD_OK: eigenvalues finite, descending, not below -1e-9·trace and not
///    above the trace; B's rows orthonormal (1e-6) and finite; the sign
///    convention of pca.h holds; the mean is finite; B is the leading
///    eigenbasis (variance of the projections on row r = eigval[r], no
///    coordinate axis with more variance than eigval[0], 1e-6·trace);
///  - pca_project_all of the same waveforms is MD_OK with finite features or
///    MD_E_NUMERIC (overflow), never non-finite features with MD_OK;
///  - int16 path (control bit 6): pca_fit_i16 with any gain returns the same
///    status as pca_fit on the converted rows (gain * count) and, when both
///    succeed, the same eigenvalues and total variance (relative 1e-9);
///    pca_project_all_i16 obeys the projection rule above.
///
/// The reproducers in crashes/fuzz_pca/ (docs/fuzzing.md, "Findings") guard a
/// covariance trace that overflows (values near 1e154: MD_E_NUMERIC, never
/// MD_OK with total_var = inf) and identical waveforms (MD_E_DEGENERATE, never
/// a basis of rounding noise); every check above applies to them.
#include <stdint.h>
#include <string.h>

#include "features/pca.h"
#include "fuzz_input.h"

#define FZ_PCA_N_MAX 256u
#define FZ_PCA_STRIDE_MAX (MD_WAVE_LEN_MAX + 4u)

static double g_wave[FZ_PCA_N_MAX * FZ_PCA_STRIDE_MAX];
static int16_t g_wave16[FZ_PCA_N_MAX * FZ_PCA_STRIDE_MAX];
static pca_basis_t g_basis16;
static double g_feat[FZ_PCA_N_MAX * MD_FEAT_DIM_MAX];
static pca_work_t g_work;
static pca_basis_t g_basis;

/* Waveform i from the input: fresh values, a copy, a scaled copy or a constant. */
static void make_wave(fz_t *in, size_t i, size_t stride, size_t d_w)
{
    double *w = &g_wave[i * stride];
    const uint8_t kind = fz_u8(in);
    const double *prev = (i > 0u) ? &g_wave[(i - 1u) * stride] : NULL;
    if ((kind & 3u) == 1u && prev != NULL) {
        memcpy(w, prev, d_w * sizeof *w);
    } else if ((kind & 3u) == 2u && prev != NULL) {
        const double c = fz_double_mode(in, kind >> 4u);
        for (size_t j = 0u; j < d_w; ++j) {
            w[j] = c * prev[j];
        }
    } else if ((kind & 3u) == 3u) {
        const double c = fz_double_mode(in, kind >> 4u);
        for (size_t j = 0u; j < d_w; ++j) {
            w[j] = c;
        }
    } else {
        for (size_t j = 0u; j < d_w; ++j) {
            w[j] = fz_double_mode(in, kind >> 4u);
        }
    }
}

/* Sample variance (1/(n-1)) of v[0..n) at stride `step`, divided by s^2
 * where s is the largest deviation from the mean: computed without squaring
 * anything large, so data near sqrt(DBL_MAX) cannot overflow the check
 * itself (it did: crashes/fuzz_pca/harness_variance_overflow). *s_out = s. */
static double scaled_var(const double *v, size_t n, size_t step, double *s_out)
{
    double mean = 0.0;
    for (size_t i = 0u; i < n; ++i) {
        mean += v[i * step] / (double)n;
    }
    double s = 0.0;
    for (size_t i = 0u; i < n; ++i) {
        s = fmax(s, fabs(v[i * step] - mean));
    }
    double var = 0.0;
    for (size_t i = 0u; (s > 0.0) && (i < n); ++i) {
        const double dv = (v[i * step] - mean) / s;
        var += dv * dv / (double)(n - 1u);
    }
    *s_out = s;
    return var;
}

/* B must really be the leading eigenbasis: the sample variance (1/(n-1)) of
 * the projections on row r equals eigval[r], and no coordinate axis carries
 * more variance than eigval[0]. Tolerances relative to the trace; compared
 * in units of the largest deviation squared (scaled_var). */
static void check_variances(const pca_basis_t *b, size_t n, size_t stride)
{
    const double tol = 1e-6 * b->total_var;
    for (size_t r = 0u; r < b->d; ++r) {
        for (size_t i = 0u; i < n; ++i) {
            double y = 0.0;
            for (size_t j = 0u; j < b->d_w; ++j) {
                y += b->b[r * b->d_w + j] * g_wave[i * stride + j];
            }
            g_feat[i] = y;
        }
        double s = 0.0;
        const double vs = scaled_var(g_feat, n, 1u, &s);
        if (s > 0.0) {
            FUZZ_CHECK(fabs(vs - b->eigval[r] / s / s) <= tol / s / s);
        } else {
            FUZZ_CHECK(b->eigval[r] <= tol);
        }
    }
    for (size_t j = 0u; j < b->d_w; ++j) {
        double s = 0.0;
        const double vs = scaled_var(&g_wave[j], n, stride, &s);
        FUZZ_CHECK((s == 0.0) || (vs <= b->eigval[0] / s / s + tol / s / s));
    }
}

static void check_basis(const pca_basis_t *b, size_t d, size_t d_w)
{
    FUZZ_CHECK(b->d == d && b->d_w == d_w);
    FUZZ_CHECK(isfinite(b->total_var) && b->total_var > 0.0);
    FUZZ_CHECK(fz_all_finite(b->eigval, d) && fz_all_finite(b->b, d * d_w) && fz_all_finite(b->mean, d_w));
    for (size_t r = 0u; r < d; ++r) {
        FUZZ_CHECK(b->eigval[r] >= -1e-9 * b->total_var);
        FUZZ_CHECK(b->eigval[r] <= b->total_var * (1.0 + 1e-9));
        if (r > 0u) {
            FUZZ_CHECK(b->eigval[r] <= b->eigval[r - 1u] + 1e-12 * b->total_var);
        }
        const double *row = &b->b[r * d_w];
        double big = 0.0;
        for (size_t j = 0u; j < d_w; ++j) {
            big = fmax(big, fabs(row[j]));
        }
        size_t pick = 0u;
        while (pick < d_w && fabs(row[pick]) < (1.0 - 1e-9) * big) {
            pick++;
        }
        FUZZ_CHECK(pick < d_w && row[pick] > 0.0); /* sign convention */
        for (size_t s = 0u; s <= r; ++s) {
            double dot = 0.0;
            for (size_t j = 0u; j < d_w; ++j) {
                dot += row[j] * b->b[s * d_w + j];
            }
            FUZZ_CHECK(fabs(dot - ((s == r) ? 1.0 : 0.0)) <= 1e-6);
        }
    }
}

/* The same waveforms as int16 counts (fresh, copy or constant) and as doubles gain * count. */
static void make_wave16(fz_t *in, size_t i, size_t stride, size_t d_w, double gain)
{
    int16_t *w = &g_wave16[i * stride];
    const uint8_t kind = fz_u8(in);
    if ((kind & 3u) == 1u && i > 0u) {
        memcpy(w, &g_wave16[(i - 1u) * stride], d_w * sizeof *w);
    } else if ((kind & 3u) == 2u) {
        const int16_t c = (int16_t)fz_u16(in);
        for (size_t j = 0u; j < d_w; ++j) {
            w[j] = c;
        }
    } else {
        for (size_t j = 0u; j < d_w; ++j) {
            w[j] = ((kind & 4u) != 0u) ? (int16_t)fz_u16(in) : (int16_t)(int8_t)fz_u8(in);
        }
    }
    for (size_t j = 0u; j < d_w; ++j) {
        g_wave[i * stride + j] = gain * (double)w[j];
    }
}

static bool close_rel(double a, double b)
{
    return fabs(a - b) <= 1e-9 * fmax(fabs(a), fabs(b)) + 1e-300;
}

static void check_projection(const pca_basis_t *b, size_t n, size_t stride, bool i16, double gain)
{
    const md_status_t pst = i16 ? pca_project_all_i16(b, g_wave16, n, stride, gain, g_feat)
                                : pca_project_all(b, g_wave, n, stride, g_feat);
    FUZZ_CHECK(pst == MD_OK || pst == MD_E_NUMERIC);
    if (pst == MD_OK) {
        FUZZ_CHECK(fz_all_finite(g_feat, n * b->d));
    }
}

static void run_i16(size_t n, size_t stride, size_t d_w, size_t d, double gain, bool finite)
{
    const md_status_t st16 = pca_fit_i16(g_wave16, n, stride, d_w, gain, d, &g_work, &g_basis16);
    FUZZ_CHECK(st16 == MD_OK || st16 == MD_E_ARG || st16 == MD_E_DEGENERATE || st16 == MD_E_NUMERIC ||
               st16 == MD_E_NOCONVERGE);
    if (!(gain > 0.0) || !isfinite(gain)) {
        FUZZ_CHECK(st16 == MD_E_ARG);
        return;
    }
    const md_status_t st = pca_fit(g_wave, n, stride, d_w, d, &g_work, &g_basis);
    if (!finite) {
        /* gain * count overflowed: there are no "converted rows" to compare
         * with, but a success would have to come from an overflowed covariance. */
        FUZZ_CHECK(st16 != MD_OK);
        return;
    }
    FUZZ_CHECK(st16 == st); /* "same result as pca_fit on the converted rows" */
    if (st16 != MD_OK) {
        return;
    }
    check_basis(&g_basis16, d, d_w);
    check_variances(&g_basis16, n, stride);
    FUZZ_CHECK(close_rel(g_basis16.total_var, g_basis.total_var));
    for (size_t k = 0u; k < d; ++k) {
        FUZZ_CHECK(fabs(g_basis16.eigval[k] - g_basis.eigval[k]) <= 1e-9 * g_basis.total_var + 1e-300);
    }
    check_projection(&g_basis16, n, stride, true, gain);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fz_t in;
    fz_init(&in, data, size);
    const uint8_t control = fz_u8(&in);
    const size_t d = control % (MD_FEAT_DIM_MAX + 2u);      /* 0 and MAX+1 are invalid */
    const size_t d_w = fz_u8(&in) % (MD_WAVE_LEN_MAX + 3u); /* up to MAX+2: invalid */
    const uint8_t s = fz_u8(&in);
    const size_t stride = ((s & 0x80u) != 0u && d_w > 0u) ? d_w - 1u : d_w + (s & 3u);
    const size_t row = (stride > d_w) ? stride : d_w;
    const bool i16 = (control & 0x40u) != 0u;
    const double gain = i16 ? (((control & 0x80u) != 0u) ? fz_double(&in) : 0.195) : 1.0;
    size_t n = 0u;
    while (fz_left(&in) > 0u && n < FZ_PCA_N_MAX && (n + 1u) * row <= FZ_PCA_N_MAX * FZ_PCA_STRIDE_MAX) {
        if (i16) {
            make_wave16(&in, n, row, d_w, gain);
        } else {
            make_wave(&in, n, row, d_w);
        }
        n++;
    }
    bool finite = true;
    for (size_t i = 0u; i < n; ++i) {
        finite = finite && fz_all_finite(&g_wave[i * row], d_w);
    }
    if (i16) {
        run_i16(n, stride, d_w, d, gain, finite);
        return 0;
    }
    const md_status_t st = pca_fit(g_wave, n, stride, d_w, d, &g_work, &g_basis);
    FUZZ_CHECK(st == MD_OK || st == MD_E_ARG || st == MD_E_DEGENERATE || st == MD_E_NUMERIC || st == MD_E_NOCONVERGE);
    if (st != MD_OK) {
        return 0;
    }
    FUZZ_CHECK(finite);
    FUZZ_CHECK(stride == row); /* a stride shorter than the waveform must have been refused */
    check_basis(&g_basis, d, d_w);
    check_variances(&g_basis, n, stride);
    check_projection(&g_basis, n, stride, false, 1.0);
    return 0;
}
