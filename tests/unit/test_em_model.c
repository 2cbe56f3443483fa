/* Unit: em_model — outlier density (Remark 3.2), mean prior and ζ (eq. 3.8,
 * 3.9, 3.14) against direct formulas; bounding volume; sort. */
#include <math.h>
#include <string.h>

#include "cluster/em_model.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static const double PI = 3.14159265358979323846;

static void test_outlier_density(void)
{
    const double xi[4] = {0.5, 0.1, 0.1, 0.25};
    em_outlier_t o;
    TEST_ASSERT_EQUAL_INT(MD_OK, em_outlier_init(2u, xi, 80.0, &o));
    const double y[2] = {1.0, -0.5};
    /* K Ξ = [[2, .4], [.4, 1]], det = 1.84, inverse = [[1, -.4], [-.4, 2]] / 1.84 */
    const double m2 = (1.0 * 1.0 + 2.0 * 0.4 * 0.5 + 2.0 * 0.25) / 1.84;
    const double gauss = exp(-0.5 * m2) / (2.0 * PI * sqrt(1.84));
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, log(0.5 * (gauss + 1.0 / 80.0)), em_outlier_logpdf(&o, y));
    const double bad[4] = {0.5, 0.6, 0.6, 0.5};
    TEST_ASSERT_EQUAL_INT(MD_E_NUMERIC, em_outlier_init(2u, bad, 80.0, &o));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, em_outlier_init(2u, xi, 0.0, &o));
}

static void test_mean_prior_and_zeta(void)
{
    em_prior_t p;
    double zeta[EM_J_MAX + 1u];
    const double mu[2] = {1.0, 2.0};
    TEST_ASSERT_EQUAL_INT(MD_OK, em_prior_init(2u, NULL, 0u, 0.025, 50.0, &p));
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, -log(50.0), em_prior_log_mean(&p, mu, zeta)); /* uniform */
    TEST_ASSERT_DOUBLE_WITHIN(1e-15, 1.0, zeta[0]);
    em_target_t t[2];
    memset(t, 0, sizeof t);
    t[0].mean[0] = 1.5;
    t[0].mean[1] = 2.0;
    t[0].s_cov[0] = 0.25;
    t[0].s_cov[3] = 1.0;
    t[0].p_detect = 0.9;
    t[1].mean[0] = -3.0;
    t[1].s_cov[0] = t[1].s_cov[3] = 2.0;
    t[1].p_detect = 0.75;
    TEST_ASSERT_EQUAL_INT(MD_OK, em_prior_init(2u, t, 2u, 0.025, 50.0, &p));
    const double c = 0.025 + 0.9 + 0.75; /* eq. 3.9 */
    const double f1 = exp(-0.5 * (0.25 / 0.25)) / (2.0 * PI * 0.5);
    const double f2 = exp(-0.5 * (16.0 + 4.0) / 2.0) / (2.0 * PI * 2.0);
    const double total = 0.025 / c / 50.0 + 0.9 / c * f1 + 0.75 / c * f2; /* eq. 3.8 */
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, log(total), em_prior_log_mean(&p, mu, zeta));
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 0.9 / c * f1 / total, zeta[1]); /* eq. 3.14 */
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 1.0, zeta[0] + zeta[1] + zeta[2]);
    t[1].p_detect = 1.5;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, em_prior_init(2u, t, 2u, 0.025, 50.0, &p));
}

/* A density evaluated on a model em_*_init() did not prepare (order 0) is NaN,
 * which fails the fit, never a distance of 0 (a perfect match). */
static void test_unprepared_model_is_not_a_match(void)
{
    em_outlier_t o;
    memset(&o, 0, sizeof o);
    const double y[2] = {1.0, -0.5};
    TEST_ASSERT_TRUE(isnan(em_outlier_logpdf(&o, y)));
    const double xi[4] = {0.5, 0.1, 0.1, 0.25};
    TEST_ASSERT_EQUAL_INT(MD_OK, em_outlier_init(2u, xi, 80.0, &o));
    const double nan_y[2] = {NAN, 0.0};
    TEST_ASSERT_TRUE(isnan(em_outlier_logpdf(&o, nan_y)));
    em_prior_t p;
    em_target_t t;
    memset(&t, 0, sizeof t);
    t.s_cov[0] = t.s_cov[3] = 1.0;
    t.p_detect = 0.9;
    TEST_ASSERT_EQUAL_INT(MD_OK, em_prior_init(2u, &t, 1u, 0.025, 50.0, &p));
    double zeta[EM_J_MAX + 1u];
    const double mu[2] = {0.0, 0.0};
    TEST_ASSERT_TRUE(isfinite(em_prior_log_mean(&p, mu, zeta)));
    memset(p.s_chol[0], 0, sizeof p.s_chol[0]); /* not a Cholesky factor */
    TEST_ASSERT_TRUE(isnan(em_prior_log_mean(&p, mu, zeta)));
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.0, zeta[0] + zeta[1]);
}

static void test_volume_and_sort(void)
{
    const double y[6] = {0.0, 1.0, 2.0, -1.0, 1.0, 3.0};
    const em_data_t d = {y, 3u, 2u};
    double v = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_OK, em_bounding_volume(&d, &v));
    TEST_ASSERT_DOUBLE_WITHIN(1e-15, 8.0, v);
    const double flat[4] = {0.0, 1.0, 2.0, 1.0};
    const em_data_t df = {flat, 2u, 2u};
    TEST_ASSERT_EQUAL_INT(MD_E_DEGENERATE, em_bounding_volume(&df, &v));
    double key[7] = {3.0, -1.0, 2.0, 2.0, 9.0, 0.0, -5.0};
    uint16_t idx[7] = {0u, 1u, 2u, 3u, 4u, 5u, 6u};
    em_sort_keys(key, idx, 7u);
    for (size_t i = 1u; i < 7u; ++i) {
        TEST_ASSERT_TRUE(key[i - 1u] <= key[i]);
    }
    TEST_ASSERT_EQUAL_UINT(6u, idx[0]);
    TEST_ASSERT_EQUAL_UINT(4u, idx[6]);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, log(3.0), em_logaddexp(log(1.0), log(2.0)));
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 1000.0, em_logaddexp(1000.0, -1000.0));
    TEST_ASSERT_EQUAL_STRING("EM_FAIL_HESSIAN", em_reason_name(EM_FAIL_HESSIAN));
}

/* The tabulated outlier density equals the direct one for the tabulated
 * points, and is not used for other data. */
static void test_outlier_table(void)
{
    const double xi[4] = {0.5, 0.1, 0.1, 0.25};
    const double y[6] = {1.0, -0.5, 0.0, 0.0, 3.0, 2.0};
    const double y2[6] = {2.0, -1.5, 1.0, 0.0, 0.0, 2.0};
    em_outlier_t o;
    TEST_ASSERT_EQUAL_INT(MD_OK, em_outlier_init(2u, xi, 80.0, &o));
    const em_data_t d = {y, 3u, 2u};
    const em_data_t d2 = {y2, 3u, 2u};
    TEST_ASSERT_EQUAL_INT(MD_OK, em_outlier_tabulate(&o, &d));
    for (size_t i = 0u; i < 3u; ++i) {
        TEST_ASSERT_DOUBLE_WITHIN(0.0, em_outlier_logpdf(&o, &y[2u * i]), em_outlier_logpdf_at(&o, &d, i));
        TEST_ASSERT_DOUBLE_WITHIN(0.0, em_outlier_logpdf(&o, &y2[2u * i]), em_outlier_logpdf_at(&o, &d2, i));
    }
    const em_data_t d1 = {y, 3u, 1u};
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, em_outlier_tabulate(&o, &d1));
    TEST_ASSERT_NULL(o.tab_y);
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, em_outlier_tabulate(&o, NULL));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_outlier_density);
    RUN_TEST(test_mean_prior_and_zeta);
    RUN_TEST(test_unprepared_model_is_not_a_match);
    RUN_TEST(test_volume_and_sort);
    RUN_TEST(test_outlier_table);
    return UNITY_END();
}
