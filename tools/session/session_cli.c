/// @file session_cli.c
/// Command line of microdrive-session (docs/session.md).
#include <errno.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "md_params.h"
#include "session.h"

/* Two halves: C11 compilers need to support string literals of 4095
 * characters only. */
static const char *usage_options(void)
{
    return "usage: microdrive-session --scenario FILE [--seed N] [--bus auto|vcan0|udp|udp:PORT|IFACE|inproc]\n"
           "                          --out DIR [--cycles N | --duration-s S] [--idle-s S] [--pace FPS]\n"
           "                          [--bin-dir DIR] [--python PY] [--param NAME=VALUE]...\n"
           "                          [--no-score] [--no-lcm] [--no-plots] [--no-recording]\n"
           "                          [--candump-samples] [--controller host|m7] [--m7-image ELF]\n"
           "                          [--qemu PATH] [--icount-shift N] [--quiet] [--help]\n"
           "  --scenario FILE   simulator scenario (scenarios/*.yaml)\n"
           "  --seed N          seed of every random stream (default: the scenario's)\n"
           "  --bus SPEC        inproc: simulator + controller in this process, virtual clock, as fast\n"
           "                    as possible; vcan0/IFACE/udp: microdrive-sim and microdrive-fw as\n"
           "                    processes; auto (default): vcan0 if present, else udp\n"
           "  --out DIR         recording.bin + recording.json (the samples the controller recorded;\n"
           "                    recording-e<k>.* per electrode with several), candump.log (every\n"
           "                    frame but the samples), truth.jsonl, report.json, session.lcmlog,\n"
           "                    tracks_pc.png waveforms.png status.png hypotheses.png truth.png\n"
           "                    [, sim.log, fw.log]\n"
           "  --cycles N        end when every electrode has completed N cycles (TLM_STATUS)\n"
           "  --duration-s S    end when simulated time passed S and every interval begun before\n"
           "                    S is reported (default: the scenario's duration_s; at most 1e9)\n"
           "  --idle-s S        end early when nothing but heartbeats moved for S seconds (virtual\n"
           "                    seconds in-process, wall seconds otherwise; default 30, 300 with\n"
           "                    --controller m7; at most 1e9)\n"
           "  --pace FPS        socket bus: microdrive-sim sends at most FPS frames per wall second after\n"
           "                    a burst, so that the controller and the recorder lose none (default\n"
           "                    10000, 2000 with --controller m7; 0 = no cap); changes when frames go\n"
           "                    out, never what they are\n"
           "  --bin-dir DIR     where microdrive-sim and microdrive-fw are (default: next to this program)\n"
           "  --python PY       interpreter for score.py and the plots (default: $MD_PYTHON, else the\n"
           "                    project venv this build was configured with, else a .venv in a folder\n"
           "                    above this program; none: a message says what to run)\n"
           "  --param NAME=VALUE  set a controller parameter before the start (repeatable; names and\n"
           "                    ranges: microdrive-fw --params-markdown), e.g. --param tracker=1;\n"
           "                    in-process applied to the controller, on a socket bus passed to\n"
           "                    microdrive-fw --param\n";
}

static const char *usage_m7_and_outputs(void)
{
    return "  --controller C    host (default): microdrive-fw, or the controller in this process with\n"
           "                    inproc; m7: the Cortex-M7 image under qemu-system-arm -M mps2-an500\n"
           "                    -icount shift=N, its frames over the board's UART to an mdcan bridge on\n"
           "                    the bus (processor in the loop, docs/pil.md; needs a socket bus)\n"
           "  --m7-image ELF    the image (default: $MD_M7_IMAGE, else\n"
           "                    <bin-dir>/../../cortex-m7/bin/microdrive-fw-m7.elf)\n"
           "  --qemu PATH       qemu-system-arm to use (default: $MD_QEMU, else through PATH)\n"
           "  --icount-shift N  virtual time of 2^N ns per instruction (default 1: ~500 MHz)\n"
           "                    (m7 also sets heartbeat_timeout_ms=10000 unless --param sets it)\n"
           "  --no-score        no report.json\n"
           "  --no-lcm          no session.lcmlog (md-lcm-bridge --write-log over candump.log and\n"
           "                    truth.jsonl); implies --no-plots\n"
           "  --no-plots        no PNG files (tools/plots/plot_session.py over session.lcmlog)\n"
           "  --no-recording    no recording.bin / recording.json (~0.6 MB per 10 s interval)\n"
           "  --candump-samples the REC_DATA frames (the samples, ~1.7 MB per 10 s interval) go into\n"
           "                    candump.log too; without it they are only in the recording\n"
           "  --quiet           no progress lines\n"
           "Progress: one line per electrode and cycle (TLM_STATUS). Exit: 0 goal reached, 4 ended idle\n"
           "before the goal (report written), 5 the session and its report are fine but the LCM log\n"
           "or the plots failed (message above), 1 runtime error, 2 usage.\n";
}

void session_cli_print_usage(FILE *f)
{
    (void)fputs(usage_options(), f);
    (void)fputs(usage_m7_and_outputs(), f);
}

static int parse_u64(const char *s, uint64_t *v)
{
    char *end = NULL;
    errno = 0;
    const unsigned long long x = strtoull(s, &end, 10);
    if (errno != 0 || end == s || *end != '\0' || s[0] == '-') {
        return -1;
    }
    *v = (uint64_t)x;
    return 0;
}

/// Longest --duration-s / --idle-s: both become microsecond counts (uint64),
/// so infinity or 1e300 must not get through (the simulator's limit).
#define SESSION_SECONDS_MAX 1e9

static int parse_double(const char *s, double *v)
{
    char *end = NULL;
    errno = 0;
    *v = strtod(s, &end);
    return (errno != 0 || end == s || *end != '\0' || !(*v >= 0.0) || !(*v <= SESSION_SECONDS_MAX)) ? -1 : 0;
}

/* Dense id of the parameter called `name` (md_params table), or -1. */
static int param_by_name(const char *name, size_t len)
{
    for (size_t i = 0u; i < md_params_count(); ++i) {
        const md_param_def_t *d = md_params_def(i);
        if (strlen(d->name) == len && strncmp(d->name, name, len) == 0) {
            return (int)i;
        }
    }
    return -1;
}

/* One --param NAME=VALUE: the name must exist and VALUE be a number; range
 * and integrality are checked later by md_params_set. */
static int cli_param(session_opts_t *o, const char *val, char *msg, size_t msglen)
{
    const char *eq = strchr(val, '=');
    if (o->n_params >= SESSION_MAX_PARAMS) {
        (void)snprintf(msg, msglen, "--param: more than %u", (unsigned)SESSION_MAX_PARAMS);
        return -1;
    }
    const int id = (eq == NULL) ? -1 : param_by_name(val, (size_t)(eq - val));
    if (id < 0) {
        (void)snprintf(msg, msglen,
                       "--param '%s': no parameter of that name (NAME=VALUE; list: microdrive-fw "
                       "--params-markdown)",
                       val);
        return -1;
    }
    char *end = NULL;
    errno = 0;
    const double v = strtod(eq + 1, &end);
    if (errno != 0 || end == eq + 1 || *end != '\0') {
        (void)snprintf(msg, msglen, "--param '%s': not a number", val);
        return -1;
    }
    session_param_t *p = &o->params[o->n_params++];
    p->arg = val;
    p->index = md_params_def((size_t)id)->index;
    p->value = v;
    return 0;
}

int session_apply_params(md_params_t *p, const session_opts_t *o, char *msg, size_t msglen)
{
    for (uint32_t i = 0u; i < o->n_params && i < SESSION_MAX_PARAMS; ++i) {
        const md_param_status_t st = md_params_set(p, o->params[i].index, o->params[i].value);
        if (st != MD_PARAM_OK) {
            const md_param_def_t *d = md_params_def((size_t)md_params_find(o->params[i].index));
            (void)snprintf(msg, msglen, "--param %s refused (status %d; range %g..%g%s)", o->params[i].arg, (int)st,
                           d->min, d->max, ((d->flags & MD_PARAM_F_INTEGER) != 0u) ? ", whole number" : "");
            return -1;
        }
    }
    return 0;
}

/* The options that take a number: 0, -1 for a bad value, 1 if opt is none of them. */
static int cli_number(session_opts_t *o, const char *opt, const char *val, bool *pace_given, bool *idle_given)
{
    uint64_t u = 0u;
    if (strcmp(opt, "--seed") == 0) {
        if (parse_u64(val, &o->seed) != 0) {
            return -1;
        }
        o->seed_given = true;
    } else if (strcmp(opt, "--cycles") == 0) {
        if (parse_u64(val, &u) != 0 || u == 0u || u > 65535u) {
            return -1;
        }
        o->cycles = (uint32_t)u;
    } else if (strcmp(opt, "--duration-s") == 0) {
        if (parse_double(val, &o->duration_s) != 0 || !(o->duration_s > 0.0)) {
            return -1;
        }
    } else if (strcmp(opt, "--idle-s") == 0) {
        if (parse_double(val, &o->idle_s) != 0 || !(o->idle_s > 0.0)) {
            return -1;
        }
        *idle_given = true;
    } else if (strcmp(opt, "--pace") == 0) {
        if (parse_u64(val, &u) != 0 || u > 10000000u) {
            return -1;
        }
        o->pace_fps = (uint32_t)u;
        *pace_given = true;
    } else if (strcmp(opt, "--icount-shift") == 0) {
        if (parse_u64(val, &u) != 0 || u > 10u) {
            return -1;
        }
        o->icount_shift = (uint32_t)u;
    } else {
        return 1;
    }
    return 0;
}

/* The options that take a text: 0, -1 for a bad value, 1 if opt is none of them. */
static int cli_text(session_opts_t *o, const char *opt, const char *val)
{
    if (strcmp(opt, "--controller") == 0) {
        if (strcmp(val, "host") == 0) {
            o->controller = SESSION_CTRL_HOST;
        } else if (strcmp(val, "m7") == 0) {
            o->controller = SESSION_CTRL_M7;
        } else {
            return -1;
        }
        return 0;
    }
    static const struct {
        const char *opt;
        size_t off;
    } text[] = {
        {"--scenario", offsetof(session_opts_t, scenario)}, {"--bus", offsetof(session_opts_t, bus)},
        {"--out", offsetof(session_opts_t, out)},           {"--bin-dir", offsetof(session_opts_t, bin_dir)},
        {"--python", offsetof(session_opts_t, python)},     {"--m7-image", offsetof(session_opts_t, m7_image)},
        {"--qemu", offsetof(session_opts_t, qemu)},
    };
    for (size_t i = 0u; i < sizeof text / sizeof text[0]; ++i) {
        if (strcmp(opt, text[i].opt) == 0) {
            memcpy((char *)o + text[i].off, &val, sizeof val);
            return 0;
        }
    }
    return 1;
}

static int cli_value(session_opts_t *o, const char *opt, const char *val, char *msg, size_t msglen, bool *pace_given,
                     bool *idle_given)
{
    if (strcmp(opt, "--param") == 0) {
        return cli_param(o, val, msg, msglen);
    }
    int r = cli_text(o, opt, val);
    if (r == 1) {
        r = cli_number(o, opt, val, pace_given, idle_given);
    }
    if (r == 1) {
        (void)snprintf(msg, msglen, "unknown option '%s'", opt);
        return -1;
    }
    if (r < 0) {
        (void)snprintf(msg, msglen, "%s: bad value '%s'", opt, val);
        return -1;
    }
    return 0;
}

/* A flag without a value: true if `a` is one (set in *o). */
static bool cli_flag(session_opts_t *o, const char *a)
{
    static const struct {
        const char *flag;
        size_t off;
        bool value;
    } flags[] = {
        {"--help", offsetof(session_opts_t, help), true},
        {"-h", offsetof(session_opts_t, help), true},
        {"--no-score", offsetof(session_opts_t, no_score), true},
        {"--quiet", offsetof(session_opts_t, quiet), true},
        {"--candump-samples", offsetof(session_opts_t, candump_samples), true},
        {"--no-sample-log", offsetof(session_opts_t, candump_samples), false}, /* the default; older command lines */
        {"--no-recording", offsetof(session_opts_t, no_recording), true},
        {"--no-lcm", offsetof(session_opts_t, no_lcm), true},
        {"--no-plots", offsetof(session_opts_t, no_plots), true},
    };
    for (size_t i = 0u; i < sizeof flags / sizeof flags[0]; ++i) {
        if (strcmp(a, flags[i].flag) == 0) {
            memcpy((char *)o + flags[i].off, &flags[i].value, sizeof(bool));
            return true;
        }
    }
    return false;
}

/* The Cortex-M7 controller's defaults for what the command line left unset, and its bus rule. */
static int cli_m7_defaults(session_opts_t *o, bool pace_given, bool idle_given, char *msg, size_t msglen)
{
    if (!pace_given) {
        o->pace_fps = SESSION_M7_PACE_FPS;
    }
    if (!idle_given) {
        o->idle_s = SESSION_M7_IDLE_S;
    }
    bool set = false;
    for (uint32_t i = 0u; i < o->n_params; ++i) {
        set = set || strncmp(o->params[i].arg, "heartbeat_timeout_ms=", 21) == 0;
    }
    /* first, so that a later --param of the same name would still win */
    if (!set && cli_param(o, SESSION_M7_HEARTBEAT_TIMEOUT, msg, msglen) != 0) {
        return -1;
    }
    if (strcmp(o->bus, "inproc") == 0 || strncmp(o->bus, "inproc:", 7) == 0) {
        (void)snprintf(msg, msglen,
                       "--controller m7 needs a socket bus (udp, vcan0, auto): QEMU and the bridge are "
                       "processes");
        return -1;
    }
    return 0;
}

int session_cli_parse(session_opts_t *o, int argc, char *const argv[], char *msg, size_t msglen)
{
    memset(o, 0, sizeof *o);
    o->bus = "auto";
    o->duration_s = -1.0;
    o->idle_s = 30.0;
    o->pace_fps = 10000u;
    o->icount_shift = 1u;
    bool pace_given = false;
    bool idle_given = false;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        if (cli_flag(o, a)) {
            if (o->help) {
                return 0;
            }
        } else if (i + 1 >= argc || strncmp(a, "--", 2) != 0) {
            (void)snprintf(msg, msglen, "'%s' needs a value or is not an option", a);
            return -1;
        } else if (cli_value(o, a, argv[++i], msg, msglen, &pace_given, &idle_given) != 0) {
            return -1;
        }
    }
    if (o->scenario == NULL || o->out == NULL) {
        (void)snprintf(msg, msglen, "--scenario and --out are required");
        return -1;
    }
    if (o->controller == SESSION_CTRL_M7 && cli_m7_defaults(o, pace_given, idle_given, msg, msglen) != 0) {
        return -1;
    }
    if (o->cycles > 0u && o->duration_s > 0.0) {
        (void)snprintf(msg, msglen, "give --cycles or --duration-s, not both");
        return -1;
    }
    /* every --param against a fresh table now, so a bad one stops nothing half-started */
    md_params_t scratch;
    if (md_params_init(&scratch) != MD_OK) {
        (void)snprintf(msg, msglen, "the controller's parameter table is inconsistent");
        return -1;
    }
    return session_apply_params(&scratch, o, msg, msglen);
}
