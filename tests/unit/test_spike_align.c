/* Unit: spike_align — windows of one spike shape cut at random sampling
 * phases and amplitudes come out aligned (no spread left along the
 * template's slope), bad arguments change nothing, a lone window keeps the
 * parabola's shift, a shift beyond its bound is clamped and counted, and
 * resampled values that leave int16 are saturated and counted. */
#include <math.h>
#include <string.h>

#include "numeric/md_rng.h"
#include "signal/spike_align.h"
#include "unity.h"

#define D_W 35u    /* 1.15 ms at 30 kHz, as the chain cuts */
#define PRE 12u    /* pre_peak at 30 kHz */
#define N_WIN 200u /* windows of the phase test */
#define NOISE 20.0 /* counts; the trough is 400 */

static sx_windows_t g_w;
static sa_work_t g_work;

void setUp(void) {}
void tearDown(void) {}

/* A smooth biphasic spike (trough 400 counts, ~3 samples wide) at time t in samples from its trough. */
static double shape(double t)
{
    const double u = t / 3.0;
    return -400.0 * exp(-0.5 * u * u) + 120.0 * exp(-0.5 * (u - 2.5) * (u - 2.5));
}

/* Row i: the raw window with its margin, the trough `phase` samples after the sample of the minimum. */
static void put_row(size_t i, double phase, double scale, double noise, md_rng_t *r)
{
    for (size_t k = 0u; k < D_W + 2u * SA_MARGIN; ++k) {
        const double t = (double)k - (double)(SA_MARGIN + PRE) - phase;
        g_w.wave[i][k] = (int16_t)lround(scale * shape(t) + noise * md_rng_gauss(r));
    }
}

static void windows(size_t n)
{
    memset(&g_w, 0, sizeof g_w);
    g_w.n = n;
    g_w.d_w = D_W;
    g_w.margin = SA_MARGIN;
    g_w.pre_peak = PRE;
    g_w.gain = 1.0;
}

/* RMS over the windows of their deviation from the mean, projected on the mean's slope. */
static double spread_along_slope(void)
{
    double mean[D_W] = {0.0}, slope[D_W] = {0.0};
    for (size_t i = 0u; i < g_w.n; ++i) {
        for (size_t j = 0u; j < D_W; ++j) {
            mean[j] += g_w.wave[i][j] / (double)g_w.n;
        }
    }
    double norm = 0.0;
    for (size_t j = 1u; j + 1u < D_W; ++j) {
        slope[j] = 0.5 * (mean[j + 1u] - mean[j - 1u]);
        norm += slope[j] * slope[j];
    }
    double ss = 0.0;
    for (size_t i = 0u; i < g_w.n; ++i) {
        double p = 0.0;
        for (size_t j = 0u; j < D_W; ++j) {
            p += (g_w.wave[i][j] - mean[j]) * slope[j];
        }
        ss += (p * p) / norm;
    }
    return sqrt(ss / (double)g_w.n);
}

/* Phases uniform in [-1/2, 1/2], noise 20 counts: after alignment the spread
 * along the slope is below the noise (the shift absorbs the noise along it
 * too). The parabola alone leaves 3.4 × the noise on these windows
 * (measured with a numpy copy of the method); cut on the sample of the
 * minimum, the windows spread by far more. */
static void test_random_phases_align_on_the_template(void)
{
    md_rng_t r;
    md_rng_seed(&r, 5u);
    windows(N_WIN);
    for (size_t i = 0u; i < N_WIN; ++i) {
        put_row(i, md_rng_uniform(&r) - 0.5, 1.0, NOISE, &r);
    }
    TEST_ASSERT_EQUAL_INT(MD_OK, sa_align_windows(&g_w, &g_work));
    TEST_ASSERT_EQUAL_size_t(0u, g_w.margin);
    TEST_ASSERT_EQUAL_UINT32(0u, g_w.n_align_clamped);
    TEST_ASSERT_LESS_THAN_DOUBLE(NOISE, spread_along_slope());
    /* the trough stays at pre_peak */
    double lo = 0.0;
    size_t at = 0u;
    for (size_t j = 0u; j < D_W; ++j) {
        double m = 0.0;
        for (size_t i = 0u; i < N_WIN; ++i) {
            m += g_w.wave[i][j];
        }
        if (m < lo) {
            lo = m;
            at = j;
        }
    }
    TEST_ASSERT_EQUAL_size_t(PRE, at);
}

/* Quieter and louder copies of one shape align alike: the template is scaled
 * to each window, so a pair cut at one phase with amplitudes 0.6 and 1.4
 * comes out proportional (within the rounding to whole counts of the input
 * and the output: (0.5 + 0.5) / 0.6 + (0.5 + 0.5) / 1.4 = 2.4 counts), and close to
 * the shape itself at phase 0 (within the cubic's error). */
static void test_amplitudes_do_not_bias_the_shift(void)
{
    md_rng_t r;
    md_rng_seed(&r, 9u);
    windows(N_WIN);
    for (size_t i = 0u; i < N_WIN; i += 2u) {
        const double phase = md_rng_uniform(&r) - 0.5;
        put_row(i, phase, 0.6, 0.0, &r);
        put_row(i + 1u, phase, 1.4, 0.0, &r);
    }
    TEST_ASSERT_EQUAL_INT(MD_OK, sa_align_windows(&g_w, &g_work));
    double pair = 0.0;
    double exact = 0.0;
    for (size_t i = 0u; i < N_WIN; i += 2u) {
        for (size_t j = 0u; j < D_W; ++j) {
            const double ref = shape((double)j - (double)PRE);
            pair = fmax(pair, fabs(g_w.wave[i][j] / 0.6 - g_w.wave[i + 1u][j] / 1.4));
            exact = fmax(exact, fabs(g_w.wave[i + 1u][j] / 1.4 - ref));
        }
    }
    TEST_ASSERT_LESS_THAN_DOUBLE(2.4, pair);
    TEST_ASSERT_LESS_THAN_DOUBLE(12.0, exact); /* 3 % of the 400-count trough */
}

static void test_bad_arguments_change_nothing(void)
{
    md_rng_t r;
    md_rng_seed(&r, 1u);
    windows(4u);
    for (size_t i = 0u; i < 4u; ++i) {
        put_row(i, 0.3, 1.0, NOISE, &r);
    }
    static sx_windows_t copy;
    copy = g_w;
    g_w.margin = 0u; /* already aligned */
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, sa_align_windows(&g_w, &g_work));
    g_w.margin = SA_MARGIN;
    g_w.pre_peak = 0u; /* no sample before the trough */
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, sa_align_windows(&g_w, &g_work));
    g_w.pre_peak = PRE;
    g_w.d_w = MD_WAVE_LEN_MAX - 2u * SA_MARGIN + 1u; /* the margin would leave the row */
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, sa_align_windows(&g_w, &g_work));
    g_w.d_w = D_W;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, sa_align_windows(NULL, &g_work));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, sa_align_windows(&g_w, NULL));
    TEST_ASSERT_EQUAL_MEMORY(&copy, &g_w, sizeof g_w);
}

/* One window has no template: it is resampled on the parabola's vertex, so
 * its minimum lands on pre_peak with the trough's depth (within the cubic's error). */
static void test_a_lone_window_keeps_the_parabola(void)
{
    md_rng_t r;
    md_rng_seed(&r, 2u);
    windows(1u);
    put_row(0u, 0.4, 1.0, 0.0, &r);
    TEST_ASSERT_EQUAL_INT(MD_OK, sa_align_windows(&g_w, &g_work));
    TEST_ASSERT_EQUAL_size_t(0u, g_w.margin);
    for (size_t j = 0u; j < D_W; ++j) {
        TEST_ASSERT_TRUE(g_w.wave[0][j] >= g_w.wave[0][PRE]);
    }
    TEST_ASSERT_INT_WITHIN(8, -400, g_w.wave[0][PRE]);
}

/* A window shaped like the template's slope (scale a close to 0) would be
 * shifted by about -1/a samples: the shift stops at its bound and is counted. */
static void test_a_shift_past_its_bound_is_clamped_and_counted(void)
{
    md_rng_t r;
    md_rng_seed(&r, 3u);
    windows(21u);
    for (size_t i = 0u; i < 20u; ++i) {
        put_row(i, 0.0, 1.0, 0.0, &r);
    }
    for (size_t k = 0u; k < D_W + 2u * SA_MARGIN; ++k) {
        const double t = (double)k - (double)(SA_MARGIN + PRE);
        g_w.wave[20][k] = (int16_t)lround(shape(t + 0.5) - shape(t - 0.5) + 0.02 * shape(t));
    }
    TEST_ASSERT_EQUAL_INT(MD_OK, sa_align_windows(&g_w, &g_work));
    TEST_ASSERT_EQUAL_UINT32(1u, g_w.n_align_clamped);
}

/* A trough at the bottom of the ADC range: the cubic undershoots below
 * INT16_MIN between samples; the value saturates and is counted. */
static void test_resampled_values_saturate_and_are_counted(void)
{
    windows(1u);
    for (size_t k = 0u; k < D_W + 2u * SA_MARGIN; ++k) {
        g_w.wave[0][k] = 0;
    }
    g_w.wave[0][SA_MARGIN + PRE - 1u] = -20000;
    g_w.wave[0][SA_MARGIN + PRE] = INT16_MIN;
    g_w.wave[0][SA_MARGIN + PRE + 1u] = -31000;
    TEST_ASSERT_EQUAL_INT(MD_OK, sa_align_windows(&g_w, &g_work));
    TEST_ASSERT_GREATER_THAN_UINT32(0u, g_w.n_clipped);
    TEST_ASSERT_EQUAL_INT16(INT16_MIN, g_w.wave[0][PRE]);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_random_phases_align_on_the_template);
    RUN_TEST(test_amplitudes_do_not_bias_the_shift);
    RUN_TEST(test_bad_arguments_change_nothing);
    RUN_TEST(test_a_lone_window_keeps_the_parabola);
    RUN_TEST(test_a_shift_past_its_bound_is_clamped_and_counted);
    RUN_TEST(test_resampled_values_saturate_and_are_counted);
    return UNITY_END();
}
