/* Unit: em — MAP-EM of thesis §3.3.3 on synthetic mixtures with known answers:
 * recovery of means/weights/volume, the fixed point is a stationary point of
 * the log-posterior, eq. 3.15 holds at convergence, degenerate inputs. */
#include <float.h>
#include <math.h>
#include <string.h>

#include "cluster/em.h"
#include "cluster/em_evidence.h"
#include "numeric/md_rng.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

#define N_MAX 320u
static double pts[N_MAX * 2u];
static uint8_t seed[N_MAX];
static double z[N_MAX * (EM_G_MAX + 1u)];
static em_evidence_work_t ews;
static const double xi[4] = {0.25, 0.0, 0.0, 0.25};

typedef struct {
    em_data_t data;
    em_outlier_t outlier;
    em_prior_t prior;
} setup_t;

/* 150 points at (-4, 3) with sd (1, 0.5), 100 at (4, 5) with sd (0.5, 1),
 * 20 uniform outliers in [-15, 15]^2; seed = true component (outliers → 0). */
static size_t make_two(uint64_t s)
{
    md_rng_t rng;
    md_rng_seed(&rng, s);
    size_t k = 0u;
    for (; k < 150u; ++k) {
        pts[2u * k] = -4.0 + md_rng_gauss(&rng);
        pts[2u * k + 1u] = 3.0 + 0.5 * md_rng_gauss(&rng);
        seed[k] = 0u;
    }
    for (; k < 250u; ++k) {
        pts[2u * k] = 4.0 + 0.5 * md_rng_gauss(&rng);
        pts[2u * k + 1u] = 5.0 + md_rng_gauss(&rng);
        seed[k] = 1u;
    }
    for (; k < 270u; ++k) {
        pts[2u * k] = -15.0 + 30.0 * md_rng_uniform(&rng);
        pts[2u * k + 1u] = -15.0 + 30.0 * md_rng_uniform(&rng);
        seed[k] = (uint8_t)(k % 2u);
    }
    return k;
}

static void prepare(size_t n, const em_target_t *tg, size_t n_tg, setup_t *s)
{
    double v = 0.0;
    s->data = (em_data_t){pts, n, 2u};
    TEST_ASSERT_EQUAL_INT(MD_OK, em_bounding_volume(&s->data, &v));
    TEST_ASSERT_EQUAL_INT(MD_OK, em_outlier_init(2u, xi, v, &s->outlier));
    TEST_ASSERT_EQUAL_INT(MD_OK, em_prior_init(2u, tg, n_tg, 0.025, v, &s->prior));
}

static void test_recovers_two_clusters(void)
{
    setup_t s;
    em_options_t opt;
    em_fit_t fit;
    prepare(make_two(1u), NULL, 0u, &s);
    em_options_default(&opt);
    TEST_ASSERT_EQUAL_INT(MD_OK, em_fit(&s.data, &s.outlier, &s.prior, seed, 2u, &opt, z, &fit));
    const em_params_t *p = &fit.params;
    TEST_ASSERT_DOUBLE_WITHIN(0.2, -4.0, p->mean[0][0]);
    TEST_ASSERT_DOUBLE_WITHIN(0.1, 3.0, p->mean[0][1]);
    TEST_ASSERT_DOUBLE_WITHIN(0.1, 4.0, p->mean[1][0]);
    TEST_ASSERT_DOUBLE_WITHIN(0.2, 5.0, p->mean[1][1]);
    TEST_ASSERT_DOUBLE_WITHIN(0.04, 150.0 / 270.0, p->pi[0]);
    TEST_ASSERT_DOUBLE_WITHIN(0.04, 100.0 / 270.0, p->pi[1]);
    TEST_ASSERT_DOUBLE_WITHIN(0.04, 20.0 / 270.0, p->pi0);
    /* both clusters have det Σ = 0.25: λ = 0.5; shapes elongated along x / y */
    TEST_ASSERT_DOUBLE_WITHIN(0.06, 0.5, p->lambda);
    TEST_ASSERT_DOUBLE_WITHIN(0.4, 2.0, p->shape[0][0]);
    TEST_ASSERT_DOUBLE_WITHIN(0.4, 2.0, p->shape[1][3]);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 1.0, p->shape[0][0] * p->shape[0][3] - p->shape[0][1] * p->shape[0][2]);
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 270.0, fit.n_soft[0] + fit.n_soft[1] + fit.n_soft[2]);
    TEST_ASSERT_TRUE(fit.iterations < 100u);
}

/* The M-step fixed point (with λ over Σ_{g≥1} n_g) zeroes the gradient of the
 * log-posterior of em_evidence.h: the Laplace expansion sits at a maximum. */
static void test_fixed_point_is_stationary(void)
{
    setup_t s;
    em_options_t opt;
    em_fit_t fit;
    em_target_t tg;
    memset(&tg, 0, sizeof tg);
    tg.mean[0] = -3.5;
    tg.mean[1] = 3.2;
    tg.s_cov[0] = tg.s_cov[3] = 0.05;
    tg.cluster_cov[0] = tg.cluster_cov[3] = 1.0;
    tg.p_detect = 0.9;
    prepare(make_two(2u), &tg, 1u, &s);
    em_options_default(&opt);
    opt.tol = 1e-13;
    const md_status_t st = em_fit(&s.data, &s.outlier, &s.prior, seed, 2u, &opt, z, &fit);
    TEST_ASSERT_TRUE((st == MD_OK) || (st == MD_E_NOCONVERGE));
    double lp = 0.0;
    double grad[EM_ETA_MAX];
    TEST_ASSERT_EQUAL_INT(MD_OK, em_log_post_derivs(&s.data, &s.outlier, &s.prior, &fit.params, &lp, grad, NULL, &ews));
    TEST_ASSERT_DOUBLE_WITHIN(1e-9 * fabs(lp), fit.log_post, lp);
    for (size_t k = 0u; k < em_param_count(2u, 2u); ++k) {
        TEST_ASSERT_DOUBLE_WITHIN(1e-4, 0.0, grad[k]);
    }
}

/* eq. 3.15 at convergence, G = 1, one tight target: the MAP mean is the
 * precision-weighted average of the data mean and the prior mean. */
static void test_map_mean_obeys_eq_3_15(void)
{
    setup_t s;
    em_options_t opt;
    em_fit_t fit;
    em_target_t tg;
    memset(&tg, 0, sizeof tg);
    tg.mean[0] = -3.7;
    tg.mean[1] = 3.2;
    tg.s_cov[0] = tg.s_cov[3] = 0.04;
    tg.cluster_cov[0] = tg.cluster_cov[3] = 1.0;
    tg.p_detect = 0.9;
    prepare(150u, &tg, 1u, &s); /* the first cluster only */
    memset(seed, 0, sizeof seed);
    em_options_default(&opt);
    opt.tol = 1e-14;
    const md_status_t st = em_fit(&s.data, &s.outlier, &s.prior, seed, 1u, &opt, z, &fit);
    TEST_ASSERT_TRUE((st == MD_OK) || (st == MD_E_NOCONVERGE));
    const em_params_t *p = &fit.params;
    double sy[2] = {0.0, 0.0};
    for (size_t i = 0u; i < 150u; ++i) {
        sy[0] += z[2u * i + 1u] * pts[2u * i];
        sy[1] += z[2u * i + 1u] * pts[2u * i + 1u];
    }
    /* A μ = b with A = n Σ^{-1} + ζ S^{-1}, b = Σ^{-1} Σ z y + ζ S^{-1} m */
    const double *c = p->shape[0];
    const double l = p->lambda;
    const double si[4] = {c[3] / l, -c[1] / l, -c[2] / l, c[0] / l}; /* det C = 1 */
    const double zeta = fit.zeta[0][1];
    const double n1 = fit.n_soft[1];
    const double a[4] = {n1 * si[0] + zeta * 25.0, n1 * si[1], n1 * si[2], n1 * si[3] + zeta * 25.0};
    const double b[2] = {si[0] * sy[0] + si[1] * sy[1] + zeta * 25.0 * tg.mean[0],
                         si[2] * sy[0] + si[3] * sy[1] + zeta * 25.0 * tg.mean[1]};
    const double det = a[0] * a[3] - a[1] * a[2];
    TEST_ASSERT_DOUBLE_WITHIN(1e-6, (a[3] * b[0] - a[1] * b[1]) / det, p->mean[0][0]);
    TEST_ASSERT_DOUBLE_WITHIN(1e-6, (a[0] * b[1] - a[2] * b[0]) / det, p->mean[0][1]);
    /* pulled from the data mean (≈ -4, 3) toward the prior (-3.7, 3.2), which is
     * close enough that ζ gives it the cluster (§3.4) */
    TEST_ASSERT_TRUE(zeta > 0.99);
    TEST_ASSERT_TRUE(p->mean[0][0] > sy[0] / n1 + 0.02);
    TEST_ASSERT_TRUE(p->mean[0][0] < tg.mean[0]);
    TEST_ASSERT_TRUE(p->mean[0][1] > sy[1] / n1 + 0.005); /* y is 4x more precise: smaller pull */
}

static void test_degenerate_and_bad_inputs(void)
{
    setup_t s;
    em_options_t opt;
    em_fit_t fit;
    em_options_default(&opt);
    prepare(make_two(3u), NULL, 0u, &s);
    s.data.n = 7u; /* < 2 clusters · (d + 2) */
    TEST_ASSERT_EQUAL_INT(MD_E_DEGENERATE, em_fit(&s.data, &s.outlier, &s.prior, seed, 2u, &opt, z, &fit));
    TEST_ASSERT_EQUAL_INT(EM_FAIL_TOO_FEW_POINTS, fit.reason);
    s.data.n = 270u;
    memset(seed, 0, sizeof seed); /* label 1 never used */
    TEST_ASSERT_EQUAL_INT(MD_E_DEGENERATE, em_fit(&s.data, &s.outlier, &s.prior, seed, 2u, &opt, z, &fit));
    TEST_ASSERT_EQUAL_INT(EM_FAIL_SEED, fit.reason);
    seed[5] = 3u;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, em_fit(&s.data, &s.outlier, &s.prior, seed, 2u, &opt, z, &fit));
    seed[5] = 0u;
    opt.max_iter = 1u;
    TEST_ASSERT_EQUAL_INT(MD_E_NOCONVERGE, em_fit(&s.data, &s.outlier, &s.prior, seed, 1u, &opt, z, &fit));
    TEST_ASSERT_EQUAL_INT(EM_FAIL_NOCONVERGE, fit.reason);
    TEST_ASSERT_TRUE(isfinite(fit.log_post) && isfinite(fit.params.lambda));
    opt.max_iter = MD_EM_MAX_ITER + 1u;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, em_fit(&s.data, &s.outlier, &s.prior, seed, 1u, &opt, z, &fit));
    em_options_default(&opt);
    for (size_t i = 0u; i < 40u; ++i) { /* collinear: singular scatter */
        pts[2u * i] = 0.3 * (double)i;
        pts[2u * i + 1u] = -0.6 * (double)i + 2.0;
    }
    prepare(40u, NULL, 0u, &s);
    TEST_ASSERT_EQUAL_INT(MD_E_DEGENERATE, em_fit(&s.data, &s.outlier, &s.prior, seed, 1u, &opt, z, &fit));
    TEST_ASSERT_EQUAL_INT(EM_FAIL_SINGULAR_COV, fit.reason);
    pts[0] = NAN;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, em_fit(&s.data, &s.outlier, &s.prior, seed, 1u, &opt, z, &fit));
}

/* docs/fuzzing.md finding 4: a finite target mean near -DBL_MAX puts the
 * Mahalanobis distance beyond the double range (inf - inf inside the
 * triangular solve). The far target has density 0 (ζ = 0), and a failed fit
 * carries no NaN (log_lik = log_post = 0, n_soft = 0). */
static void test_far_target_and_failed_fit_leave_no_nan(void)
{
    setup_t s;
    em_options_t opt;
    em_fit_t fit;
    em_target_t tg[2];
    memset(tg, 0, sizeof tg);
    tg[0].mean[0] = -DBL_MAX;
    tg[0].mean[1] = -DBL_MAX;
    tg[0].s_cov[0] = tg[0].s_cov[3] = 0.25;
    tg[0].s_cov[1] = tg[0].s_cov[2] = 0.2; /* L = [0.5 0; 0.4 0.3]: forward solve does inf - inf */
    tg[0].cluster_cov[0] = tg[0].cluster_cov[3] = 1.0;
    tg[0].p_detect = 0.9;
    tg[1] = tg[0];
    tg[1].mean[0] = -3.5;
    tg[1].mean[1] = 3.2;
    prepare(make_two(4u), tg, 2u, &s);
    double zeta[EM_J_MAX + 1u];
    const double far_mu[2] = {DBL_MAX, DBL_MAX};
    const double lp = em_prior_log_mean(&s.prior, far_mu, zeta);
    TEST_ASSERT_TRUE(isfinite(lp));
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.0, zeta[1]);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 1.0, zeta[0] + zeta[1] + zeta[2]);
    const double nan_mu[2] = {NAN, 1.0};
    TEST_ASSERT_FALSE(isnan(em_prior_log_mean(&s.prior, nan_mu, zeta)));
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.0, zeta[0] + zeta[1] + zeta[2]);
    em_options_default(&opt);
    TEST_ASSERT_EQUAL_INT(MD_OK, em_fit(&s.data, &s.outlier, &s.prior, seed, 2u, &opt, z, &fit));
    TEST_ASSERT_TRUE(isfinite(fit.log_post) && isfinite(fit.log_lik));
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.0, fit.zeta[0][1]);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.0, fit.zeta[1][1]);
    /* a fit that fails after iterating (5 seed points for a second cluster
     * among uniform outliers: its soft count drops below d + 2) */
    for (size_t i = 0u; i < 270u; ++i) {
        seed[i] = (i >= 250u && i < 255u) ? 1u : 0u;
    }
    const md_status_t st = em_fit(&s.data, &s.outlier, &s.prior, seed, 2u, &opt, z, &fit);
    TEST_ASSERT_TRUE((st != MD_OK) && (st != MD_E_NOCONVERGE));
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.0, fit.log_post);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.0, fit.log_lik);
    for (size_t g = 0u; g <= EM_G_MAX; ++g) {
        TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.0, fit.n_soft[g]);
    }
}

/* Three overlapping unit-variance clusters (centres 2.6-2.8 sd apart) and 20
 * outliers: EM's linear convergence is slow here (~90 steps at the default
 * tolerance), the case the accelerator is for. */
static size_t make_overlap(uint64_t s)
{
    md_rng_t rng;
    md_rng_seed(&rng, s);
    size_t k = 0u;
    for (; k < 260u; ++k) {
        const uint8_t c = (uint8_t)(k % 3u);
        const double cx = (c == 0u) ? 0.0 : ((c == 1u) ? 2.8 : 1.4);
        const double cy = (c == 2u) ? 2.24 : 0.0;
        pts[2u * k] = cx + md_rng_gauss(&rng);
        pts[2u * k + 1u] = cy + md_rng_gauss(&rng);
        seed[k] = c;
    }
    for (; k < 280u; ++k) {
        pts[2u * k] = -12.0 + 24.0 * md_rng_uniform(&rng);
        pts[2u * k + 1u] = -12.0 + 24.0 * md_rng_uniform(&rng);
        seed[k] = (uint8_t)(k % 3u);
    }
    return k;
}

static void fit_with(const setup_t *s, size_t g, bool accelerate, double tol, uint32_t max_iter, em_fit_t *fit)
{
    em_options_t opt;
    em_options_default(&opt);
    opt.accelerate = accelerate;
    opt.tol = tol;
    opt.max_iter = max_iter;
    const md_status_t st = em_fit(&s->data, &s->outlier, &s->prior, seed, g, &opt, z, fit);
    TEST_ASSERT_TRUE((st == MD_OK) || (st == MD_E_NOCONVERGE));
}

static void assert_same_fit(const em_fit_t *a, const em_fit_t *b, double tol_mean)
{
    TEST_ASSERT_DOUBLE_WITHIN(1e-9 * fabs(a->log_post), a->log_post, b->log_post);
    for (size_t g = 0u; g < a->params.g; ++g) {
        TEST_ASSERT_DOUBLE_WITHIN(tol_mean, a->params.mean[g][0], b->params.mean[g][0]);
        TEST_ASSERT_DOUBLE_WITHIN(tol_mean, a->params.mean[g][1], b->params.mean[g][1]);
        TEST_ASSERT_DOUBLE_WITHIN(tol_mean, a->params.pi[g], b->params.pi[g]);
    }
    TEST_ASSERT_DOUBLE_WITHIN(tol_mean, a->params.lambda, b->params.lambda);
}

/* SQUAREM keeps EM's fixed point: the known-answer fits (no prior; one
 * target prior) end where plain EM ends, at a tight tolerance. */
static void test_squarem_same_optimum_as_plain_em(void)
{
    setup_t s;
    em_fit_t plain;
    em_fit_t fast;
    prepare(make_two(1u), NULL, 0u, &s);
    fit_with(&s, 2u, false, 1e-13, MD_EM_MAX_ITER, &plain);
    fit_with(&s, 2u, true, 1e-13, MD_EM_MAX_ITER, &fast);
    assert_same_fit(&plain, &fast, 1e-5);
    em_target_t tg;
    memset(&tg, 0, sizeof tg);
    tg.mean[0] = -3.5;
    tg.mean[1] = 3.2;
    tg.s_cov[0] = tg.s_cov[3] = 0.05;
    tg.cluster_cov[0] = tg.cluster_cov[3] = 1.0;
    tg.p_detect = 0.9;
    prepare(make_two(2u), &tg, 1u, &s);
    fit_with(&s, 2u, false, 1e-13, MD_EM_MAX_ITER, &plain);
    fit_with(&s, 2u, true, 1e-13, MD_EM_MAX_ITER, &fast);
    assert_same_fit(&plain, &fast, 1e-5);
    /* at the default tolerance both stop within it of the same log-posterior */
    fit_with(&s, 2u, false, MD_EM_TOL_REL, MD_EM_MAX_ITER, &plain);
    fit_with(&s, 2u, true, MD_EM_TOL_REL, MD_EM_MAX_ITER, &fast);
    TEST_ASSERT_DOUBLE_WITHIN(1e-5 * fabs(plain.log_post), plain.log_post, fast.log_post);
}

/* Overlapping clusters, G = 3: the same optimum in several times fewer EM
 * steps (fails without the accelerator: plain EM's count is the reference). */
static void test_squarem_fewer_iterations_on_overlap(void)
{
    setup_t s;
    em_fit_t plain;
    em_fit_t fast;
    em_fit_t ref;
    prepare(make_overlap(4u), NULL, 0u, &s);
    fit_with(&s, 3u, false, MD_EM_TOL_REL, MD_EM_MAX_ITER, &plain);
    fit_with(&s, 3u, true, MD_EM_TOL_REL, MD_EM_MAX_ITER, &fast);
    fit_with(&s, 3u, false, 1e-14, MD_EM_MAX_ITER, &ref);
    TEST_ASSERT_EQUAL_INT(MD_OK, plain.status);
    TEST_ASSERT_EQUAL_INT(MD_OK, fast.status);
    TEST_ASSERT_GREATER_THAN_UINT(60u, plain.iterations);
    TEST_ASSERT_LESS_THAN_UINT(plain.iterations / 2u, fast.iterations);
    /* the accelerated fit is at least as close to the optimum as plain EM */
    TEST_ASSERT_TRUE(fast.log_post >= plain.log_post - 1e-9 * fabs(plain.log_post));
    TEST_ASSERT_TRUE(ref.log_post >= fast.log_post - 1e-9 * fabs(ref.log_post));
}

/* MAP-EM is monotone and SQUAREM keeps it so: the log-posterior after k
 * EM steps (an accepted extrapolation counts inside them) never decreases in k. */
static void test_squarem_log_post_monotone(void)
{
    setup_t s;
    em_fit_t fit;
    prepare(make_overlap(3u), NULL, 0u, &s);
    double prev = -INFINITY;
    for (uint32_t k = 1u; k <= 30u; ++k) {
        fit_with(&s, 3u, true, 1e-15, k, &fit);
        TEST_ASSERT_TRUE(isfinite(fit.log_post));
        TEST_ASSERT_TRUE(fit.log_post >= prev - 1e-10 * fabs(fit.log_post));
        prev = fit.log_post;
    }
}

/* em_fit_from: from another prior's optimum it reaches this prior's optimum (the
 * one a seeded fit finds), in fewer steps; bad starting points are refused. */
static void test_fit_from_converges_to_the_same_optimum(void)
{
    setup_t s;
    em_options_t opt;
    em_fit_t seeded;
    em_fit_t donor;
    em_fit_t warm;
    em_target_t tg;
    memset(&tg, 0, sizeof tg);
    tg.mean[0] = -3.0;
    tg.mean[1] = 3.4;
    tg.s_cov[0] = tg.s_cov[3] = 0.2;
    tg.p_detect = 0.9;
    em_options_default(&opt);
    opt.tol = 1e-12;
    prepare(make_two(3u), NULL, 0u, &s); /* donor: uniform prior */
    TEST_ASSERT_EQUAL_INT(MD_OK, em_fit(&s.data, &s.outlier, &s.prior, seed, 2u, &opt, z, &donor));
    prepare(make_two(3u), &tg, 1u, &s); /* this prior pulls cluster 1 towards (-3, 3.4) */
    TEST_ASSERT_EQUAL_INT(MD_OK, em_fit(&s.data, &s.outlier, &s.prior, seed, 2u, &opt, z, &seeded));
    TEST_ASSERT_EQUAL_INT(MD_OK, em_fit_from(&s.data, &s.outlier, &s.prior, &donor.params, &opt, z, &warm));
    TEST_ASSERT_TRUE(fabs(donor.params.mean[0][0] - seeded.params.mean[0][0]) > 1e-3); /* the priors differ */
    TEST_ASSERT_DOUBLE_WITHIN(1e-8 * fabs(seeded.log_post), seeded.log_post, warm.log_post);
    for (size_t g = 0u; g < 2u; ++g) {
        for (size_t j = 0u; j < 2u; ++j) {
            TEST_ASSERT_DOUBLE_WITHIN(1e-5, seeded.params.mean[g][j], warm.params.mean[g][j]);
        }
    }
    TEST_ASSERT_TRUE(warm.iterations < seeded.iterations);

    em_params_t bad = donor.params;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, em_fit_from(&s.data, &s.outlier, &s.prior, NULL, &opt, z, &warm));
    bad.pi[1] = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, em_fit_from(&s.data, &s.outlier, &s.prior, &bad, &opt, z, &warm));
    bad = donor.params;
    bad.lambda = -1.0;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, em_fit_from(&s.data, &s.outlier, &s.prior, &bad, &opt, z, &warm));
    bad = donor.params;
    bad.mean[0][1] = NAN;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, em_fit_from(&s.data, &s.outlier, &s.prior, &bad, &opt, z, &warm));
    bad = donor.params;
    bad.d = 3u;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, em_fit_from(&s.data, &s.outlier, &s.prior, &bad, &opt, z, &warm));
    TEST_ASSERT_EQUAL_INT(EM_FAIL_ARG, warm.reason);
    bad = donor.params;
    bad.shape[0][0] = -1.0; /* not positive definite */
    TEST_ASSERT_EQUAL_INT(MD_E_NUMERIC, em_fit_from(&s.data, &s.outlier, &s.prior, &bad, &opt, z, &warm));
}

static void test_labels_argmax(void)
{
    const double zz[6] = {0.1, 0.7, 0.2, 0.6, 0.3, 0.1};
    uint8_t lab[2];
    em_labels(zz, 2u, 2u, lab);
    TEST_ASSERT_EQUAL_UINT(1u, lab[0]);
    TEST_ASSERT_EQUAL_UINT(0u, lab[1]);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_recovers_two_clusters);
    RUN_TEST(test_fixed_point_is_stationary);
    RUN_TEST(test_map_mean_obeys_eq_3_15);
    RUN_TEST(test_degenerate_and_bad_inputs);
    RUN_TEST(test_far_target_and_failed_fit_leave_no_nan);
    RUN_TEST(test_squarem_same_optimum_as_plain_em);
    RUN_TEST(test_squarem_fewer_iterations_on_overlap);
    RUN_TEST(test_squarem_log_post_monotone);
    RUN_TEST(test_fit_from_converges_to_the_same_optimum);
    RUN_TEST(test_labels_argmax);
    return UNITY_END();
}
