#include "sim_cli.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char USAGE[] =
    "usage: microdrive-sim --scenario FILE [--seed N] [--bus SPEC] [--realtime]\n"
    "                      [--export-recording DIR] [options]\n"
    "\n"
    "The plant of the autonomous microdrive on a CAN bus: actuator driver (node 2),\n"
    "position sensor (node 3) and neural front-end (node 4), driven by the models\n"
    "of a YAML scenario. See docs/sim-process.md.\n"
    "\n"
    "  --scenario FILE         scenario (YAML, see scenarios/ and docs/simulator.md); required\n"
    "  --seed N                seed of every random stream (default: the scenario's `seed`)\n"
    "  --bus SPEC              vcan0 | can0 | <ifname> | udp | udp:<port> | auto (default auto:\n"
    "                          vcan0 if SocketCAN works, else UDP multicast on loopback);\n"
    "                          the choice and its reason are printed\n"
    "  --realtime              simulated time follows CLOCK_MONOTONIC (demos with candump);\n"
    "                          default: fast deterministic lockstep, time moves only while a\n"
    "                          commanded motion or recording is in progress\n"
    "  --export-recording DIR  no bus: write the scenario's scripted recording to DIR\n"
    "                          (recording.bin/.json, ground_truth.csv/.jsonl) and exit\n"
    "  --truth FILE            write the session's ground truth (JSON lines) to FILE\n"
    "  --hall-rate HZ          HALL_READING rate in simulated time (default: scenario's\n"
    "                          sensor.report_rate_hz)\n"
    "  --calib-period-ms MS    HALL_CALIB repeat period in simulated time (default 10000)\n"
    "  --no-autostart          nodes wait in pre-operational for NMT start (default: they\n"
    "                          become operational after boot)\n"
    "  --duration-s S          exit when simulated time reaches S (default: scenario's\n"
    "                          duration_s; 0 = no limit)\n"
    "  --pace FPS              lockstep: at most FPS frames per wall second, so that\n"
    "                          receivers on UDP keep up (default 50000; 0 = no limit)\n"
    "  -h, --help              this text\n"
    "\n"
    "Heartbeats (0x702-0x704) go out every 100 ms of wall time in both modes.\n"
    "SIGINT/SIGTERM end the process cleanly (exit 0). Exit 1: runtime error, 2: usage.\n";

const char *sim_cli_usage(void)
{
    return USAGE;
}

static int cli_fail(char *msg, size_t msglen, const char *what, const char *arg)
{
    if (msg != NULL && msglen > 0u) {
        (void)snprintf(msg, msglen, "%s%s%s", what, (arg != NULL) ? ": " : "", (arg != NULL) ? arg : "");
    }
    return -1;
}

static int parse_u64(const char *s, uint64_t max, uint64_t *out)
{
    char *end = NULL;
    if (s == NULL || *s < '0' || *s > '9') {
        return -1;
    }
    errno = 0;
    const unsigned long long v = strtoull(s, &end, 10);
    if (errno != 0 || *end != '\0' || v > max) {
        return -1;
    }
    *out = (uint64_t)v;
    return 0;
}

static int parse_double(const char *s, double lo, double hi, double *out)
{
    char *end = NULL;
    if (s == NULL || *s == '\0') {
        return -1;
    }
    errno = 0;
    const double v = strtod(s, &end);
    if (errno != 0 || *end != '\0' || !isfinite(v) || v < lo || v > hi) {
        return -1;
    }
    *out = v;
    return 0;
}

static void cli_defaults(sim_cli_t *cli)
{
    memset(cli, 0, sizeof *cli);
    cli->bus = "auto";
    cli->calib_period_ms = 10000u;
    cli->autostart = true;
    cli->duration_s = -1.0;
    cli->pace_fps = 50000u;
}

/* Options with a value; returns 1 if `opt` was one of them, -1 on a bad value. */
static int cli_valued(sim_cli_t *cli, const char *opt, const char *val, char *msg, size_t msglen)
{
    uint64_t u = 0u;
    if (strcmp(opt, "--scenario") == 0) {
        cli->scenario = val;
    } else if (strcmp(opt, "--seed") == 0) {
        if (parse_u64(val, UINT64_MAX, &cli->seed) != 0) {
            return cli_fail(msg, msglen, "--seed needs an unsigned 64-bit integer", val);
        }
        cli->seed_given = true;
    } else if (strcmp(opt, "--bus") == 0) {
        cli->bus = val;
    } else if (strcmp(opt, "--export-recording") == 0) {
        cli->export_dir = val;
    } else if (strcmp(opt, "--truth") == 0) {
        cli->truth = val;
    } else if (strcmp(opt, "--hall-rate") == 0) {
        if (parse_double(val, 0.1, 10000.0, &cli->hall_rate_hz) != 0) {
            return cli_fail(msg, msglen, "--hall-rate needs a rate in 0.1..10000 Hz", val);
        }
    } else if (strcmp(opt, "--calib-period-ms") == 0) {
        if (parse_u64(val, 86400000u, &u) != 0 || u == 0u) {
            return cli_fail(msg, msglen, "--calib-period-ms needs 1..86400000", val);
        }
        cli->calib_period_ms = (uint32_t)u;
    } else if (strcmp(opt, "--duration-s") == 0) {
        if (parse_double(val, 0.0, 1e9, &cli->duration_s) != 0) {
            return cli_fail(msg, msglen, "--duration-s needs 0..1e9 seconds", val);
        }
    } else if (strcmp(opt, "--pace") == 0) {
        if (parse_u64(val, 10000000u, &u) != 0) {
            return cli_fail(msg, msglen, "--pace needs 0..10000000 frames per second", val);
        }
        cli->pace_fps = (uint32_t)u;
    } else {
        return 0;
    }
    return 1;
}

int sim_cli_parse(sim_cli_t *cli, int argc, char *const argv[], char *msg, size_t msglen)
{
    cli_defaults(cli);
    for (int i = 1; i < argc; i++) {
        const char *opt = argv[i];
        if (strcmp(opt, "--help") == 0 || strcmp(opt, "-h") == 0) {
            cli->help = true;
            return 0;
        }
        if (strcmp(opt, "--realtime") == 0) {
            cli->realtime = true;
            continue;
        }
        if (strcmp(opt, "--no-autostart") == 0) {
            cli->autostart = false;
            continue;
        }
        if (i + 1 >= argc) {
            sim_cli_t scratch = *cli; /* known option without its value, or unknown? */
            return cli_fail(msg, msglen,
                            (cli_valued(&scratch, opt, "", NULL, 0u) != 0) ? "missing value after" : "unknown option",
                            opt);
        }
        const int rc = cli_valued(cli, opt, argv[i + 1], msg, msglen);
        if (rc < 0) {
            return -1;
        }
        if (rc == 0) {
            return cli_fail(msg, msglen, "unknown option", opt);
        }
        i++;
    }
    if (cli->scenario == NULL || cli->scenario[0] == '\0') {
        return cli_fail(msg, msglen, "--scenario FILE is required", NULL);
    }
    return 0;
}
