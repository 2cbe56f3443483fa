/// @file cluster_bench.c
/// Host benchmark of one clustering interval (docs/clustering.md): ~300
/// spikes in 2-D from three neurons plus outliers, model classes G = 1..4,
/// for MAP + Laplace (the thesis default), MAP + BIC and ML + BIC.
/// Prints the median wall time over N runs and the sizes of the caller-owned
/// structures. `cluster_bench [runs] [map-laplace|map-bic|ml-bic]`; with a
/// configuration named, only that one runs (for callgrind).
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cluster/cluster.h"
#include "numeric/md_rng.h"
#include "tool_time.h"

#define BENCH_SPIKES 300u
#define BENCH_RUNS_DEFAULT 51u
#define BENCH_RUNS_MAX 1001u

static double pts[BENCH_SPIKES * 2u];
static cluster_workspace_t ws;
static cluster_result_t res;
static double times_ms[BENCH_RUNS_MAX];

static void make_interval(em_target_t *tg)
{
    static const double centre[3][2] = {{-4.0, 1.0}, {3.0, 3.0}, {0.5, -4.0}};
    md_rng_t rng;
    md_rng_seed(&rng, 2008u);
    for (size_t i = 0u; i < BENCH_SPIKES; ++i) {
        if (i % 20u == 19u) { /* 5 % detector false positives */
            pts[2u * i] = -10.0 + 20.0 * md_rng_uniform(&rng);
            pts[2u * i + 1u] = -10.0 + 20.0 * md_rng_uniform(&rng);
            continue;
        }
        const size_t c = i % 3u;
        pts[2u * i] = centre[c][0] + md_rng_gauss(&rng);
        pts[2u * i + 1u] = centre[c][1] + 0.7 * md_rng_gauss(&rng);
    }
    memset(tg, 0, 3u * sizeof *tg);
    for (size_t c = 0u; c < 3u; ++c) { /* the previous interval's clusters, slightly drifted */
        tg[c].mean[0] = centre[c][0] + 0.2;
        tg[c].mean[1] = centre[c][1] - 0.1;
        tg[c].s_cov[0] = tg[c].s_cov[3] = 0.05;
        tg[c].cluster_cov[0] = 1.0;
        tg[c].cluster_cov[3] = 0.5;
        tg[c].p_detect = 0.9;
    }
}

static const char *only; /* configuration filter from argv[2], or NULL */

static void bench(const char *name, cluster_method_t method, cluster_evidence_t ev, const cluster_input_t *in,
                  unsigned runs)
{
    if ((only != NULL) && (strcmp(only, name) != 0)) {
        return;
    }
    cluster_config_t cfg;
    cluster_config_default(&cfg, method);
    cfg.evidence = ev;
    md_status_t st = MD_OK;
    for (unsigned r = 0u; r < runs; ++r) {
        const double t0 = tool_now_ms();
        st = cluster_fit_models(&cfg, in, &ws, &res);
        times_ms[r] = tool_now_ms() - t0;
    }
    qsort(times_ms, runs, sizeof times_ms[0], tool_cmp_double);
    unsigned iters = 0u;
    for (size_t g = 0u; g < EM_G_MAX; ++g) {
        iters += res.model[g].fit.iterations;
    }
    printf("| %-14s | %8.3f | %8.3f | %s | %zu | %5.3f | %3u |\n", name, times_ms[runs / 2u], times_ms[0],
           md_status_name(st), res.best_g, (res.best_g > 0u) ? res.model[res.best_g - 1u].post_prob : 0.0, iters);
}

int main(int argc, char **argv)
{
    unsigned runs = BENCH_RUNS_DEFAULT;
    if (argc > 1) {
        runs = (unsigned)strtoul(argv[1], NULL, 10);
        if ((runs == 0u) || (runs > BENCH_RUNS_MAX)) {
            fprintf(stderr, "usage: %s [runs 1..%u]\n", argv[0], BENCH_RUNS_MAX);
            return 2;
        }
    }
    only = (argc > 2) ? argv[2] : NULL;
    em_target_t tg[3];
    make_interval(tg);
    static const double noise_cov[4] = {0.2, 0.0, 0.0, 0.2};
    const cluster_input_t map_in = {{pts, BENCH_SPIKES, 2u}, noise_cov, tg, 3u, NULL};
    printf("one interval: %u spikes, d = 2, G = 1..%u, %u runs\n\n", BENCH_SPIKES, EM_G_MAX, runs);
    printf("| configuration  | median ms | min ms | status | best G | P(best) | EM iterations (all G) |\n");
    printf("|---|---|---|---|---|---|---|\n");
    bench("map-laplace", CLUSTER_MAP, CLUSTER_EVIDENCE_LAPLACE, &map_in, runs);
    bench("map-bic", CLUSTER_MAP, CLUSTER_EVIDENCE_BIC, &map_in, runs);
    bench("ml-bic", CLUSTER_ML, CLUSTER_EVIDENCE_BIC, &map_in, runs);
    printf("\nsizeof(cluster_workspace_t) = %zu bytes\n", sizeof(cluster_workspace_t));
    printf("  z %zu, seed work %zu, hac %zu, evidence %zu, outlier+prior %zu\n", sizeof ws.z, sizeof ws.seed_ws,
           sizeof ws.hac, sizeof ws.ev, sizeof ws.outlier + sizeof ws.prior);
    printf("sizeof(cluster_result_t)    = %zu bytes\n", sizeof(cluster_result_t));
    return 0;
}
