/// @file mhtc_bench.c
/// Benchmark of one MHTC step (docs/mhtc.md): L = 8, G_max = 4, ~300 spikes of
/// three synthetic neurons plus outliers, d_w = 35 (1.15 ms at 30 kHz), d = 2,
/// Laplace evidence. Warm-up intervals fill the hypothesis set; then each
/// measured step is timed. Prints sizes of the per-electrode state and the
/// shared workspace. usage: mhtc-bench [STEPS] [--bic] [--tol T] [--L N]
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "numeric/md_rng.h"
#include "features/pca.h"
#include "metrics/quality.h"
#include "tool_time.h"
#include "tracking/mhtc.h"

#define B_DW 35u
#define B_D 2u
#define B_N 300u
#define B_NOISE 128u
#define B_WARMUP 6u

static mhtc_state_t g_st;
static mhtc_workspace_t g_ws;
static mhtc_result_t g_out;
static pca_work_t g_pw;
static pca_basis_t g_basis;
static double g_wave[B_N][B_DW];
static double g_noise[B_NOISE][B_DW];
static double g_y[B_N * B_D];
static double g_xi[B_D * B_D];
static double g_ms[1000];

static double b_template(int u, size_t i, double drift)
{
    const double c[3] = {12.0, 14.0, 11.0}, a[3] = {-80.0, -55.0, 45.0}, w[3] = {2.0, 4.0, 2.5};
    const double t = ((double)i - c[u] - drift) / w[u];
    return a[u] * exp(-0.5 * t * t) - 0.35 * a[u] * exp(-0.5 * (t - 4.0) * (t - 4.0) / 6.0);
}

static void b_interval(md_rng_t *rng, size_t k)
{
    const size_t counts[3] = {130u, 100u, 55u};
    size_t n = 0u;
    for (int u = 0; u < 3; ++u) {
        for (size_t s = 0u; s < counts[u]; ++s, ++n) {
            for (size_t i = 0u; i < B_DW; ++i) {
                g_wave[n][i] = b_template(u, i, 0.05 * (double)k) + 8.0 * md_rng_gauss(rng);
            }
        }
    }
    for (; n < B_N; ++n) { /* outliers */
        for (size_t i = 0u; i < B_DW; ++i) {
            g_wave[n][i] = 40.0 * md_rng_gauss(rng);
        }
    }
    for (size_t s = 0u; s < B_NOISE; ++s) {
        for (size_t i = 0u; i < B_DW; ++i) {
            g_noise[s][i] = 8.0 * md_rng_gauss(rng);
        }
    }
    if ((pca_fit(&g_wave[0][0], B_N, B_DW, B_DW, B_D, &g_pw, &g_basis) != MD_OK) ||
        (pca_project_all(&g_basis, &g_wave[0][0], B_N, B_DW, g_y) != MD_OK) ||
        (qm_noise_feature_cov(&g_basis, &g_noise[0][0], B_NOISE, B_DW, g_xi) != MD_OK)) {
        (void)fprintf(stderr, "mhtc-bench: synthetic interval failed\n");
        exit(1);
    }
}

/* [--bic] [--tol T] [--L N] from argv[2] on into *cfg; an unknown option sets an L mhtc_config_check refuses. */
static void b_parse_options(int argc, char **argv, mhtc_config_t *cfg, int *bic)
{
    for (int i = 2; i < argc; ++i) {
        if (strcmp(argv[i], "--bic") == 0) {
            *bic = 1;
        } else if ((strcmp(argv[i], "--tol") == 0) && (i + 1 < argc)) {
            cfg->em.tol = strtod(argv[++i], NULL);
        } else if ((strcmp(argv[i], "--L") == 0) && (i + 1 < argc)) {
            cfg->L = (size_t)strtoul(argv[++i], NULL, 10);
        } else {
            cfg->L = 0u; /* rejected by the caller */
        }
    }
}

/* The warm-up intervals, then `steps` timed MHTC steps (g_ms); the model hypotheses of the timed steps in
 * *models. 0, or 1 after a failed step. */
static int b_run(size_t steps, size_t *models)
{
    md_rng_t rng;
    md_rng_seed(&rng, 2024u);
    *models = 0u;
    for (size_t k = 0u; k < B_WARMUP + steps; ++k) {
        b_interval(&rng, k);
        const mhtc_input_t in = {g_y, B_N, &g_wave[0][0], B_DW, &g_basis, g_xi, 10.0, NULL, 0.0, 0.0};
        const double t0 = tool_now_ms();
        const md_status_t st = mhtc_update(&g_st, &in, &g_ws, &g_out);
        const double dt = tool_now_ms() - t0;
        if (st != MD_OK) {
            (void)fprintf(stderr, "mhtc-bench: step %zu failed: %s\n", k, md_status_name(st));
            return 1;
        }
        if (k >= B_WARMUP) {
            g_ms[k - B_WARMUP] = dt;
            *models += g_out.models_fitted;
        }
    }
    return 0;
}

int main(int argc, char **argv)
{
    const size_t steps = (argc > 1) ? (size_t)strtoul(argv[1], NULL, 10) : 10u;
    int bic = 0;
    mhtc_config_t cfg;
    mhtc_config_default(&cfg, MHTC_TRACKER_MHTC);
    b_parse_options(argc, argv, &cfg, &bic);
    if ((steps == 0u) || (steps > 1000u) || (mhtc_config_check(&cfg) != MD_OK)) {
        (void)fprintf(stderr, "usage: mhtc-bench [STEPS 1..1000] [--bic] [--tol T > 0] [--L 1..%u]\n",
                      (unsigned)MHTC_L_MAX);
        return 2;
    }
    cfg.q_process = 25.0;
    cfg.init_var = 25.0;
    cfg.evidence = bic ? CLUSTER_EVIDENCE_BIC : CLUSTER_EVIDENCE_LAPLACE;
    size_t models = 0u;
    if ((mhtc_init(&g_st, &cfg) != MD_OK) || (b_run(steps, &models) != 0)) {
        return 1;
    }
    qsort(g_ms, steps, sizeof g_ms[0], tool_cmp_double);
    printf("L %zu, EM tol %g, steps %zu, evidence %s: median %.2f ms, min %.2f ms, max %.2f ms; model hypotheses per "
           "step %.1f; "
           "hypotheses %zu, tracks (leading) %zu\n",
           cfg.L, cfg.em.tol, steps, bic ? "BIC" : "Laplace", g_ms[steps / 2u], g_ms[0], g_ms[steps - 1u],
           (double)models / (double)steps, g_out.n_hyp, g_out.n_tracks);
    printf("sizeof: mhtc_state_t %zu B (per electrode), mhtc_track_t %zu B x %u, kf_state_t %zu B, "
           "mhtc_hyp_t %zu B x %u, mhtc_workspace_t %zu B (shared)\n",
           sizeof(mhtc_state_t), sizeof(mhtc_track_t), (unsigned)MHTC_POOL, sizeof(kf_state_t), sizeof(mhtc_hyp_t),
           (unsigned)MHTC_L_MAX, sizeof(mhtc_workspace_t));
    printf("stats: pruned %u failed %u fallbacks %u dup %u pool_drops %u murty_solves %u shared %u\n",
           g_st.stats.models_pruned, g_st.stats.models_failed, g_st.stats.evidence_fallbacks, g_st.stats.dup_pruned,
           g_st.stats.pool_drops, g_st.stats.murty_solves, g_st.stats.models_shared);
    return 0;
}
