/// @file fuzz_cli.c
/// Fuzz target: the command-line parsers of the host programs, including the
/// three readers of `--param NAME=VALUE`:
///   byte 0 % 3 = 0  microdrive-fw   (firmware/port/posix/fw_cli.h: fw_cli_parse, then
///                                    fw_cli_configure on a fresh parameter table)
///                1  microdrive-session (tools/session/session_cli.c: session_cli_parse,
///                                    which checks every --param against a fresh table)
///                2  microdrive-sim  (host_sim/app/sim_cli.h: sim_cli_parse)
/// The rest of the input is argv[1..], one argument per NUL-separated piece
/// (at most 64), each an exact-size heap copy.
/// Invariants: documented return values; a refusal comes with a one-line
/// reason (fw: unless getopt_long printed it); an accepted command line has
/// its values in the documented ranges, finite; after fw_cli_configure or
/// session_cli_parse succeeds every parameter the table holds is finite,
/// within [min, max], whole when flagged integer, and the last --param of
/// each NAME is what the table holds (microdrive-fw) or what the session
/// will apply (session).
#include <getopt.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "fuzz_input.h"
#include "fw_cli.h"
#include "md_params.h"
#include "session.h"
#include "sim_cli.h"

#define MAX_ARGS 64

/* a == b without -Wfloat-equal (exact comparison intended). */
static bool same(double a, double b)
{
    return !(a < b) && !(a > b) && !isnan(a) && !isnan(b);
}

/* The parameter of the table called `name` (len bytes), or -1. */
static int param_named(const char *name, size_t len)
{
    for (size_t i = 0u; i < md_params_count(); ++i) {
        const md_param_def_t *d = md_params_def(i);
        if (strlen(d->name) == len && strncmp(d->name, name, len) == 0) {
            return (int)i;
        }
    }
    return -1;
}

static void check_table(const md_params_t *p)
{
    for (size_t i = 0u; i < md_params_count(); ++i) {
        const md_param_def_t *d = md_params_def(i);
        const double v = p->value[i];
        FUZZ_CHECK(isfinite(v) && v >= d->min && v <= d->max);
        FUZZ_CHECK((d->flags & MD_PARAM_F_INTEGER) == 0u || same(v, floor(v)));
    }
}

static void check_msg(const char *msg, size_t cap, bool required)
{
    FUZZ_CHECK(memchr(msg, '\0', cap) != NULL);
    FUZZ_CHECK(!required || msg[0] != '\0');
}

static void fuzz_fw(int argc, char **argv)
{
    fw_cli_t o;
    char msg[256];
    const fw_cli_result_t r = fw_cli_parse(argc, argv, &o, msg, sizeof msg);
    FUZZ_CHECK(r == FW_CLI_USAGE || r == FW_CLI_RUN || r == FW_CLI_HELP || r == FW_CLI_MARKDOWN);
    check_msg(msg, sizeof msg, false);
    if (r != FW_CLI_RUN) {
        return;
    }
    FUZZ_CHECK(o.bus_spec != NULL && o.n_param >= 0 && o.n_param <= FW_CLI_MAX_PARAMS);
    md_params_t p;
    FUZZ_CHECK(md_params_init(&p) == MD_OK);
    const int rc = fw_cli_configure(&p, &o, msg, sizeof msg);
    FUZZ_CHECK(rc == 0 || rc == -1);
    check_msg(msg, sizeof msg, rc != 0);
    if (rc != 0) {
        return;
    }
    FUZZ_CHECK(msg[0] == '\0');
    check_table(&p);
    if (o.auto_start != 0) {
        FUZZ_CHECK(md_params_get_u32(&p, MD_P_AUTO_START) == 1u || o.n_param > 0);
    }
    /* the last --param of each name is what the table holds */
    for (int i = 0; i < o.n_param; ++i) {
        const char *eq = strchr(o.param[i], '=');
        FUZZ_CHECK(eq != NULL);
        const int id = param_named(o.param[i], (size_t)(eq - o.param[i]));
        FUZZ_CHECK(id >= 0);
        bool last = true;
        for (int j = i + 1; j < o.n_param; ++j) {
            const char *eq2 = strchr(o.param[j], '=');
            last = last && !(eq2 != NULL && param_named(o.param[j], (size_t)(eq2 - o.param[j])) == id);
        }
        if (last) {
            FUZZ_CHECK(same(p.value[id], strtod(eq + 1, NULL)));
        }
    }
}

static void fuzz_session(int argc, char **argv)
{
    static session_opts_t o;
    char msg[512];
    msg[0] = '\0';
    const int rc = session_cli_parse(&o, argc, argv, msg, sizeof msg);
    FUZZ_CHECK(rc == 0 || rc == -1);
    check_msg(msg, sizeof msg, rc != 0);
    if (rc != 0 || o.help) {
        return;
    }
    FUZZ_CHECK(o.scenario != NULL && o.out != NULL && o.bus != NULL);
    FUZZ_CHECK(o.cycles <= 65535u && o.pace_fps <= 10000000u);
    /* both become microsecond counts (uint64): 1e9 s at most, as microdrive-sim's --duration-s */
    FUZZ_CHECK(same(o.duration_s, -1.0) || (o.duration_s > 0.0 && o.duration_s <= 1e9));
    FUZZ_CHECK(o.idle_s > 0.0 && o.idle_s <= 1e9);
    FUZZ_CHECK(!(o.cycles > 0u && o.duration_s > 0.0));
    FUZZ_CHECK(o.n_params <= SESSION_MAX_PARAMS);
    md_params_t p;
    FUZZ_CHECK(md_params_init(&p) == MD_OK);
    FUZZ_CHECK(session_apply_params(&p, &o, msg, sizeof msg) == 0);
    check_table(&p);
    for (uint32_t i = 0u; i < o.n_params; ++i) {
        FUZZ_CHECK(md_params_find(o.params[i].index) >= 0 && isfinite(o.params[i].value));
    }
}

static void fuzz_sim(int argc, char **argv)
{
    sim_cli_t c;
    char msg[512];
    msg[0] = '\0';
    const int rc = sim_cli_parse(&c, argc, argv, msg, sizeof msg);
    FUZZ_CHECK(rc == 0 || rc == -1);
    check_msg(msg, sizeof msg, rc != 0);
    if (rc != 0 || c.help) {
        return;
    }
    FUZZ_CHECK(c.scenario != NULL && c.scenario[0] != '\0' && c.bus != NULL);
    FUZZ_CHECK(same(c.hall_rate_hz, 0.0) || (c.hall_rate_hz >= 0.1 && c.hall_rate_hz <= 10000.0));
    FUZZ_CHECK(c.calib_period_ms >= 1u && c.calib_period_ms <= 86400000u);
    FUZZ_CHECK(same(c.duration_s, -1.0) || (isfinite(c.duration_s) && c.duration_s >= 0.0 && c.duration_s <= 1e9));
    FUZZ_CHECK(c.pace_fps <= 10000000u);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static const char *const PROG[3] = {"microdrive-fw", "microdrive-session", "microdrive-sim"};
    if (size == 0u) {
        return 0;
    }
    opterr = 0; /* getopt_long's own messages: not wanted 10^7 times */
    const unsigned which = data[0] % 3u;
    char *argv[MAX_ARGS + 2];
    int argc = 0;
    argv[argc++] = strdup(PROG[which]);
    size_t at = 1u;
    while (at < size && argc <= MAX_ARGS) {
        const uint8_t *z = memchr(&data[at], '\0', size - at);
        const size_t end = (z != NULL) ? (size_t)(z - data) : size;
        char *a = (char *)malloc(end - at + 1u);
        FUZZ_CHECK(a != NULL);
        memcpy(a, &data[at], end - at);
        a[end - at] = '\0';
        argv[argc++] = a;
        at = end + 1u;
    }
    argv[argc] = NULL;
    char *keep[MAX_ARGS + 2]; /* getopt_long may permute argv */
    memcpy(keep, argv, sizeof(char *) * (size_t)argc);
    switch (which) {
    case 0u: fuzz_fw(argc, argv); break;
    case 1u: fuzz_session(argc, argv); break;
    default: fuzz_sim(argc, argv); break;
    }
    for (int i = 0; i < argc; ++i) {
        free(keep[i]);
    }
    return 0;
}
