/* sim-bench: how much faster than real time the simulator generates signal.
 *   sim-bench [--minutes M] [SCENARIO.yaml]
 * Default: 3 electrodes, 30 kHz, 8 random neurons each within reach, every
 * electrode recorded continuously for M (default 100) simulated minutes in
 * 10 s intervals with a 10 um move after each, reversing every 40 moves so
 * the tips stay among the neurons (the moves happen while recording, so
 * motion artifacts are included; only recorded samples count as simulated
 * time).
 * Prints the simulated time, the CPU time, and the speed-up. */
#define _POSIX_C_SOURCE 200809L
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "scenario/scenario.h"

#define BENCH_CHUNK 4096u

static double cpu_s(void)
{
    struct timespec ts;
    (void)clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static void default_scenario(scenario_t *sc)
{
    scenario_default(sc);
    (void)snprintf(sc->name, sizeof sc->name, "%s", "bench");
    sc->n_electrodes = 3u;
    for (uint32_t e = 0u; e < 3u; ++e) {
        sim_electrode_config_t *c = &sc->electrodes[e];
        c->start_um = 1000.0;
        c->random_neurons.count = 8u;
        c->random_neurons.depth_min_um = 950.0;
        c->random_neurons.depth_max_um = 1700.0;
    }
}

int main(int argc, char **argv)
{
    double minutes = 100.0;
    static scenario_t sc;
    static char err[4096];
    default_scenario(&sc);
    for (int i = 1; i < argc; ++i) {
        if (strcmp(argv[i], "--minutes") == 0 && i + 1 < argc) {
            minutes = strtod(argv[++i], NULL);
        } else if (scenario_load(&sc, argv[i], err, sizeof err) != 0) {
            (void)fputs(err, stderr);
            return 1;
        }
    }
    sim_world_t *w = calloc(1u, sizeof *w);
    if (w == NULL || scenario_make_world(&sc, sc.seed, w) != MD_OK || !(minutes > 0.0)) {
        (void)fprintf(stderr, "sim-bench: cannot build the world\n");
        free(w);
        return 1;
    }
    static int16_t buf[BENCH_CHUNK];
    static sim_gt_spike_t gt[4096];
    const double fs = w->el[0].fs;
    const uint64_t total = (uint64_t)floor(minutes * 60.0 * fs);
    const uint64_t interval = (uint64_t)floor(10.0 * fs);
    uint64_t done = 0u, spikes = 0u;
    int64_t checksum = 0;
    const double t0 = cpu_s();
    while (done < total) {
        const uint64_t left = total - done;
        const size_t n = (size_t)(left < BENCH_CHUNK ? left : BENCH_CHUNK);
        for (uint32_t e = 0u; e < w->n_electrodes; ++e) {
            spikes += sim_electrode_generate(&w->el[e], buf, n, gt, 4096u);
            checksum += buf[n - 1u];
        }
        const uint64_t before = done / interval;
        done += n;
        if (done / interval != before) {
            const int dir = ((done / interval / 40u) % 2u == 0u) ? 1 : -1;
            for (uint32_t e = 0u; e < w->n_electrodes; ++e) {
                (void)sim_electrode_command(&w->el[e], actuator_steps_for(&w->el[e].act.p, 10.0 * dir), dir, 2000.0);
            }
        }
    }
    const double cpu = cpu_s() - t0;
    const double sim_s = (double)total / fs;
    (void)printf("sim-bench: %" PRIu32 " electrodes x %.1f simulated min at %.0f Hz: %.2f s CPU, "
                 "speed-up %.0fx real time (%" PRIu64 " spikes, checksum %" PRId64 ")\n",
                 w->n_electrodes, minutes, fs, cpu, sim_s / cpu, spikes, checksum);
    free(w);
    return 0;
}
