/// @file test_kalman.c
/// The low-rank waveform-space Kalman filter against a dense textbook filter
/// (eq. 4.7-4.9, 4.13, 4.15-4.17): exact below the rank bound, conservative above.
#include <math.h>
#include <stdbool.h>
#include <string.h>

#include "numeric/linalg.h"
#include "numeric/md_rng.h"
#include "tracking/kalman.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

#define DW 23u
#define D 2u

static kf_work_t g_ws;
static double g_lam[DW * DW]; /* dense reference Λ */
static double g_x[DW];        /* dense reference x̂ */
static double g_low[DW * DW];

/* d × d_w with orthonormal rows, like a PCA basis. */
static void random_basis(md_rng_t *rng, double *h)
{
    for (size_t c = 0u; c < D; ++c) {
        for (size_t i = 0u; i < DW; ++i) {
            h[c * DW + i] = md_rng_gauss(rng);
        }
        for (size_t c2 = 0u; c2 < c; ++c2) {
            double s = 0.0;
            for (size_t i = 0u; i < DW; ++i) {
                s += h[c * DW + i] * h[c2 * DW + i];
            }
            for (size_t i = 0u; i < DW; ++i) {
                h[c * DW + i] -= s * h[c2 * DW + i];
            }
        }
        double n = 0.0;
        for (size_t i = 0u; i < DW; ++i) {
            n += h[c * DW + i] * h[c * DW + i];
        }
        for (size_t i = 0u; i < DW; ++i) {
            h[c * DW + i] /= sqrt(n);
        }
    }
}

/* Dense eq. 4.15-4.17. */
static void dense_update(const double *h, const double *mu, const double *r)
{
    static double p[DW * D], k[DW * D], lam2[DW * DW];
    double s[D * D], sinv[D * D], work[D * D];
    for (size_t i = 0u; i < DW; ++i) {
        for (size_t c = 0u; c < D; ++c) {
            double acc = 0.0;
            for (size_t j = 0u; j < DW; ++j) {
                acc += g_lam[i * DW + j] * h[c * DW + j];
            }
            p[i * D + c] = acc;
        }
    }
    for (size_t c = 0u; c < D; ++c) {
        for (size_t c2 = 0u; c2 < D; ++c2) {
            double acc = r[c * D + c2];
            for (size_t i = 0u; i < DW; ++i) {
                acc += h[c * DW + i] * p[i * D + c2];
            }
            s[c * D + c2] = acc;
        }
    }
    TEST_ASSERT_EQUAL_INT(MD_OK, linalg_spd_inverse(s, D, sinv, work, NULL));
    TEST_ASSERT_EQUAL_INT(MD_OK, linalg_matmul(p, sinv, k, DW, D, D));
    double nu[D];
    for (size_t c = 0u; c < D; ++c) {
        double acc = mu[c];
        for (size_t i = 0u; i < DW; ++i) {
            acc -= h[c * DW + i] * g_x[i];
        }
        nu[c] = acc;
    }
    for (size_t i = 0u; i < DW; ++i) {
        g_x[i] += k[i * D] * nu[0] + k[i * D + 1u] * nu[1];
    }
    for (size_t i = 0u; i < DW; ++i) {
        for (size_t j = 0u; j < DW; ++j) {
            double acc = 0.0;
            for (size_t c = 0u; c < D; ++c) {
                acc += k[i * D + c] * p[j * D + c];
            }
            lam2[i * DW + j] = g_lam[i * DW + j] - acc;
        }
    }
    memcpy(g_lam, lam2, sizeof lam2);
}

static void dense_init(const double *x0, double a0, const double *h, const double *r)
{
    memcpy(g_x, x0, sizeof g_x);
    for (size_t i = 0u; i < DW; ++i) {
        for (size_t j = 0u; j < DW; ++j) {
            double acc = (i == j) ? a0 : 0.0;
            for (size_t c = 0u; c < D; ++c) {
                for (size_t c2 = 0u; c2 < D; ++c2) {
                    acc += h[c * DW + i] * (r[c * D + c2] - ((c == c2) ? a0 : 0.0)) * h[c2 * DW + j];
                }
            }
            g_lam[i * DW + j] = acc;
        }
    }
}

static double max_abs_diff(const double *a, const double *b, size_t n)
{
    double m = 0.0;
    for (size_t i = 0u; i < n; ++i) {
        m = fmax(m, fabs(a[i] - b[i]));
    }
    return m;
}

/* Drives both filters through `steps` predict+update cycles. */
static void run_both(kf_state_t *st, md_rng_t *rng, size_t steps, double q, bool check_exact)
{
    double h[D * DW], mu[D], r[D * D] = {0.5, 0.1, 0.1, 0.3};
    for (size_t k = 0u; k < steps; ++k) {
        random_basis(rng, h);
        TEST_ASSERT_EQUAL_INT(MD_OK, kf_predict(st, q));
        for (size_t i = 0u; i < DW; ++i) {
            g_lam[i * DW + i] += q;
        }
        double mu_pred[D], hlh[D * D];
        TEST_ASSERT_EQUAL_INT(MD_OK, kf_measure(st, h, D, mu_pred, hlh));
        for (size_t c = 0u; c < D; ++c) {
            mu[c] = mu_pred[c] + md_rng_gauss(rng);
        }
        TEST_ASSERT_EQUAL_INT(MD_OK, kf_update(st, h, D, mu, r, &g_ws));
        dense_update(h, mu, r);
        if (check_exact) {
            kf_covariance(st, g_low);
            TEST_ASSERT_DOUBLE_WITHIN(1e-5, 0.0, max_abs_diff(g_low, g_lam, DW * DW));
            TEST_ASSERT_DOUBLE_WITHIN(1e-5, 0.0, max_abs_diff(st->x, g_x, DW));
        }
    }
}

static void init_both(kf_state_t *st, md_rng_t *rng, double a0)
{
    double x0[DW], h[D * DW], r[D * D] = {0.4, 0.05, 0.05, 0.2};
    for (size_t i = 0u; i < DW; ++i) {
        x0[i] = 10.0 * md_rng_gauss(rng);
    }
    random_basis(rng, h);
    TEST_ASSERT_EQUAL_INT(MD_OK, kf_init(st, DW, x0, a0, h, D, r, &g_ws));
    dense_init(x0, a0, h, r);
}

static void test_exact_below_rank_bound(void)
{
    md_rng_t rng;
    md_rng_seed(&rng, 7u);
    kf_state_t st;
    init_both(&st, &rng, 2.0);
    kf_covariance(&st, g_low);
    TEST_ASSERT_DOUBLE_WITHIN(1e-6, 0.0, max_abs_diff(g_low, g_lam, DW * DW));
    /* init uses 2 directions, each update adds at most D: 3 updates stay within KF_RANK_MAX = 8 */
    run_both(&st, &rng, (KF_RANK_MAX - D) / D, 0.25, true);
}

static void test_conservative_above_rank_bound(void)
{
    md_rng_t rng;
    md_rng_seed(&rng, 11u);
    kf_state_t st;
    init_both(&st, &rng, 2.0);
    run_both(&st, &rng, 20u, 0.25, false);
    TEST_ASSERT_LESS_OR_EQUAL_UINT(KF_RANK_MAX, st.rank);
    /* Λ_lowrank - Λ_dense must be positive semidefinite (over-estimate only). */
    static double diff[DW * DW], vecs[DW * DW];
    double vals[DW];
    kf_covariance(&st, g_low);
    for (size_t i = 0u; i < DW * DW; ++i) {
        diff[i] = g_low[i] - g_lam[i];
    }
    TEST_ASSERT_EQUAL_INT(MD_OK, linalg_sym_eigen(diff, DW, vals, vecs, 60u));
    TEST_ASSERT_GREATER_OR_EQUAL_DOUBLE(-1e-5, vals[DW - 1u]);
    /* the state estimate stays close to the exact one (information lost is old) */
    TEST_ASSERT_LESS_THAN_DOUBLE(1.0, max_abs_diff(st.x, g_x, DW));
}

/* A move scales the whole waveform by an uncertain factor: Q = qI + s2 x̂x̂ᵀ,
 * exact against the dense filter below the rank bound, and the update then
 * follows a scaled measurement along x̂ much further than with Q = qI. */
/* An orthonormal D x DW basis whose first row is x's direction, and the
 * measurement of scale * x through it. Returns |x|. */
static double basis_along(const double *x, double scale, double *h, double *mu)
{
    double nx = 0.0;
    for (size_t i = 0u; i < DW; ++i) {
        nx += x[i] * x[i];
    }
    memset(h, 0, D * DW * sizeof h[0]);
    for (size_t i = 0u; i < DW; ++i) {
        h[i] = x[i] / sqrt(nx);
    }
    h[DW + ((fabs(h[0]) < 0.5) ? 0u : 1u)] = 1.0; /* any second unit row */
    double dot = 0.0;
    for (size_t i = 0u; i < DW; ++i) {
        dot += h[i] * h[DW + i];
    }
    double n2 = 0.0;
    for (size_t i = 0u; i < DW; ++i) {
        h[DW + i] -= dot * h[i];
        n2 += h[DW + i] * h[DW + i];
    }
    double m1 = 0.0;
    for (size_t i = 0u; i < DW; ++i) {
        h[DW + i] /= sqrt(n2);
        m1 += h[DW + i] * x[i];
    }
    mu[0] = scale * sqrt(nx);
    mu[1] = scale * m1;
    return sqrt(nx);
}

/* The state both scaled-prediction tests start from (and the dense twin). */
static void scaled_setup(kf_state_t *st, md_rng_t *rng)
{
    md_rng_seed(rng, 13u);
    init_both(st, rng, 2.0);
}

static void test_scaled_prediction(void)
{
    md_rng_t rng;
    kf_state_t st;
    scaled_setup(&st, &rng);
    const double q = 0.25, s2 = 0.09;
    double xk[DW];
    memcpy(xk, st.x, sizeof xk);
    TEST_ASSERT_EQUAL_INT(MD_OK, kf_predict_scaled(&st, q, s2, &g_ws));
    for (size_t i = 0u; i < DW; ++i) {
        for (size_t j = 0u; j < DW; ++j) {
            g_lam[i * DW + j] += ((i == j) ? q : 0.0) + s2 * xk[i] * xk[j];
        }
    }
    kf_covariance(&st, g_low);
    TEST_ASSERT_DOUBLE_WITHIN(1e-4, 0.0, max_abs_diff(g_low, g_lam, DW * DW));
    TEST_ASSERT_EQUAL_MEMORY(xk, st.x, sizeof xk); /* x̂ unchanged (F = I) */
    /* a measurement of 1.3 x̂ through a basis containing x̂'s direction */
    double h[D * DW], mu[D], r[D * D] = {0.5, 0.0, 0.0, 0.5};
    const double nx = basis_along(xk, 1.3, h, mu);
    TEST_ASSERT_EQUAL_INT(MD_OK, kf_update(&st, h, D, mu, r, &g_ws));
    dense_update(h, mu, r);
    TEST_ASSERT_DOUBLE_WITHIN(1e-4, 0.0, max_abs_diff(st.x, g_x, DW));
    /* the same update after Q = qI only moves less along x̂ */
    kf_state_t iso;
    init_both(&iso, &rng, 2.0);
    memcpy(iso.x, xk, sizeof xk);
    TEST_ASSERT_EQUAL_INT(MD_OK, kf_predict(&iso, q));
    TEST_ASSERT_EQUAL_INT(MD_OK, kf_update(&iso, h, D, mu, r, &g_ws));
    double along = 0.0, along_iso = 0.0;
    for (size_t i = 0u; i < DW; ++i) {
        along += h[i] * st.x[i];
        along_iso += h[i] * iso.x[i];
    }
    TEST_ASSERT_GREATER_THAN_DOUBLE(0.95 * (mu[0] - nx), along - nx);
    TEST_ASSERT_LESS_THAN_DOUBLE(along - nx, along_iso - nx);
}

/* s2 = 0 is kf_predict; bad arguments are refused. */
static void test_scaled_prediction_arguments(void)
{
    md_rng_t rng;
    kf_state_t st;
    scaled_setup(&st, &rng);
    const double q = 0.25, s2 = 0.09;
    const double a_before = st.a;
    TEST_ASSERT_EQUAL_INT(MD_OK, kf_predict_scaled(&st, q, 0.0, &g_ws));
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, a_before + q, st.a);
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, kf_predict_scaled(&st, q, -1.0, &g_ws));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, kf_predict_scaled(&st, q, NAN, &g_ws));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, kf_predict_scaled(&st, -1.0, s2, &g_ws));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, kf_predict_scaled(&st, q, s2, NULL));
}

static void test_predict_measure(void)
{
    kf_state_t st;
    double x0[DW] = {0}, h[D * DW] = {0}, mu[D], hlh[D * D];
    x0[3] = 5.0;
    h[3] = 1.0;
    h[DW + 4u] = 1.0;
    TEST_ASSERT_EQUAL_INT(MD_OK, kf_init(&st, DW, x0, 1.0, NULL, 0u, NULL, &g_ws));
    TEST_ASSERT_EQUAL_INT(MD_OK, kf_predict(&st, 0.5));
    TEST_ASSERT_EQUAL_INT(MD_OK, kf_measure(&st, h, D, mu, hlh));
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 5.0, mu[0]);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 0.0, mu[1]);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 1.5, hlh[0]);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 0.0, hlh[1]);
}

static void test_rejects_bad_input(void)
{
    kf_state_t st;
    double x0[DW] = {0}, h[D * DW] = {0}, mu[D] = {NAN, 0.0}, r[D * D] = {1, 0, 0, 1};
    h[0] = 1.0;
    h[DW + 1u] = 1.0;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, kf_init(&st, DW, x0, 0.0, NULL, 0u, NULL, &g_ws));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, kf_init(&st, KF_DW_MAX + 1u, x0, 1.0, NULL, 0u, NULL, &g_ws));
    TEST_ASSERT_EQUAL_INT(MD_OK, kf_init(&st, DW, x0, 1.0, NULL, 0u, NULL, &g_ws));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, kf_predict(&st, -1.0));
    TEST_ASSERT_EQUAL_INT(MD_E_NUMERIC, kf_update(&st, h, D, mu, r, &g_ws));
    double r_bad[D * D] = {-1, 0, 0, -1};
    mu[0] = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_E_NUMERIC, kf_update(&st, h, D, mu, r_bad, &g_ws));
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 1.0, st.a); /* unchanged on failure */
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_exact_below_rank_bound);
    RUN_TEST(test_conservative_above_rank_bound);
    RUN_TEST(test_scaled_prediction);
    RUN_TEST(test_scaled_prediction_arguments);
    RUN_TEST(test_predict_measure);
    RUN_TEST(test_rejects_bad_input);
    return UNITY_END();
}
