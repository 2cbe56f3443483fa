/* Unit: cluster — model classes G = 1..4, evidence and eq. 3.17 on synthetic
 * interval data with known answers; the mean prior deciding a close call;
 * the §3.3.5 model prior; degenerate inputs return a reason, never NaN. */
#include <math.h>
#include <string.h>

#include "cluster/cluster.h"
#include "numeric/md_rng.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static double pts[EM_N_MAX * 2u];
static uint8_t truth[EM_N_MAX];
static cluster_workspace_t ws;
static cluster_result_t res;
static const double noise_cov[4] = {0.25, 0.0, 0.0, 0.25};

/* n points from G isotropic Gaussians (sd) at the given centres, weights equal,
 * plus n_out uniform outliers in [-12, 12]^2. */
static size_t make_mixture(uint64_t seed, const double (*centre)[2], size_t g, size_t n, double sd, size_t n_out)
{
    md_rng_t rng;
    md_rng_seed(&rng, seed);
    size_t k = 0u;
    for (size_t i = 0u; i < n; ++i, ++k) {
        const size_t c = i % g;
        pts[2u * k] = centre[c][0] + sd * md_rng_gauss(&rng);
        pts[2u * k + 1u] = centre[c][1] + sd * md_rng_gauss(&rng);
        truth[k] = (uint8_t)(c + 1u);
    }
    for (size_t i = 0u; i < n_out; ++i, ++k) {
        pts[2u * k] = -12.0 + 24.0 * md_rng_uniform(&rng);
        pts[2u * k + 1u] = -12.0 + 24.0 * md_rng_uniform(&rng);
        truth[k] = 0u;
    }
    return k;
}

static cluster_input_t input_of(size_t n, const em_target_t *tg, size_t n_tg, const double *prior)
{
    cluster_input_t in = {{pts, n, 2u}, noise_cov, tg, n_tg, prior};
    return in;
}

static void target_at(em_target_t *t, double x, double y, double s_var, double c_var)
{
    memset(t, 0, sizeof *t);
    t->mean[0] = x;
    t->mean[1] = y;
    t->s_cov[0] = t->s_cov[3] = s_var;
    t->cluster_cov[0] = t->cluster_cov[3] = c_var;
    t->p_detect = 0.9;
}

/* Cluster g of the fit whose mean is nearest to (x, y). */
static size_t nearest_cluster(const em_params_t *p, double x, double y)
{
    size_t best = 0u;
    double bd = INFINITY;
    for (size_t g = 0u; g < p->g; ++g) {
        const double d = hypot(p->mean[g][0] - x, p->mean[g][1] - y);
        if (d < bd) {
            bd = d;
            best = g;
        }
    }
    return best;
}

/* Spikes sit away from the origin, where the noise-like outlier Gaussian lives. */
static const double three[3][2] = {{-5.0, 0.0}, {5.0, 2.0}, {0.0, 7.0}};

static void check_three_recovered(const cluster_result_t *r)
{
    TEST_ASSERT_EQUAL_UINT(3u, r->best_g);
    const cluster_model_t *m = &r->model[2];
    TEST_ASSERT_TRUE(m->post_prob > 0.99);
    for (size_t c = 0u; c < 3u; ++c) {
        const size_t g = nearest_cluster(&m->fit.params, three[c][0], three[c][1]);
        /* 100 points of sd 1: the mean is within ~4 standard errors (0.1) */
        TEST_ASSERT_DOUBLE_WITHIN(0.4, three[c][0], m->fit.params.mean[g][0]);
        TEST_ASSERT_DOUBLE_WITHIN(0.4, three[c][1], m->fit.params.mean[g][1]);
        TEST_ASSERT_DOUBLE_WITHIN(0.06, 0.3226, m->fit.params.pi[g]); /* 100 of 310 */
    }
    /* Σ_g = λ C_g ≈ I: λ ≈ 1 */
    TEST_ASSERT_DOUBLE_WITHIN(0.25, 1.0, m->fit.params.lambda);
    double sum = 0.0;
    for (size_t g = 0u; g < r->g_max; ++g) {
        sum += r->model[g].post_prob;
    }
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 1.0, sum);
}

static void test_map_without_targets_recovers_three(void)
{
    const size_t n = make_mixture(101u, three, 3u, 300u, 1.0, 10u);
    cluster_config_t cfg;
    cluster_config_default(&cfg, CLUSTER_MAP);
    const cluster_input_t in = input_of(n, NULL, 0u, NULL);
    TEST_ASSERT_EQUAL_INT(MD_OK, cluster_fit_models(&cfg, &in, &ws, &res));
    check_three_recovered(&res);
    /* uniform outliers farther than 5 sd from every centre go to g = 0; the
     * cluster points go to their own cluster */
    size_t far = 0u;
    for (size_t i = 0u; i < n; ++i) {
        double dmin = INFINITY;
        for (size_t c = 0u; c < 3u; ++c) {
            dmin = fmin(dmin, hypot(pts[2u * i] - three[c][0], pts[2u * i + 1u] - three[c][1]));
        }
        if (truth[i] == 0u && dmin > 5.0) {
            TEST_ASSERT_EQUAL_UINT(0u, res.model[2].labels[i]);
            far++;
        } else if (truth[i] > 0u && dmin < 2.0) {
            const size_t g = nearest_cluster(&res.model[2].fit.params, three[truth[i] - 1u][0],
                                             three[truth[i] - 1u][1]);
            TEST_ASSERT_EQUAL_UINT(g + 1u, res.model[2].labels[i]);
        }
    }
    TEST_ASSERT_GREATER_OR_EQUAL_UINT(3u, far); /* the check above saw some outliers */
}

static void test_ml_baseline_recovers_three(void)
{
    const size_t n = make_mixture(102u, three, 3u, 300u, 1.0, 10u);
    cluster_config_t cfg;
    cluster_config_default(&cfg, CLUSTER_ML);
    TEST_ASSERT_EQUAL_INT(CLUSTER_EVIDENCE_BIC, cfg.evidence);
    const cluster_input_t in = input_of(n, NULL, 0u, NULL);
    TEST_ASSERT_EQUAL_INT(MD_OK, cluster_fit_models(&cfg, &in, &ws, &res));
    check_three_recovered(&res);
}

static void test_map_with_targets_tracks_them(void)
{
    const size_t n = make_mixture(103u, three, 3u, 300u, 1.0, 10u);
    em_target_t tg[3];
    /* targets listed in a different order than the data's centres */
    target_at(&tg[0], 0.3, 6.8, 0.2, 1.0);
    target_at(&tg[1], -5.2, 0.1, 0.2, 1.0);
    target_at(&tg[2], 4.8, 2.2, 0.2, 1.0);
    cluster_config_t cfg;
    cluster_config_default(&cfg, CLUSTER_MAP);
    const cluster_input_t in = input_of(n, tg, 3u, NULL);
    TEST_ASSERT_EQUAL_INT(MD_OK, cluster_fit_models(&cfg, &in, &ws, &res));
    check_three_recovered(&res);
    const size_t expect_target[3] = {2u, 3u, 1u}; /* ζ column of the target at each centre */
    for (size_t c = 0u; c < 3u; ++c) {
        const size_t g = nearest_cluster(&res.model[2].fit.params, three[c][0], three[c][1]);
        TEST_ASSERT_TRUE(res.model[2].fit.zeta[g][expect_target[c]] > 0.99); /* §3.4 association */
    }
}

/* Laplace evidence alone (uniform model prior) picks the true G for 1..4. */
static void test_laplace_selects_true_g(void)
{
    const double four[4][2] = {{-6.0, -6.0}, {6.0, -6.0}, {-6.0, 6.0}, {6.0, 6.0}};
    cluster_config_t cfg;
    cluster_config_default(&cfg, CLUSTER_MAP);
    for (size_t g = 1u; g <= 4u; ++g) {
        const size_t n = make_mixture(200u + g, four, g, 60u * g, 1.0, 0u);
        const cluster_input_t in = input_of(n, NULL, 0u, NULL);
        TEST_ASSERT_EQUAL_INT(MD_OK, cluster_fit_models(&cfg, &in, &ws, &res));
        TEST_ASSERT_EQUAL_UINT(g, res.best_g);
    }
}

/* Close call (thesis §3.3.5 "close calls", §3.6 (a), §4.5 k = 5: higher
 * evidence for the model with clusters at both predicted locations): two
 * clusters 2.2 sd apart. With no targets the evidence prefers one cluster;
 * with two targets predicting the two locations MAP picks two. */
static void test_prior_decides_close_call(void)
{
    const double two[2][2] = {{-1.1, 4.0}, {1.1, 4.0}};
    const size_t n = make_mixture(303u, two, 2u, 60u, 1.0, 0u);
    cluster_config_t cfg;
    cluster_config_default(&cfg, CLUSTER_MAP);
    cluster_input_t in = input_of(n, NULL, 0u, NULL);
    TEST_ASSERT_EQUAL_INT(MD_OK, cluster_fit_models(&cfg, &in, &ws, &res));
    TEST_ASSERT_TRUE(res.model[1].usable); /* decided by evidence, not by a failed fit */
    TEST_ASSERT_EQUAL_UINT(1u, res.best_g);
    em_target_t tg[2];
    target_at(&tg[0], -1.1, 4.0, 0.02, 1.0);
    target_at(&tg[1], 1.1, 4.0, 0.02, 1.0);
    in = input_of(n, tg, 2u, NULL);
    TEST_ASSERT_EQUAL_INT(MD_OK, cluster_fit_models(&cfg, &in, &ws, &res));
    TEST_ASSERT_TRUE(res.model[0].usable);
    TEST_ASSERT_EQUAL_UINT(2u, res.best_g);
}

static void test_model_prior_forgetting(void)
{
    const double prev[4] = {0.0, 1.0, 0.0, 0.0};
    double prior[4];
    TEST_ASSERT_EQUAL_INT(MD_OK, cluster_model_prior_forget(prev, 4u, CLUSTER_ALPHA_FORGET, prior));
    TEST_ASSERT_DOUBLE_WITHIN(1e-15, 0.0125, prior[0]);
    TEST_ASSERT_DOUBLE_WITHIN(1e-15, 0.9625, prior[1]);
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, cluster_model_prior_forget(prev, 4u, 1.5, prior));
    /* the prior enters eq. 3.17 (§3.6 (b): it biases toward a consistent number
     * of clusters): on the close-call data of the previous test, a previous
     * posterior certain of G = 2 raises P(G = 2 | Y) */
    const double two[2][2] = {{-1.1, 4.0}, {1.1, 4.0}};
    const size_t n = make_mixture(303u, two, 2u, 60u, 1.0, 0u);
    cluster_config_t cfg;
    cluster_config_default(&cfg, CLUSTER_MAP);
    cluster_input_t in = input_of(n, NULL, 0u, NULL);
    TEST_ASSERT_EQUAL_INT(MD_OK, cluster_fit_models(&cfg, &in, &ws, &res));
    TEST_ASSERT_TRUE(res.model[1].usable);
    const double p2_uniform = res.model[1].post_prob;
    in = input_of(n, NULL, 0u, prior);
    TEST_ASSERT_EQUAL_INT(MD_OK, cluster_fit_models(&cfg, &in, &ws, &res));
    TEST_ASSERT_TRUE(res.model[1].post_prob > p2_uniform);
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, log(0.9625), res.model[1].log_model_prior);
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, log(0.0125), res.model[0].log_model_prior);
}

static void assert_no_nan(const cluster_result_t *r)
{
    for (size_t g = 0u; g < EM_G_MAX; ++g) {
        const cluster_model_t *m = &r->model[g];
        TEST_ASSERT_TRUE(isfinite(m->log_evidence) && isfinite(m->post_prob) && isfinite(m->fit.log_lik) &&
                         isfinite(m->fit.params.lambda));
    }
}

static void run_degenerate(size_t n, em_reason_t expect_g1, md_status_t expect_st)
{
    cluster_config_t cfg;
    cluster_config_default(&cfg, CLUSTER_MAP);
    for (size_t method = 0u; method < 2u; ++method) {
        cluster_config_default(&cfg, (method == 0u) ? CLUSTER_MAP : CLUSTER_ML);
        const cluster_input_t in = input_of(n, NULL, 0u, NULL);
        TEST_ASSERT_EQUAL_INT(expect_st, cluster_fit_models(&cfg, &in, &ws, &res));
        TEST_ASSERT_EQUAL_UINT(0u, res.best_g);
        TEST_ASSERT_EQUAL_STRING(em_reason_name(expect_g1), em_reason_name(res.model[0].fit.reason));
        assert_no_nan(&res);
    }
}

static void test_degenerate_inputs_return_reasons(void)
{
    run_degenerate(0u, EM_FAIL_TOO_FEW_POINTS, MD_E_DEGENERATE);
    pts[0] = 1.0;
    pts[1] = 2.0;
    run_degenerate(1u, EM_FAIL_ZERO_VOLUME, MD_E_DEGENERATE); /* one point: V = 0 */
    pts[2] = 3.0;
    pts[3] = 5.0;
    run_degenerate(2u, EM_FAIL_TOO_FEW_POINTS, MD_E_DEGENERATE); /* V > 0, but < d + 2 points */
    for (size_t i = 0u; i < 50u; ++i) {                          /* all identical */
        pts[2u * i] = 0.5;
        pts[2u * i + 1u] = -0.5;
    }
    run_degenerate(50u, EM_FAIL_ZERO_VOLUME, MD_E_DEGENERATE);
    for (size_t i = 0u; i < 50u; ++i) { /* collinear on a diagonal: V > 0, scatter singular */
        pts[2u * i] = 0.1 * (double)i;
        pts[2u * i + 1u] = 1.0 + 0.2 * (double)i;
    }
    run_degenerate(50u, EM_FAIL_SINGULAR_COV, MD_E_DEGENERATE);
}

static void test_bad_arguments(void)
{
    cluster_config_t cfg;
    cluster_config_default(&cfg, CLUSTER_MAP);
    const double one[1][2] = {{0.0, 4.0}};
    const size_t n = make_mixture(501u, one, 1u, 40u, 1.0, 0u);
    cluster_input_t in = input_of(n, NULL, 0u, NULL);
    cfg.g_max = 0u;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, cluster_fit_models(&cfg, &in, &ws, &res));
    cluster_config_default(&cfg, CLUSTER_MAP);
    const double bad_noise[4] = {-1.0, 0.0, 0.0, 1.0};
    in.noise_cov = bad_noise;
    TEST_ASSERT_EQUAL_INT(MD_E_NUMERIC, cluster_fit_models(&cfg, &in, &ws, &res));
    TEST_ASSERT_EQUAL_INT(EM_FAIL_NOISE_COV, res.model[0].fit.reason);
    in.noise_cov = noise_cov;
    pts[3] = NAN;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, cluster_fit_models(&cfg, &in, &ws, &res));
    assert_no_nan(&res);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_map_without_targets_recovers_three);
    RUN_TEST(test_ml_baseline_recovers_three);
    RUN_TEST(test_map_with_targets_tracks_them);
    RUN_TEST(test_laplace_selects_true_g);
    RUN_TEST(test_prior_decides_close_call);
    RUN_TEST(test_model_prior_forgetting);
    RUN_TEST(test_degenerate_inputs_return_reasons);
    RUN_TEST(test_bad_arguments);
    return UNITY_END();
}
