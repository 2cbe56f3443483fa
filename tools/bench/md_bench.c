/// @file md_bench.c
/// Host benchmark of one electrode cycle, stage by stage (bench_core.h).
///
///   md-bench [--runs N] [--features FILE] [--callgrind]
///
/// Default: every stage N times (default 21); prints one line per stage
///   stage <name> median_ms <m> min_ms <a> max_ms <b> runs <N> in_cycle <0|1>
/// and a `cycle` line with the sum of the medians of the cycle's stages.
/// Times are reported, never judged. --features writes the measured
/// interval's spike features (one "y1 y2" line per spike) for
/// tools/bench/sklearn_gmm.py. --callgrind (under `valgrind --tool=callgrind
/// --collect-atstart=no`) runs each stage once with collection on and dumps
/// the counts as "stage:<name>", so every dump holds one stage only.
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench_core.h"
#include "tool_time.h"

#if defined(__has_include)
#if __has_include(<valgrind/callgrind.h>)
#include <valgrind/callgrind.h>
#define MB_HAVE_CALLGRIND 1
#endif
#endif
#ifndef MB_HAVE_CALLGRIND
#define MB_HAVE_CALLGRIND 0
#endif

#define MB_RUNS_MAX 1000u

static double g_ms[BENCH_ST_COUNT][MB_RUNS_MAX];

static int mb_write_features(const char *path)
{
    size_t n = 0u;
    const double *y = bench_features(&n);
    FILE *f = fopen(path, "w");
    if (f == NULL) {
        perror(path);
        return 1;
    }
    for (size_t i = 0u; i < n; ++i) {
        (void)fprintf(f, "%.17g %.17g\n", y[i * BENCH_D], y[i * BENCH_D + 1u]);
    }
    return (fclose(f) == 0) ? 0 : 1;
}

static int mb_callgrind(void)
{
#if MB_HAVE_CALLGRIND
    for (unsigned s = 0u; s < (unsigned)BENCH_ST_COUNT; ++s) {
        char name[64];
        (void)snprintf(name, sizeof name, "stage:%s", bench_stage_name((bench_stage_t)s));
        CALLGRIND_ZERO_STATS;
        CALLGRIND_TOGGLE_COLLECT;
        const md_status_t st = bench_run_stage((bench_stage_t)s);
        CALLGRIND_TOGGLE_COLLECT;
        CALLGRIND_DUMP_STATS_AT(name);
        if (st != MD_OK) {
            (void)fprintf(stderr, "md-bench: stage %s failed: %s\n", name, md_status_name(st));
            return 1;
        }
        printf("stage %s callgrind dumped\n", bench_stage_name((bench_stage_t)s));
    }
    return 0;
#else
    (void)fprintf(stderr, "md-bench: built without valgrind/callgrind.h\n");
    return 2;
#endif
}

static int mb_timed(size_t runs)
{
    double cycle_ms = 0.0;
    for (size_t r = 0u; r < runs; ++r) {
        for (unsigned s = 0u; s < (unsigned)BENCH_ST_COUNT; ++s) {
            const double t0 = tool_now_ms();
            const md_status_t st = bench_run_stage((bench_stage_t)s);
            g_ms[s][r] = tool_now_ms() - t0;
            if (st != MD_OK) {
                (void)fprintf(stderr, "md-bench: stage %s failed: %s\n", bench_stage_name((bench_stage_t)s),
                              md_status_name(st));
                return 1;
            }
        }
    }
    for (unsigned s = 0u; s < (unsigned)BENCH_ST_COUNT; ++s) {
        qsort(g_ms[s], runs, sizeof g_ms[s][0], tool_cmp_double);
        const double med = g_ms[s][runs / 2u];
        printf("stage %s median_ms %.4f min_ms %.4f max_ms %.4f runs %zu in_cycle %d\n",
               bench_stage_name((bench_stage_t)s), med, g_ms[s][0], g_ms[s][runs - 1u], runs,
               bench_stage_in_cycle((bench_stage_t)s));
        cycle_ms += bench_stage_in_cycle((bench_stage_t)s) ? med : 0.0;
    }
    printf("cycle median_sum_ms %.4f\n", cycle_ms);
    return 0;
}

int main(int argc, char **argv)
{
    size_t runs = 21u;
    const char *features = NULL;
    int callgrind = 0;
    for (int i = 1; i < argc; ++i) {
        if (strcmp(argv[i], "--runs") == 0 && i + 1 < argc) {
            runs = (size_t)strtoul(argv[++i], NULL, 10);
        } else if (strcmp(argv[i], "--features") == 0 && i + 1 < argc) {
            features = argv[++i];
        } else if (strcmp(argv[i], "--callgrind") == 0) {
            callgrind = 1;
        } else {
            runs = 0u; /* rejected below */
        }
    }
    if (runs == 0u || runs > MB_RUNS_MAX) {
        (void)fprintf(stderr, "usage: md-bench [--runs 1..%u] [--features FILE] [--callgrind]\n", MB_RUNS_MAX);
        return 2;
    }
    const md_status_t st = bench_setup();
    if (st != MD_OK) {
        (void)fprintf(stderr, "md-bench: setup failed: %s\n", md_status_name(st));
        return 1;
    }
    bench_info_t info;
    bench_info(&info);
    printf("interval fs_hz %u seconds %u true_spikes %u detected %u noise %u d_w %u hyp %u tracks %u models %u "
           "reused %u shared %u warm %u cluster_best_g %u static_bytes %zu\n",
           BENCH_FS_HZ, BENCH_SECONDS, info.true_spikes, info.detected, info.noise, info.d_w, info.hyp, info.tracks,
           info.models, info.reused, info.shared, info.warm, info.cluster_best_g, bench_static_bytes());
    if (features != NULL && mb_write_features(features) != 0) {
        return 1;
    }
    return callgrind ? mb_callgrind() : mb_timed(runs);
}
