/* Unit: pca — the basis of constructed data is known. */
#include <math.h>
#include <string.h>

#include "numeric/md_rng.h"
#include "features/pca.h"
#include "unity.h"

#define N_PTS 400u
#define DW 48u

static double g_wave[N_PTS * MD_WAVE_LEN_MAX];
static double g_feat[N_PTS * MD_FEAT_DIM_MAX];
static pca_work_t g_work;
static pca_basis_t g_basis;

void setUp(void) {}
void tearDown(void) {}

/* Orthonormal directions u1, u2 in R^DW: a sine and a cosine period (exactly orthogonal). */
static void directions(double *u1, double *u2)
{
    for (size_t j = 0u; j < DW; ++j) {
        const double ph = 6.283185307179586 * (double)j / (double)DW;
        u1[j] = sin(ph) * sqrt(2.0 / (double)DW);
        u2[j] = cos(ph) * sqrt(2.0 / (double)DW);
    }
}

/* x_i = m + a_i u1 + b_i u2 with exactly centred, uncorrelated a, b of
 * variances 9 and 1: the covariance is 9 u1 u1^T + u2 u2^T. */
static void make_data(double *u1, double *u2, double *m)
{
    directions(u1, u2);
    for (size_t j = 0u; j < DW; ++j) {
        m[j] = -50.0 * exp(-0.5 * ((double)j - 10.0) * ((double)j - 10.0) / 4.0);
    }
    for (size_t i = 0u; i < N_PTS; ++i) {
        /* a on a 4-point grid, b on a 2-point grid: (+-1, +-3) patterns in all
         * 8 combinations -> mean 0, var(a) = 5, var(b) = 1, cov(a,b) = 0 */
        const double a_vals[4] = {-3.0, -1.0, 1.0, 3.0};
        const double a = a_vals[i % 4u] * sqrt(9.0 / 5.0);
        const double b = ((i / 4u) % 2u) ? 1.0 : -1.0;
        for (size_t j = 0u; j < DW; ++j) {
            g_wave[i * MD_WAVE_LEN_MAX + j] = m[j] + a * u1[j] + b * u2[j];
        }
    }
}

static void test_recovers_eigenvectors_and_variances(void)
{
    double u1[DW], u2[DW], m[DW];
    make_data(u1, u2, m);
    TEST_ASSERT_EQUAL_INT(MD_OK, pca_fit(g_wave, N_PTS, MD_WAVE_LEN_MAX, DW, 2u, &g_work, &g_basis));
    /* sample covariance uses 1/(N-1): variances 9 N/(N-1) and N/(N-1) */
    const double f = (double)N_PTS / (double)(N_PTS - 1u);
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 9.0 * f, g_basis.eigval[0]);
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 1.0 * f, g_basis.eigval[1]);
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 10.0 * f, g_basis.total_var);
    double d1 = 0.0, d2 = 0.0;
    for (size_t j = 0u; j < DW; ++j) {
        d1 += g_basis.b[j] * u1[j];
        d2 += g_basis.b[DW + j] * u2[j];
    }
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 1.0, fabs(d1));
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 1.0, fabs(d2));
    for (size_t j = 0u; j < DW; ++j) {
        TEST_ASSERT_DOUBLE_WITHIN(1e-9, m[j], g_basis.mean[j]);
    }
}

static void test_sign_convention_is_deterministic(void)
{
    double u1[DW], u2[DW], m[DW];
    make_data(u1, u2, m);
    TEST_ASSERT_EQUAL_INT(MD_OK, pca_fit(g_wave, N_PTS, MD_WAVE_LEN_MAX, DW, 2u, &g_work, &g_basis));
    for (size_t k = 0u; k < 2u; ++k) {
        /* sin and cos have exactly tied extremes (+-1 at several phases): the
         * first component within 1e-9 of the largest magnitude is positive */
        double big = 0.0;
        for (size_t j = 0u; j < DW; ++j) {
            big = fmax(big, fabs(g_basis.b[k * DW + j]));
        }
        size_t first = 0u;
        while (fabs(g_basis.b[k * DW + first]) < (1.0 - 1e-9) * big) {
            ++first;
        }
        TEST_ASSERT_TRUE(g_basis.b[k * DW + first] > 0.0);
    }
    /* negating every waveform leaves the covariance and hence B unchanged */
    double b0[2u * DW];
    memcpy(b0, g_basis.b, sizeof b0);
    for (size_t i = 0u; i < N_PTS; ++i) {
        for (size_t j = 0u; j < DW; ++j) {
            g_wave[i * MD_WAVE_LEN_MAX + j] = -g_wave[i * MD_WAVE_LEN_MAX + j];
        }
    }
    TEST_ASSERT_EQUAL_INT(MD_OK, pca_fit(g_wave, N_PTS, MD_WAVE_LEN_MAX, DW, 2u, &g_work, &g_basis));
    for (size_t j = 0u; j < 2u * DW; ++j) {
        TEST_ASSERT_DOUBLE_WITHIN(1e-9, b0[j], g_basis.b[j]);
    }
}

static void test_projection_is_b_times_x(void)
{
    double u1[DW], u2[DW], m[DW];
    make_data(u1, u2, m);
    TEST_ASSERT_EQUAL_INT(MD_OK, pca_fit(g_wave, N_PTS, MD_WAVE_LEN_MAX, DW, 2u, &g_work, &g_basis));
    TEST_ASSERT_EQUAL_INT(MD_OK, pca_project_all(&g_basis, g_wave, N_PTS, MD_WAVE_LEN_MAX, g_feat));
    const double s1 = (g_basis.b[0] * u1[0] + g_basis.b[1] * u1[1] > 0.0) ? 1.0 : -1.0;
    double mproj = 0.0;
    for (size_t j = 0u; j < DW; ++j) {
        mproj += g_basis.b[j] * m[j];
    }
    /* point 1 has a = -1*sqrt(9/5): y_0 = B_0 m + s1 a */
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, mproj + s1 * -1.0 * sqrt(9.0 / 5.0), g_feat[1u * 2u]);
}

static void test_degenerate_and_bad_input(void)
{
    for (size_t i = 0u; i < 10u; ++i) {
        for (size_t j = 0u; j < DW; ++j) {
            g_wave[i * MD_WAVE_LEN_MAX + j] = (double)j; /* identical waveforms */
        }
    }
    TEST_ASSERT_EQUAL_INT(MD_E_DEGENERATE, pca_fit(g_wave, 10u, MD_WAVE_LEN_MAX, DW, 2u, &g_work, &g_basis));
    TEST_ASSERT_EQUAL_INT(MD_E_DEGENERATE, pca_fit(g_wave, 1u, MD_WAVE_LEN_MAX, DW, 2u, &g_work, &g_basis));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, pca_fit(g_wave, 10u, MD_WAVE_LEN_MAX, DW, 0u, &g_work, &g_basis));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, pca_fit(g_wave, 10u, MD_WAVE_LEN_MAX, DW, MD_FEAT_DIM_MAX + 1u, &g_work, &g_basis));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, pca_fit(g_wave, 10u, 10u, 23u, 2u, &g_work, &g_basis));
    g_wave[3] = NAN;
    TEST_ASSERT_EQUAL_INT(MD_E_NUMERIC, pca_fit(g_wave, 10u, MD_WAVE_LEN_MAX, DW, 2u, &g_work, &g_basis));
}

/* docs/fuzzing.md finding 2 (crashes/fuzz_pca/pca_trace_overflow_inf_total_var):
 * every covariance entry is finite (5e307) but their sum overflows: the fit
 * must report it, not return MD_OK with total_var = inf and a wrong basis. */
static void test_trace_overflow_is_numeric(void)
{
    const size_t dw = 10u;
    for (size_t j = 0u; j < dw; ++j) {
        g_wave[j] = 1e154;
        g_wave[MD_WAVE_LEN_MAX + j] = 1e-321;
    }
    TEST_ASSERT_EQUAL_INT(MD_E_NUMERIC, pca_fit(g_wave, 2u, MD_WAVE_LEN_MAX, dw, 1u, &g_work, &g_basis));
    /* a single entry overflows */
    g_wave[0] = 1e200;
    TEST_ASSERT_EQUAL_INT(MD_E_NUMERIC, pca_fit(g_wave, 2u, MD_WAVE_LEN_MAX, dw, 1u, &g_work, &g_basis));
    /* the mean overflows (sum of two 1.5e308) */
    for (size_t j = 0u; j < dw; ++j) {
        g_wave[j] = 1.5e308;
        g_wave[MD_WAVE_LEN_MAX + j] = 1.5e308 - 1e300 * (double)j;
    }
    TEST_ASSERT_EQUAL_INT(MD_E_NUMERIC, pca_fit(g_wave, 2u, MD_WAVE_LEN_MAX, dw, 1u, &g_work, &g_basis));
}

/* Large but representable data is not refused: the known basis scaled by 1e100. */
static void test_large_scale_data_still_fits(void)
{
    double u1[DW], u2[DW], m[DW];
    make_data(u1, u2, m);
    for (size_t i = 0u; i < N_PTS * MD_WAVE_LEN_MAX; ++i) {
        g_wave[i] *= 1e100;
    }
    TEST_ASSERT_EQUAL_INT(MD_OK, pca_fit(g_wave, N_PTS, MD_WAVE_LEN_MAX, DW, 2u, &g_work, &g_basis));
    const double f = (double)N_PTS / (double)(N_PTS - 1u);
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 9.0 * f, g_basis.eigval[0] * 1e-200);
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 10.0 * f, g_basis.total_var * 1e-200);
}

/* docs/fuzzing.md finding 5 (crashes/fuzz_pca/subnormal_variance_eigval_above_trace):
 * samples of ~1e-160 have squared deviations in the subnormal range, where
 * the trace and the eigenvalues lose relative precision (an eigenvalue came
 * out above the trace). Such a variance is refused; 1e-140 still fits. */
static void test_variance_below_normal_range_is_degenerate(void)
{
    double u1[DW], u2[DW], m[DW];
    make_data(u1, u2, m);
    for (size_t i = 0u; i < N_PTS * MD_WAVE_LEN_MAX; ++i) {
        g_wave[i] *= 1e-160;
    }
    TEST_ASSERT_EQUAL_INT(MD_E_DEGENERATE, pca_fit(g_wave, N_PTS, MD_WAVE_LEN_MAX, DW, 2u, &g_work, &g_basis));
    for (size_t i = 0u; i < N_PTS * MD_WAVE_LEN_MAX; ++i) {
        g_wave[i] *= 1e20;
    }
    TEST_ASSERT_EQUAL_INT(MD_OK, pca_fit(g_wave, N_PTS, MD_WAVE_LEN_MAX, DW, 2u, &g_work, &g_basis));
    TEST_ASSERT_TRUE(g_basis.eigval[0] <= g_basis.total_var);
    const double f = (double)N_PTS / (double)(N_PTS - 1u);
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 9.0 * f, g_basis.eigval[0] * 1e280);
}

/* docs/fuzzing.md finding 3 (crashes/fuzz_pca/identical_waveforms_ok_instead_of_degenerate):
 * 25 identical windows of 31354 counts x 0.195 uV (a saturated front-end):
 * the rounded mean leaves a trace of ~1e-23, which must not give MD_OK and a
 * basis of rounding noise. One count of difference is real data again. */
static void test_identical_windows_within_rounding_are_degenerate(void)
{
    static int16_t w16[25u * 20u];
    const size_t n = 25u, dw = 20u;
    const double gain = 0.195;
    for (size_t i = 0u; i < n * dw; ++i) {
        w16[i] = 31354;
        g_wave[(i / dw) * MD_WAVE_LEN_MAX + i % dw] = gain * 31354.0;
    }
    TEST_ASSERT_EQUAL_INT(MD_E_DEGENERATE, pca_fit_i16(w16, n, dw, dw, gain, 2u, &g_work, &g_basis));
    TEST_ASSERT_EQUAL_INT(MD_E_DEGENERATE, pca_fit(g_wave, n, MD_WAVE_LEN_MAX, dw, 2u, &g_work, &g_basis));
    w16[7u * dw + 3u] = 31353;
    TEST_ASSERT_EQUAL_INT(MD_OK, pca_fit_i16(w16, n, dw, dw, gain, 1u, &g_work, &g_basis));
    /* one count in one of 25 windows: variance gain^2 (1/25)(24/25)·25/24 on one axis */
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, gain * gain / 25.0, g_basis.eigval[0]);
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 1.0, fabs(g_basis.b[3]));
}

static void test_noisy_spikes_d3(void)
{
    /* random data with a dominant direction: d = 3 rows are orthonormal */
    md_rng_t rng;
    md_rng_seed(&rng, 5u);
    double u1[DW], u2[DW];
    directions(u1, u2);
    for (size_t i = 0u; i < 200u; ++i) {
        const double a = 5.0 * md_rng_gauss(&rng);
        for (size_t j = 0u; j < 23u; ++j) {
            g_wave[i * MD_WAVE_LEN_MAX + j] = a * u1[j] + md_rng_gauss(&rng);
        }
    }
    TEST_ASSERT_EQUAL_INT(MD_OK, pca_fit(g_wave, 200u, MD_WAVE_LEN_MAX, 23u, 3u, &g_work, &g_basis));
    for (size_t p = 0u; p < 3u; ++p) {
        for (size_t q = 0u; q < 3u; ++q) {
            double dot = 0.0;
            for (size_t j = 0u; j < 23u; ++j) {
                dot += g_basis.b[p * 23u + j] * g_basis.b[q * 23u + j];
            }
            TEST_ASSERT_DOUBLE_WITHIN(1e-12, (p == q) ? 1.0 : 0.0, dot);
        }
    }
    TEST_ASSERT_TRUE(g_basis.eigval[0] > 5.0 * g_basis.eigval[1]);
    TEST_ASSERT_TRUE(g_basis.eigval[1] >= g_basis.eigval[2]);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_recovers_eigenvectors_and_variances);
    RUN_TEST(test_sign_convention_is_deterministic);
    RUN_TEST(test_projection_is_b_times_x);
    RUN_TEST(test_degenerate_and_bad_input);
    RUN_TEST(test_noisy_spikes_d3);
    RUN_TEST(test_trace_overflow_is_numeric);
    RUN_TEST(test_large_scale_data_still_fits);
    RUN_TEST(test_identical_windows_within_rounding_are_degenerate);
    RUN_TEST(test_variance_below_normal_range_is_degenerate);
    return UNITY_END();
}
