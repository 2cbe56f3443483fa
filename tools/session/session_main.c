/// @file session_main.c
/// microdrive-session: starts the simulator and the controller, records every
/// frame, shows progress per cycle, scores the session against the
/// simulator's ground truth (tools/session/score.py -> report.json), writes
/// the session's LCM log (md-lcm-bridge --write-log -> session.lcmlog) and
/// plots it (tools/plots/plot_session.py -> *.png).
/// Design and report format: docs/session.md; telemetry: docs/telemetry.md.
#include <errno.h>
#include <inttypes.h>
#include <libgen.h>
#include <limits.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "md_bus.h"
#include "scenario/scenario.h"
#include "session.h"

#ifndef MD_SESSION_PYTHON
#define MD_SESSION_PYTHON "python3"
#endif
#ifndef MD_SESSION_SCORER
#define MD_SESSION_SCORER "score.py"
#endif

#ifndef MD_SESSION_PLOTTER
#define MD_SESSION_PLOTTER "plot_session.py"
#endif
#ifndef MD_SESSION_LCM_TYPES
#define MD_SESSION_LCM_TYPES ""
#endif

#define SESSION_EXIT_IDLE 4
/// The session and its report are fine, but its LCM log or plots are not.
#define SESSION_EXIT_TELEMETRY 5

volatile int session_stop_signal = 0;

static void on_signal(int sig)
{
    session_stop_signal = sig;
}

static void install_signals(void)
{
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    (void)sigemptyset(&sa.sa_mask);
    (void)sigaction(SIGINT, &sa, NULL);
    (void)sigaction(SIGTERM, &sa, NULL);
}

static int mkdir_p(const char *path)
{
    char buf[PATH_MAX];
    (void)snprintf(buf, sizeof buf, "%s", path);
    for (char *p = buf + 1; *p != '\0'; p++) {
        if (*p == '/') {
            *p = '\0';
            if (mkdir(buf, 0755) != 0 && errno != EEXIST) {
                return -1;
            }
            *p = '/';
        }
    }
    return (mkdir(buf, 0755) != 0 && errno != EEXIST) ? -1 : 0;
}

/* The directory of this executable (build/<preset>/bin). */
static void self_dir(char *out, size_t len)
{
    char exe[PATH_MAX];
    const ssize_t n = readlink("/proc/self/exe", exe, sizeof exe - 1u);
    if (n <= 0) {
        (void)snprintf(out, len, ".");
        return;
    }
    exe[n] = '\0';
    (void)snprintf(out, len, "%s", dirname(exe));
}

/* The interpreter for score.py and the plots: --python, $MD_PYTHON, the
 * project venv this build was configured with, else a .venv in a folder
 * above this executable (a checkout that moved). NULL when there is none. */
static const char *pick_python(const session_opts_t *o)
{
    static char found[PATH_MAX + 32];
    if (o->python != NULL) {
        return o->python;
    }
    const char *env = getenv("MD_PYTHON");
    if (env != NULL && env[0] != '\0') {
        return env;
    }
    if (access(MD_SESSION_PYTHON, X_OK) == 0) {
        return MD_SESSION_PYTHON;
    }
    char dir[PATH_MAX];
    self_dir(dir, sizeof dir);
    for (int up = 0; up < 8; up++) { /* build/<preset>/bin is three below the checkout */
        (void)snprintf(found, sizeof found, "%s/.venv/bin/python", dir);
        if (access(found, X_OK) == 0) {
            return found;
        }
        char *slash = strrchr(dir, '/');
        if (slash == NULL || slash == dir) {
            break;
        }
        *slash = '\0';
    }
    return NULL;
}

/* What to run when there is no interpreter for `what`. */
static void no_python(const char *what)
{
    char dir[PATH_MAX];
    self_dir(dir, sizeof dir);
    fprintf(stderr,
            "microdrive-session: no Python for %s: the project venv %s is missing (and no .venv above %s).\n"
            "  Make it: scripts/setup-venv.sh in the checkout (or configure the build: cmake --preset release);\n"
            "  or pass --python PY (an interpreter with requirements.txt installed); --no-score / --no-lcm skip it.\n",
            what, MD_SESSION_PYTHON, dir);
}

/* Runs argv (argv[0] through PATH); returns its exit status, -1 if it died
 * by a signal or could not be waited for, 127 if it could not be started. */
static int run_child(char *const argv[])
{
    (void)fflush(stdout);
    (void)fflush(stderr);
    const pid_t pid = fork();
    if (pid == 0) {
        execvp(argv[0], argv);
        fprintf(stderr, "microdrive-session: cannot run %s: %s\n", argv[0], strerror(errno));
        _exit(127);
    }
    int status = 0;
    if (pid < 0 || waitpid(pid, &status, 0) != pid) {
        return -1;
    }
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

/* Path from the environment variable `env` if set, else `def`. */
static void env_or(char *out, size_t len, const char *env, const char *def)
{
    const char *v = getenv(env);
    (void)snprintf(out, len, "%s", (v != NULL && v[0] != '\0') ? v : def);
}

/* DIR/session.lcmlog from DIR/candump.log and DIR/truth.jsonl: the bridge in
 * log mode writes the same LCM event log lcm-logger would record from a live
 * bridge, byte-identical on every run, for both bus kinds (docs/telemetry.md). */
static int run_bridge(const session_opts_t *o)
{
    static char bridge[PATH_MAX], def[PATH_MAX], log[PATH_MAX], truth[PATH_MAX], out[PATH_MAX];
    (void)snprintf(def, sizeof def, "%s/md-lcm-bridge", o->bin_dir);
    env_or(bridge, sizeof bridge, "MD_SESSION_BRIDGE", def);
    (void)snprintf(log, sizeof log, "%s/candump.log", o->out);
    (void)snprintf(truth, sizeof truth, "%s/truth.jsonl", o->out);
    (void)snprintf(out, sizeof out, "%s/session.lcmlog", o->out);
    if (access(bridge, X_OK) != 0) {
        fprintf(stderr, "microdrive-session: LCM log: no %s (built only with libcjson-dev; --no-lcm to skip)\n",
                bridge);
        return -1;
    }
    char *const argv[] = {bridge, "--from-log", log, "--truth", truth, "--write-log", out, "--quiet", NULL};
    return run_child(argv);
}

/* The PNG files of DIR from DIR/session.lcmlog. */
static int run_plots(const session_opts_t *o)
{
    static char py[PATH_MAX], plotter[PATH_MAX], log[PATH_MAX], out[PATH_MAX], types[PATH_MAX], label[PATH_MAX];
    static char scen[PATH_MAX];
    (void)snprintf(scen, sizeof scen, "%s", o->scenario);
    char *base = basename(scen);
    char *dot = strrchr(base, '.');
    if (dot != NULL && dot != base) {
        *dot = '\0';
    }
    (void)snprintf(label, sizeof label, "%s seed %" PRIu64, base, o->seed);
    const char *python = pick_python(o);
    if (python == NULL) {
        no_python("the plots (tools/plots/plot_session.py)");
        return -1;
    }
    (void)snprintf(py, sizeof py, "%s", python);
    env_or(plotter, sizeof plotter, "MD_SESSION_PLOTTER", MD_SESSION_PLOTTER);
    env_or(types, sizeof types, "MD_LCM_TYPES", MD_SESSION_LCM_TYPES);
    (void)snprintf(log, sizeof log, "%s/session.lcmlog", o->out);
    (void)snprintf(out, sizeof out, "%s", o->out);
    char *const with_types[] = {py, plotter, log, "--out", out, "--label", label, "--types", types, "--quiet", NULL};
    char *const without[] = {py, plotter, log, "--out", out, "--label", label, "--quiet", NULL};
    return run_child(types[0] != '\0' ? with_types : without);
}

/* The LCM log, then the plots; each failure named. 0 ok, -1 one failed. */
static int run_telemetry(const session_opts_t *o)
{
    if (o->no_lcm) {
        if (!o->no_plots) {
            fprintf(stderr, "microdrive-session: no plots: they are drawn from session.lcmlog (--no-lcm)\n");
        }
        return 0;
    }
    const int b = run_bridge(o);
    if (b != 0) {
        fprintf(stderr, "microdrive-session: LCM log failed: md-lcm-bridge exit %d; %s/session.lcmlog is not valid\n",
                b, o->out);
        return -1;
    }
    fprintf(stderr, "microdrive-session: LCM log %s/session.lcmlog\n", o->out);
    if (o->no_plots) {
        return 0;
    }
    const int p = run_plots(o);
    if (p != 0) {
        fprintf(stderr, "microdrive-session: plots failed: plot_session.py exit %d\n", p);
        return -1;
    }
    fprintf(stderr, "microdrive-session: plots %s/{tracks_pc,waveforms,status,hypotheses,truth}.png\n", o->out);
    return 0;
}

/* Runs score.py; returns its exit status (0 ok). */
static int run_scorer(const session_opts_t *o, const char *bus_label, const char *end_name)
{
    static char py[PATH_MAX], scorer[PATH_MAX], scen[PATH_MAX], log[PATH_MAX], truth[PATH_MAX], report[PATH_MAX];
    static char seed[32], goal[64], bus[64], end[32];
    const char *env_scorer = getenv("MD_SESSION_SCORER");
    (void)snprintf(scorer, sizeof scorer, "%s",
                   (env_scorer != NULL && env_scorer[0] != '\0') ? env_scorer : MD_SESSION_SCORER);
    const char *python = pick_python(o);
    if (python == NULL) {
        no_python("the report (tools/session/score.py)");
        return -1;
    }
    (void)snprintf(py, sizeof py, "%s", python);
    (void)snprintf(scen, sizeof scen, "%s", o->scenario);
    (void)snprintf(log, sizeof log, "%s/candump.log", o->out);
    (void)snprintf(truth, sizeof truth, "%s/truth.jsonl", o->out);
    (void)snprintf(report, sizeof report, "%s/report.json", o->out);
    (void)snprintf(seed, sizeof seed, "%" PRIu64, o->seed);
    (void)snprintf(bus, sizeof bus, "%s", bus_label);
    (void)snprintf(end, sizeof end, "%s", end_name);
    if (o->cycles > 0u) {
        (void)snprintf(goal, sizeof goal, "%u", (unsigned)o->cycles);
    } else {
        (void)snprintf(goal, sizeof goal, "%.6f", o->duration_s);
    }
    char *const argv[] = {py,
                          scorer,
                          "--log",
                          log,
                          "--truth",
                          truth,
                          "--out",
                          report,
                          "--scenario",
                          scen,
                          "--seed",
                          seed,
                          "--bus",
                          bus,
                          "--end",
                          end,
                          o->cycles > 0u ? "--cycles" : "--duration-s",
                          goal,
                          NULL};
    return run_child(argv);
}

static bool bus_is_inproc(const char *bus)
{
    return strcmp(bus, "inproc") == 0 || strncmp(bus, "inproc:", 7) == 0;
}

/* Runs the session of the parsed options; returns the end and the bus label. */
static session_end_t run(session_opts_t *o, const scenario_t *sc, char *bus_label, size_t len)
{
    static session_rec_t rec;
    const uint32_t electrodes = sc->n_electrodes;
    char path[PATH_MAX];
    (void)snprintf(path, sizeof path, "%s/candump.log", o->out);
    FILE *log = fopen(path, "w");
    if (log == NULL) {
        fprintf(stderr, "microdrive-session: cannot write %s: %s\n", path, strerror(errno));
        return SESSION_END_ERROR;
    }
    session_track_t track;
    const session_goal_t goal = {o->cycles, (o->cycles > 0u) ? 0u : (uint64_t)(o->duration_s * 1e6)};
    session_track_init(&track, log, "inproc", electrodes, goal, o->quiet);
    track.log_samples = o->candump_samples;
    if (!o->no_recording) {
        char msg[SESSION_REC_PATH_MAX + 64u];
        if (session_rec_open(&rec, o->out, electrodes, sc->name, o->seed, msg, sizeof msg) != 0) {
            fprintf(stderr, "microdrive-session: %s\n", msg);
            (void)fclose(log);
            return SESSION_END_ERROR;
        }
        track.rec = &rec;
    }
    session_end_t end;
    if (bus_is_inproc(o->bus)) {
        (void)snprintf(bus_label, len, "inproc");
        (void)snprintf(path, sizeof path, "%s/truth.jsonl", o->out);
        FILE *truth = fopen(path, "w");
        if (truth == NULL) {
            fprintf(stderr, "microdrive-session: cannot write %s: %s\n", path, strerror(errno));
            (void)fclose(log);
            session_rec_abandon(&rec);
            return SESSION_END_ERROR;
        }
        fprintf(stderr, "microdrive-session: bus inproc (simulator and controller in this process, virtual clock)\n");
        track.stamp_sim = true; /* the virtual clock stands still while the controller works */
        end = session_run_inproc(o, "inproc:session", &track, truth);
        (void)fclose(truth);
    } else {
        char used[64] = "";
        end = session_run_procs(o, &track, used, sizeof used);
        (void)snprintf(bus_label, len, "%s", (strncmp(used, "udp", 3) == 0) ? "udp" : used);
    }
    (void)fclose(log);
    session_track_summary(&track, stderr);
    if (session_rec_close(track.rec, stderr) != 0 && end != SESSION_END_SIGNAL) {
        end = SESSION_END_ERROR;
    }
    return end;
}

int main(int argc, char *argv[])
{
    static session_opts_t o;
    static scenario_t sc;
    char msg[1024], bin_dir[PATH_MAX];
    if (session_cli_parse(&o, argc, argv, msg, sizeof msg) != 0) {
        fprintf(stderr, "microdrive-session: %s\n", msg);
        session_cli_print_usage(stderr);
        return 2;
    }
    if (o.help) {
        session_cli_print_usage(stdout);
        return 0;
    }
    if (scenario_load(&sc, o.scenario, msg, sizeof msg) != 0) {
        fprintf(stderr, "microdrive-session: %s", msg);
        return 2;
    }
    if (!o.seed_given) {
        o.seed = sc.seed;
    }
    if (o.cycles == 0u && !(o.duration_s > 0.0)) {
        o.duration_s = sc.duration_s;
    }
    if (o.bin_dir == NULL) {
        self_dir(bin_dir, sizeof bin_dir);
        o.bin_dir = bin_dir;
    }
    if (mkdir_p(o.out) != 0) {
        fprintf(stderr, "microdrive-session: cannot create %s: %s\n", o.out, strerror(errno));
        return 1;
    }
    install_signals();
    char bus_label[64];
    const session_end_t end = run(&o, &sc, bus_label, sizeof bus_label);
    fprintf(stderr, "microdrive-session: ended: %s\n", session_end_name(end));
    if (end == SESSION_END_ERROR || end == SESSION_END_SIGNAL) {
        return 1;
    }
    if (!o.no_score && run_scorer(&o, bus_label, end == SESSION_END_GOAL ? "goal" : "idle") != 0) {
        fprintf(stderr, "microdrive-session: scoring failed\n");
        return 1;
    }
    if (run_telemetry(&o) != 0) {
        return SESSION_EXIT_TELEMETRY;
    }
    return (end == SESSION_END_GOAL) ? 0 : SESSION_EXIT_IDLE;
}
