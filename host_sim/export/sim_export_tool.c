/* sim-export: writes a simulated recording (recording.bin/.json, ground truth)
 * from a scenario file. Used by tests/python and by hand:
 *   sim-export SCENARIO.yaml OUTDIR [--seed N] [--intervals N] [--interval-s S]
 */
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "export/sim_export.h"

static int usage(void)
{
    (void)fprintf(stderr, "usage: sim-export SCENARIO.yaml OUTDIR [--seed N] [--intervals N] [--interval-s S]\n");
    return 2;
}

int main(int argc, char **argv)
{
    if (argc < 3) {
        return usage();
    }
    static scenario_t sc;
    static char err[8192];
    if (scenario_load(&sc, argv[1], err, sizeof err) != 0) {
        (void)fputs(err, stderr);
        return 1;
    }
    uint64_t seed = sc.seed;
    for (int i = 3; i + 1 < argc; i += 2) {
        char *end = NULL;
        if (strcmp(argv[i], "--seed") == 0) {
            seed = strtoull(argv[i + 1], &end, 10);
        } else if (strcmp(argv[i], "--intervals") == 0) {
            sc.export_cfg.intervals = (uint32_t)strtoul(argv[i + 1], &end, 10);
        } else if (strcmp(argv[i], "--interval-s") == 0) {
            sc.export_cfg.interval_s = strtod(argv[i + 1], &end);
        } else {
            return usage();
        }
        if (end == NULL || *end != '\0' || sc.export_cfg.intervals == 0u || !(sc.export_cfg.interval_s > 0.0)) {
            return usage();
        }
    }
    if ((argc - 3) % 2 != 0) {
        return usage();
    }
    const md_status_t st = sim_export_recording(&sc, seed, argv[2], err, sizeof err);
    if (st != MD_OK) {
        (void)fprintf(stderr, "sim-export: %s\n", err);
        return 1;
    }
    (void)printf("sim-export: %s -> %s (%" PRIu32 " channels, %" PRIu32 " x %.3f s, seed %" PRIu64 ")\n", argv[1],
                 argv[2], sc.n_electrodes, sc.export_cfg.intervals, sc.export_cfg.interval_s, seed);
    return 0;
}
