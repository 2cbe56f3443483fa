/// @file sim_cli.h
/// Command line of microdrive-sim (docs/sim-process.md). Parsing only: no I/O
/// besides the message written into the caller's buffer.
#ifndef SIM_CLI_H
#define SIM_CLI_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

typedef struct {
    const char *scenario;  ///< --scenario FILE (required unless --help)
    bool seed_given;
    uint64_t seed;             ///< --seed N (default: the scenario's seed)
    const char *bus;           ///< --bus SPEC (default "auto")
    bool realtime;             ///< --realtime
    const char *export_dir;    ///< --export-recording DIR (NULL: join the bus)
    const char *truth;         ///< --truth FILE (NULL: no ground truth)
    double hall_rate_hz;       ///< --hall-rate HZ (0: the scenario's)
    uint32_t calib_period_ms;  ///< --calib-period-ms MS (default 10000)
    bool autostart;            ///< false with --no-autostart
    double duration_s;         ///< --duration-s S (<0: the scenario's; 0: no limit)
    uint32_t pace_fps;         ///< --pace FPS, lockstep frame rate cap (0: none)
    bool help;                 ///< --help / -h
} sim_cli_t;

/// Parses argv into *cli (defaults first). Returns 0, or -1 with a one-line
/// reason in msg for an unknown option, a missing or malformed value, or a
/// missing --scenario.
int sim_cli_parse(sim_cli_t *cli, int argc, char *const argv[], char *msg, size_t msglen);

/// The --help text.
const char *sim_cli_usage(void);

#endif
