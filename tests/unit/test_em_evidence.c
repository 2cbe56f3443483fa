/* Unit: em_evidence — analytic gradient/Hessian of the log-posterior (thesis
 * App. B) against finite differences at random parameter points, for d = 1, 2, 3;
 * Θ packing round trip; Laplace evidence and BIC bookkeeping. */
#include <math.h>
#include <string.h>

#include "cluster/em.h"
#include "cluster/em_evidence.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static uint64_t rng_state;

static uint64_t splitmix64(void)
{
    uint64_t z = (rng_state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

static double uniform01(void)
{
    return ((double)(splitmix64() >> 11) + 0.5) * (1.0 / 9007199254740992.0);
}

static double gauss(void)
{
    return sqrt(-2.0 * log(uniform01())) * cos(6.283185307179586 * uniform01());
}

#define N_PTS 60u
static double pts[N_PTS * EM_D_MAX];
static em_evidence_work_t ws;
static double hess[EM_ETA_MAX * EM_ETA_MAX];
static double hess_fd[EM_ETA_MAX * EM_ETA_MAX];

typedef struct {
    em_data_t data;
    em_outlier_t outlier;
    em_prior_t prior;
    em_params_t params;
} fixture_t;

/* Random data, random (valid, non-stationary) parameters and a 2-target prior. */
static void make_fixture(size_t d, size_t g, uint64_t seed, fixture_t *f)
{
    rng_state = seed;
    for (size_t i = 0u; i < N_PTS * d; ++i) {
        pts[i] = 2.0 * gauss() + ((i / d) % 2u == 0u ? 3.0 : -2.0);
    }
    f->data = (em_data_t){pts, N_PTS, d};
    double vol = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_OK, em_bounding_volume(&f->data, &vol));
    double xi[EM_D_MAX * EM_D_MAX] = {0.0};
    for (size_t j = 0u; j < d; ++j) {
        xi[j * d + j] = 0.5 + 0.1 * (double)j;
    }
    TEST_ASSERT_EQUAL_INT(MD_OK, em_outlier_init(d, xi, vol, &f->outlier));
    em_target_t tg[2];
    memset(tg, 0, sizeof tg);
    for (size_t j = 0u; j < 2u; ++j) {
        for (size_t k = 0u; k < d; ++k) {
            tg[j].mean[k] = gauss() * 2.0;
            tg[j].s_cov[k * d + k] = 1.0 + uniform01();
        }
        if (d > 1u) {
            tg[j].s_cov[1] = tg[j].s_cov[d] = 0.3;
        }
        tg[j].p_detect = 0.8;
    }
    TEST_ASSERT_EQUAL_INT(MD_OK, em_prior_init(d, tg, 2u, 0.025, vol, &f->prior));
    double theta[EM_ETA_MAX];
    size_t k = 0u;
    for (size_t c = 0u; c < g; ++c) {
        theta[k++] = 0.8 / (double)g * (0.7 + 0.6 * uniform01());
        for (size_t j = 0u; j < d; ++j) {
            theta[k++] = 3.0 * gauss();
        }
        const double free_d2[] = {0.6 + uniform01(), 0.4 * gauss()};
        const double free_d3[] = {0.8 + 0.5 * uniform01(), 0.2 * gauss(), 0.2 * gauss(), 0.8 + 0.5 * uniform01(),
                                  0.2 * gauss()};
        for (size_t t = 0u; t < (d * (d + 1u)) / 2u - 1u; ++t) {
            theta[k++] = (d == 2u) ? free_d2[t] : free_d3[t];
        }
    }
    theta[k] = 1.5 + uniform01();
    TEST_ASSERT_EQUAL_INT(MD_OK, em_theta_unpack(theta, d, g, &f->params));
}

static double log_post_at(const fixture_t *f, const double *theta, double *grad)
{
    em_params_t p;
    double lp = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_OK, em_theta_unpack(theta, f->params.d, f->params.g, &p));
    TEST_ASSERT_EQUAL_INT(MD_OK, em_log_post_derivs(&f->data, &f->outlier, &f->prior, &p, &lp, grad, NULL, &ws));
    return lp;
}

/* Central differences of the log-posterior (gradient) and of the analytic
 * gradient (Hessian); they agree to 1e-6 (gradient) and 1e-5 (Hessian) relative. */
static void check_derivatives(size_t d, size_t g, uint64_t seed)
{
    fixture_t f;
    make_fixture(d, g, seed, &f);
    const size_t eta = em_param_count(d, g);
    double theta[EM_ETA_MAX];
    double grad[EM_ETA_MAX];
    double lp = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_OK, em_theta_pack(&f.params, theta));
    TEST_ASSERT_EQUAL_INT(MD_OK, em_log_post_derivs(&f.data, &f.outlier, &f.prior, &f.params, &lp, grad, hess, &ws));
    double max_rel_g = 0.0;
    double max_rel_h = 0.0;
    for (size_t k = 0u; k < eta; ++k) {
        const double h = 1e-5 * fmax(0.1, fabs(theta[k]));
        double tp[EM_ETA_MAX];
        double tm[EM_ETA_MAX];
        double gp[EM_ETA_MAX];
        double gm[EM_ETA_MAX];
        memcpy(tp, theta, sizeof tp);
        memcpy(tm, theta, sizeof tm);
        tp[k] += h;
        tm[k] -= h;
        const double fd_g = (log_post_at(&f, tp, gp) - log_post_at(&f, tm, gm)) / (2.0 * h);
        max_rel_g = fmax(max_rel_g, fabs(fd_g - grad[k]) / fmax(1.0, fabs(grad[k])));
        for (size_t c = 0u; c < eta; ++c) {
            hess_fd[k * eta + c] = (gp[c] - gm[c]) / (2.0 * h);
        }
    }
    for (size_t r = 0u; r < eta; ++r) {
        for (size_t c = 0u; c < eta; ++c) {
            const double scale = fmax(fabs(hess[r * eta + c]),
                                      1e-3 * sqrt(fabs(hess[r * eta + r] * hess[c * eta + c])));
            max_rel_h = fmax(max_rel_h, fabs(hess_fd[r * eta + c] - hess[r * eta + c]) / scale);
        }
    }
    TEST_ASSERT_LESS_THAN_DOUBLE(1e-6, max_rel_g);
    TEST_ASSERT_LESS_THAN_DOUBLE(1e-5, max_rel_h);
}

static void test_hessian_matches_fd_2d(void)
{
    check_derivatives(2u, 1u, 11u);
    check_derivatives(2u, 2u, 12u);
    check_derivatives(2u, 3u, 13u);
    check_derivatives(2u, 4u, 14u);
}

static void test_hessian_matches_fd_1d_3d(void)
{
    check_derivatives(1u, 2u, 21u);
    check_derivatives(3u, 1u, 31u);
    check_derivatives(3u, 3u, 32u);
}

/* The analytic Hessian diagonal also matches a second difference of the
 * log-posterior itself (no analytic gradient in the loop). */
static void test_hessian_diagonal_matches_second_difference(void)
{
    fixture_t f;
    make_fixture(2u, 3u, 41u, &f);
    const size_t eta = em_param_count(2u, 3u);
    double theta[EM_ETA_MAX];
    double lp0 = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_OK, em_theta_pack(&f.params, theta));
    TEST_ASSERT_EQUAL_INT(MD_OK, em_log_post_derivs(&f.data, &f.outlier, &f.prior, &f.params, &lp0, NULL, hess, &ws));
    for (size_t k = 0u; k < eta; ++k) {
        const double h = 1e-3 * fmax(0.1, fabs(theta[k]));
        double f_pm[4];
        const double steps[4] = {2.0 * h, h, -h, -2.0 * h};
        for (size_t s = 0u; s < 4u; ++s) {
            double t[EM_ETA_MAX];
            memcpy(t, theta, sizeof t);
            t[k] += steps[s];
            f_pm[s] = log_post_at(&f, t, NULL);
        }
        /* fourth-order stencil */
        const double d2 = (-f_pm[0] + 16.0 * f_pm[1] - 30.0 * lp0 + 16.0 * f_pm[2] - f_pm[3]) / (12.0 * h * h);
        TEST_ASSERT_DOUBLE_WITHIN(1e-5 * fabs(hess[k * eta + k]), hess[k * eta + k], d2);
    }
}

static void test_theta_round_trip_and_constraint(void)
{
    fixture_t f;
    make_fixture(3u, 2u, 51u, &f);
    double theta[EM_ETA_MAX];
    em_params_t back;
    TEST_ASSERT_EQUAL_UINT(19u, em_param_count(3u, 2u));
    TEST_ASSERT_EQUAL_UINT(21u, em_param_count(2u, 4u));
    TEST_ASSERT_EQUAL_INT(MD_OK, em_theta_pack(&f.params, theta));
    TEST_ASSERT_EQUAL_INT(MD_OK, em_theta_unpack(theta, 3u, 2u, &back));
    for (size_t g = 0u; g < 2u; ++g) {
        const double *c = back.shape[g];
        const double det = c[0] * (c[4] * c[8] - c[5] * c[7]) - c[1] * (c[3] * c[8] - c[5] * c[6]) +
                           c[2] * (c[3] * c[7] - c[4] * c[6]);
        TEST_ASSERT_DOUBLE_WITHIN(1e-12, 1.0, det);
        TEST_ASSERT_EQUAL_MEMORY(f.params.shape[g], back.shape[g], sizeof back.shape[g]);
    }
    /* c11 <= 0 makes C indefinite: rejected, not NaN */
    theta[1u + 3u] = -0.5;
    TEST_ASSERT_EQUAL_INT(MD_E_NUMERIC, em_theta_unpack(theta, 3u, 2u, &back));
}

static void test_bic_and_prior_constant(void)
{
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, -100.0 - 0.5 * 11.0 * log(50.0), em_evidence_bic(-100.0, 2u, 2u, 50u));
    /* G = 3, d = 2: log 3! - 3·2·log 10 */
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, log(6.0) - 6.0 * log(10.0), em_param_prior_log_const(2u, 3u, 10.0));
}

/* One data part at a fitted Θ̂, finished under two priors in any order, gives
 * exactly what em_evidence_laplace gives under each (MHTC's reuse of a fit). */
static void test_data_part_serves_several_priors(void)
{
    fixture_t f;
    make_fixture(2u, 2u, 61u, &f);
    uint8_t labels[N_PTS];
    for (size_t i = 0u; i < N_PTS; ++i) {
        labels[i] = (uint8_t)(i % 2u);
    }
    static double z[N_PTS * 3u];
    em_options_t opt;
    em_options_default(&opt);
    em_fit_t fit;
    TEST_ASSERT_EQUAL_INT(MD_OK, em_fit(&f.data, &f.outlier, &f.prior, labels, 2u, &opt, z, &fit));
    em_prior_t other;
    em_target_t tg;
    memset(&tg, 0, sizeof tg);
    tg.mean[0] = fit.params.mean[0][0] + 0.5;
    tg.mean[1] = fit.params.mean[0][1];
    tg.s_cov[0] = tg.s_cov[3] = 0.4;
    tg.p_detect = 0.9;
    double vol = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_OK, em_bounding_volume(&f.data, &vol));
    TEST_ASSERT_EQUAL_INT(MD_OK, em_prior_init(2u, &tg, 1u, 0.025, vol, &other));
    double ev_a = 0.0;
    double ev_b = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_OK, em_evidence_laplace(&f.data, &f.outlier, &f.prior, &fit.params, 10.0, &ws, &ev_a));
    TEST_ASSERT_EQUAL_INT(MD_OK, em_evidence_laplace(&f.data, &f.outlier, &other, &fit.params, 10.0, &ws, &ev_b));
    TEST_ASSERT_TRUE(fabs(ev_a - ev_b) > 1e-3); /* the priors matter */
    double e = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_OK, em_evidence_data(&f.data, &f.outlier, &fit.params, &ws));
    TEST_ASSERT_EQUAL_INT(MD_OK, em_evidence_finish(&other, &fit.params, 10.0, &ws, &e));
    TEST_ASSERT_EQUAL_MEMORY(&ev_b, &e, sizeof e); /* bit for bit */
    TEST_ASSERT_EQUAL_INT(MD_OK, em_evidence_finish(&f.prior, &fit.params, 10.0, &ws, &e));
    TEST_ASSERT_EQUAL_MEMORY(&ev_a, &e, sizeof e);
    TEST_ASSERT_EQUAL_INT(MD_OK, em_evidence_finish(&other, &fit.params, 10.0, &ws, &e));
    TEST_ASSERT_EQUAL_MEMORY(&ev_b, &e, sizeof e); /* bit for bit */
    em_params_t wrong = fit.params;
    wrong.g = 1u;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, em_evidence_finish(&other, &wrong, 10.0, &ws, &e));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, em_evidence_finish(&other, &fit.params, 0.0, &ws, &e));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_hessian_matches_fd_2d);
    RUN_TEST(test_hessian_matches_fd_1d_3d);
    RUN_TEST(test_hessian_diagonal_matches_second_difference);
    RUN_TEST(test_theta_round_trip_and_constraint);
    RUN_TEST(test_bic_and_prior_constant);
    RUN_TEST(test_data_part_serves_several_priors);
    return UNITY_END();
}
