/* Unit: em_modes — ridgeline ratio of two Gaussian components against the
 * 1-D mixture's own density (a fine grid), and the over-split test built on it. */
#include <math.h>
#include <string.h>

#include "cluster/em_modes.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

/* Two clusters in d = 2: means (0, 0) and (sep, 0), weights w and 1 - w (no
 * outliers), shape diag(sx², 1/sx²) for both (det C = 1), volume λ = 1. */
static em_params_t pair(double sep, double w, double sx)
{
    em_params_t p;
    memset(&p, 0, sizeof p);
    p.d = 2u;
    p.g = 2u;
    p.pi[0] = w;
    p.pi[1] = 1.0 - w;
    p.mean[1][0] = sep;
    for (size_t g = 0u; g < 2u; ++g) {
        p.shape[g][0] = sx * sx;
        p.shape[g][3] = 1.0 / (sx * sx);
    }
    p.lambda = 1.0;
    return p;
}

/* Reference: the same ratio from the 1-D mixture on a grid of 200 001 points
 * (with equal shapes the ridgeline is the segment between the means). */
static double reference_ratio(double sep, double w, double sx)
{
    static double v[200001];
    const size_t n = sizeof v / sizeof v[0];
    size_t kmin = 0u;
    for (size_t k = 0u; k < n; ++k) {
        const double x = sep * (double)k / (double)(n - 1u);
        const double za = x / sx;
        const double zb = (x - sep) / sx;
        v[k] = w * exp(-0.5 * za * za) + (1.0 - w) * exp(-0.5 * zb * zb);
        kmin = (v[k] < v[kmin]) ? k : kmin;
    }
    double left = 0.0;
    double right = 0.0;
    for (size_t k = 0u; k < n; ++k) {
        left = (k <= kmin) ? fmax(left, v[k]) : left;
        right = (k >= kmin) ? fmax(right, v[k]) : right;
    }
    return v[kmin] / fmin(left, right);
}

static void test_ratio_matches_the_mixture_density(void)
{
    const double cases[][3] = {
        {1.9, 0.5, 1.0},                  /* equal halves closer than 2 sd: one mode */
        {2.6, 0.5, 1.0},                  /* just past 2 sd: a shallow dip (0.827) */
        {3.0, 0.5, 1.0}, {2.5, 0.9, 1.0}, /* a small component on the flank: a shoulder, one mode */
        {4.0, 0.9, 1.0}, {5.2, 0.5, 2.0}, /* wide along the axis joining the means: as 2.6 sd */
        {8.0, 0.5, 1.0},                  /* far apart: a deep dip */
    };
    for (size_t i = 0u; i < sizeof cases / sizeof cases[0]; ++i) {
        const em_params_t p = pair(cases[i][0], cases[i][1], cases[i][2]);
        double r = -1.0;
        TEST_ASSERT_EQUAL_INT(MD_OK, em_ridge_ratio(&p, 1u, 2u, &r));
        TEST_ASSERT_DOUBLE_WITHIN(0.01, reference_ratio(cases[i][0], cases[i][1], cases[i][2]), r);
        double r21 = -1.0;
        TEST_ASSERT_EQUAL_INT(MD_OK, em_ridge_ratio(&p, 2u, 1u, &r21));
        TEST_ASSERT_DOUBLE_WITHIN(1e-12, r, r21);
    }
}

/* A narrow component inside a wide one (different shapes, curved ridgeline):
 * one mode whatever the weights. */
static void test_a_component_inside_another_is_one_mode(void)
{
    em_params_t p = pair(0.5, 0.8, 1.0);
    p.shape[1][0] = 9.0;
    p.shape[1][3] = 1.0 / 9.0;
    p.lambda = 2.0;
    double r = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_OK, em_ridge_ratio(&p, 1u, 2u, &r));
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 1.0, r);
}

static void test_oversplit_needs_one_unimodal_pair(void)
{
    em_params_t p;
    memset(&p, 0, sizeof p);
    p.d = 2u;
    p.g = 3u;
    p.lambda = 1.0;
    p.pi0 = 0.1;
    const double mean[3][2] = {{0.0, 0.0}, {10.0, 0.0}, {0.0, 10.0}};
    for (size_t g = 0u; g < 3u; ++g) {
        p.pi[g] = 0.3;
        p.mean[g][0] = mean[g][0];
        p.mean[g][1] = mean[g][1];
        p.shape[g][0] = 1.0;
        p.shape[g][3] = 1.0;
    }
    bool split = true;
    TEST_ASSERT_EQUAL_INT(MD_OK, em_params_oversplit(&p, 0.99, &split));
    TEST_ASSERT_FALSE(split);
    p.mean[2][0] = 11.5; /* the third now sits 1.5 sd beside the second */
    p.mean[2][1] = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_OK, em_params_oversplit(&p, 0.99, &split));
    TEST_ASSERT_TRUE(split);
    p.g = 1u; /* one cluster: nothing to split */
    TEST_ASSERT_EQUAL_INT(MD_OK, em_params_oversplit(&p, 0.99, &split));
    TEST_ASSERT_FALSE(split);
}

static void test_bad_inputs(void)
{
    em_params_t p = pair(3.0, 0.5, 1.0);
    double r = 0.0;
    bool split = true;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, em_ridge_ratio(&p, 1u, 1u, &r));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, em_ridge_ratio(&p, 0u, 1u, &r));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, em_ridge_ratio(&p, 1u, 3u, &r));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, em_ridge_ratio(NULL, 1u, 2u, &r));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, em_ridge_ratio(&p, 1u, 2u, NULL));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, em_params_oversplit(&p, 0.0, &split));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, em_params_oversplit(&p, 1.5, &split));
    p.pi[1] = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, em_ridge_ratio(&p, 1u, 2u, &r));
    p = pair(3.0, 0.5, 1.0);
    p.lambda = NAN;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, em_ridge_ratio(&p, 1u, 2u, &r));
    p = pair(3.0, 0.5, 1.0);
    p.shape[1][0] = -1.0; /* not SPD */
    TEST_ASSERT_EQUAL_INT(MD_E_NUMERIC, em_ridge_ratio(&p, 1u, 2u, &r));
    TEST_ASSERT_EQUAL_INT(MD_E_NUMERIC, em_params_oversplit(&p, 0.99, &split));
    TEST_ASSERT_FALSE(split);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_ratio_matches_the_mixture_density);
    RUN_TEST(test_a_component_inside_another_is_one_mode);
    RUN_TEST(test_oversplit_needs_one_unimodal_pair);
    RUN_TEST(test_bad_inputs);
    return UNITY_END();
}
