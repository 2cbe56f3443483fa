/// @file fuzz_cluster.c
/// Fuzz target 5a: clustering of one interval (firmware/core/cluster/cluster.h,
/// cluster_fit_models) with MAP or ML, Laplace or BIC, on arbitrary point sets:
/// empty, one spike, more than EM_N_MAX points, duplicates, collinear points,
/// huge, tiny and denormal values, NaN and inf; arbitrary noise covariance,
/// predicted targets, model prior and configuration. Checks:
///  - the status is a documented one; non-finite points or n > EM_N_MAX give
///    MD_E_ARG; MD_OK implies a usable best_g within 1..g_max;
///  - no model class in 1..g_max carries a NaN anywhere in its result
///    (cluster.h: "never leaves NaN in the result");
///  - every usable model is fully finite: parameters, log-likelihood,
///    evidence, posterior in [0, 1]; labels are 0..G; the posteriors of the
///    usable models sum to 1.
#include <stdint.h>
#include <string.h>

#include "cluster/cluster.h"
#include "fuzz_input.h"

#define FZ_N_CAP (EM_N_MAX + 4u) /* a few more than the capacity: must be refused */
/* Executions must stay cheap enough for 10 million of them on a shared core
 * (docs/fuzzing.md, "fuzz_cluster harness"): by default at most FZ_N_SMALL
 * points and an EM bound of at most FZ_ITER_SMALL. Config bit 6 lifts the
 * point cap to FZ_N_CAP (full capacity and overflow), bit 5 the EM bound to
 * MD_EM_MAX_ITER, bit 3 allows any bound at all. Empty, one-spike, duplicate,
 * collinear and extreme-value sets all fit under the small cap. */
#define FZ_N_SMALL 40u
#define FZ_ITER_SMALL 8u

static double g_points[FZ_N_CAP * EM_D_MAX];
static cluster_workspace_t g_ws;
static cluster_result_t g_out;
static em_target_t g_targets[EM_J_MAX + 1u];

/* A symmetric matrix that is SPD unless the fuzzer asks for a hostile one. */
static void make_cov(fz_t *in, size_t d, double *m)
{
    const uint8_t kind = fz_u8(in);
    for (size_t r = 0u; r < d; ++r) {
        for (size_t c = 0u; c <= r; ++c) {
            double v = fz_double_mode(in, (kind & 1u) ? fz_u8(in) : 0u);
            if (r == c && (kind & 1u) == 0u) {
                v = fabs(v) + 0.125; /* diagonally dominant below: SPD */
            } else if ((kind & 1u) == 0u) {
                v = v / 64.0;
            }
            m[r * d + c] = v;
            m[c * d + r] = v;
        }
    }
}

static uint8_t make_config(fz_t *in, cluster_config_t *cfg)
{
    const uint8_t a = fz_u8(in);
    cluster_config_default(cfg, ((a & 1u) != 0u) ? CLUSTER_ML : CLUSTER_MAP);
    if ((a & 2u) != 0u) {
        cfg->evidence = (cfg->evidence == CLUSTER_EVIDENCE_BIC) ? CLUSTER_EVIDENCE_LAPLACE : CLUSTER_EVIDENCE_BIC;
    }
    cfg->g_max = 1u + fz_u8(in) % EM_G_MAX;
    if ((a & 4u) != 0u) {
        cfg->g_max = fz_u8(in) % (EM_G_MAX + 2u); /* 0 and EM_G_MAX+1 invalid */
    }
    /* Short EM runs keep executions fast (the iteration bound path is the same
     * at 3 as at 200); bit 5 allows the full bound, bit 3 anything at all. */
    cfg->em.max_iter = 1u + (uint32_t)(fz_u8(in) % (((a & 32u) != 0u) ? MD_EM_MAX_ITER : FZ_ITER_SMALL));
    if ((a & 8u) != 0u) {
        cfg->em.max_iter = fz_u32(in);
        cfg->em.tol = fz_double(in);
    }
    if ((a & 16u) != 0u) {
        cfg->lambda_new = fz_double(in);
        cfg->lambda_false = fz_double(in);
        cfg->shape_prior_width = fz_double(in);
    }
    return a;
}

static size_t make_targets(fz_t *in, size_t d)
{
    const size_t n = fz_u8(in) % (EM_J_MAX + 2u);
    for (size_t j = 0u; j < n && j <= EM_J_MAX; ++j) {
        em_target_t *t = &g_targets[j];
        memset(t, 0, sizeof *t);
        for (size_t k = 0u; k < d; ++k) {
            t->mean[k] = fz_double(in);
        }
        make_cov(in, d, t->s_cov);
        make_cov(in, d, t->cluster_cov);
        const uint8_t p = fz_u8(in);
        t->p_detect = (p < 250u) ? (double)(p + 1u) / 250.0 : fz_double(in);
    }
    return n;
}

/* Point i: fresh values, a duplicate, a multiple of the previous one (collinear
 * through the origin) or the previous one shifted along the first axis only. */
static void make_point(fz_t *in, size_t i, size_t d)
{
    double *y = &g_points[i * d];
    const double *prev = (i > 0u) ? &g_points[(i - 1u) * d] : NULL;
    const uint8_t kind = fz_u8(in);
    const uint8_t mode = (uint8_t)(kind >> 4u);
    if ((kind & 3u) == 1u && prev != NULL) {
        memcpy(y, prev, d * sizeof *y);
    } else if ((kind & 3u) == 2u && prev != NULL) {
        const double c = fz_double_mode(in, mode);
        for (size_t k = 0u; k < d; ++k) {
            y[k] = c * prev[k];
        }
    } else if ((kind & 3u) == 3u && prev != NULL) {
        memcpy(y, prev, d * sizeof *y);
        y[0] += fz_double_mode(in, mode);
    } else {
        for (size_t k = 0u; k < d; ++k) {
            y[k] = fz_double_mode(in, mode);
        }
    }
}

static bool no_nan(const double *v, size_t n)
{
    for (size_t i = 0u; i < n; ++i) {
        if (isnan(v[i])) {
            return false;
        }
    }
    return true;
}

static void check_fit_finite(const em_fit_t *f, size_t d, size_t g)
{
    const em_params_t *p = &f->params;
    FUZZ_CHECK(p->d == d && p->g == g);
    FUZZ_CHECK(isfinite(p->pi0) && fz_all_finite(p->pi, g) && isfinite(p->lambda) && p->lambda > 0.0);
    for (size_t k = 0u; k < g; ++k) {
        FUZZ_CHECK(fz_all_finite(p->mean[k], d) && fz_all_finite(p->shape[k], d * d));
        FUZZ_CHECK(p->pi[k] >= 0.0 && p->pi[k] <= 1.0);
        FUZZ_CHECK(fz_all_finite(f->zeta[k], EM_J_MAX + 1u));
    }
    FUZZ_CHECK(fz_all_finite(f->n_soft, g + 1u) && isfinite(f->log_lik) && isfinite(f->log_post));
}

static void check_result(const cluster_config_t *cfg, size_t n, size_t d, md_status_t st)
{
    double post_sum = 0.0;
    size_t usable = 0u;
    for (size_t gi = 0u; gi < cfg->g_max; ++gi) {
        const cluster_model_t *m = &g_out.model[gi];
        const em_fit_t *f = &m->fit;
        FUZZ_CHECK(!isnan(m->log_evidence) && !isnan(m->log_model_prior) && !isnan(m->post_prob));
        /* no NaN in any model, failed fits included (crashes/fuzz_cluster/: a
         * target mean near -DBL_MAX, docs/fuzzing.md "Findings") */
        FUZZ_CHECK(!isnan(f->log_lik) && !isnan(f->log_post) && no_nan(f->n_soft, EM_G_MAX + 1u));
        if (!m->usable) {
            continue;
        }
        usable++;
        FUZZ_CHECK(f->status == MD_OK || f->status == MD_E_NOCONVERGE);
        check_fit_finite(f, d, gi + 1u);
        FUZZ_CHECK(isfinite(m->log_evidence) && isfinite(m->post_prob));
        FUZZ_CHECK(m->post_prob >= 0.0 && m->post_prob <= 1.0);
        for (size_t i = 0u; i < n; ++i) {
            FUZZ_CHECK(m->labels[i] <= gi + 1u);
        }
        post_sum += m->post_prob;
    }
    if (st == MD_OK) {
        FUZZ_CHECK(usable > 0u);
        FUZZ_CHECK(g_out.best_g >= 1u && g_out.best_g <= cfg->g_max && g_out.model[g_out.best_g - 1u].usable);
        FUZZ_CHECK(fabs(post_sum - 1.0) <= 1e-9);
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fz_t in;
    fz_init(&in, data, size);
    cluster_config_t cfg;
    const size_t n_cap = ((make_config(&in, &cfg) & 64u) != 0u) ? FZ_N_CAP : FZ_N_SMALL;
    const uint8_t db = fz_u8(&in);
    const size_t d = (db < 250u) ? 1u + db % EM_D_MAX : db % (EM_D_MAX + 2u); /* rarely 0 or D_MAX+1 */
    const size_t dd = (d >= 1u && d <= EM_D_MAX) ? d : 1u;
    double noise[EM_D_MAX * EM_D_MAX];
    make_cov(&in, dd, noise);
    cluster_input_t cin;
    memset(&cin, 0, sizeof cin);
    cin.noise_cov = noise;
    cin.n_targets = make_targets(&in, dd);
    cin.targets = (cin.n_targets > 0u || (fz_u8(&in) & 1u) != 0u) ? g_targets : NULL;
    double model_prior[EM_G_MAX];
    if ((fz_u8(&in) & 1u) != 0u) {
        for (size_t g = 0u; g < EM_G_MAX; ++g) {
            model_prior[g] = fz_double(&in);
        }
        cin.model_prior = model_prior;
    }
    size_t n = 0u;
    while (fz_left(&in) > 0u && n < n_cap) {
        make_point(&in, n, dd);
        n++;
    }
    cin.data.y = g_points;
    cin.data.n = n;
    cin.data.d = d;
    memset(&g_out, 0, sizeof g_out);
    const md_status_t st = cluster_fit_models(&cfg, &cin, &g_ws, &g_out);
    FUZZ_CHECK(st == MD_OK || st == MD_E_ARG || st == MD_E_DEGENERATE || st == MD_E_NUMERIC || st == MD_E_NOCONVERGE);
    const bool cfg_ok = cfg.g_max >= 1u && cfg.g_max <= EM_G_MAX;
    if (!cfg_ok || d != dd) {
        FUZZ_CHECK(st == MD_E_ARG);
        return 0;
    }
    if (n > EM_N_MAX || !fz_all_finite(g_points, n * d)) {
        FUZZ_CHECK(st == MD_E_ARG);
    }
    check_result(&cfg, (n <= EM_N_MAX) ? n : 0u, d, st);
    return 0;
}
