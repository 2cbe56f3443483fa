/* sim-export: writes a simulated recording (recording.bin/.json, ground truth)
 * from a scenario file. Used by tests/python and by hand:
 *   sim-export SCENARIO.yaml OUTDIR [--seed N] [--intervals N] [--interval-s S]
 */
#include <errno.h>
#include <inttypes.h>
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "export/sim_export.h"

static int usage(void)
{
    (void)fprintf(stderr, "usage: sim-export SCENARIO.yaml OUTDIR [--seed N] [--intervals N] [--interval-s S]\n");
    return 2;
}

/* A whole decimal number in min..max: strtoull alone would take "-1" as
 * 2^64 - 1 and wrap anything above the target type. */
static bool parse_count(const char *s, uint64_t min, uint64_t max, uint64_t *out)
{
    char *end = NULL;
    errno = 0;
    if (s[0] < '0' || s[0] > '9') {
        return false;
    }
    const unsigned long long v = strtoull(s, &end, 10);
    if (errno != 0 || end == s || *end != '\0' || v < min || v > max) {
        return false;
    }
    *out = (uint64_t)v;
    return true;
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
        const char *v = argv[i + 1];
        uint64_t n = 0u;
        bool ok = false;
        if (strcmp(argv[i], "--seed") == 0) {
            ok = parse_count(v, 0u, UINT64_MAX, &seed);
        } else if (strcmp(argv[i], "--intervals") == 0) {
            ok = parse_count(v, 1u, UINT32_MAX, &n);
            sc.export_cfg.intervals = (uint32_t)n;
        } else if (strcmp(argv[i], "--interval-s") == 0) {
            char *end = NULL;
            sc.export_cfg.interval_s = strtod(v, &end);
            ok = end != v && *end == '\0' && isfinite(sc.export_cfg.interval_s) && sc.export_cfg.interval_s > 0.0;
        }
        if (!ok) {
            (void)fprintf(stderr, "sim-export: %s %s: not a valid value\n", argv[i], v);
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
