/// @file fw_cli.c
/// Command line of microdrive-fw (see fw_cli.h).
#include "fw_cli.h"

#include <errno.h>
#include <getopt.h>
#include <stdio.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

static void set_msg(char *msg, size_t msglen, const char *text)
{
    if (msg != NULL && msglen > 0u) {
        (void)snprintf(msg, msglen, "%s", text);
    }
}

/* Applies one setting through the same checks as a bus set; `opt` is the
 * option as given ("--heartbeat-ms", "--param NAME=VALUE"), for messages. */
static int set_param(md_params_t *p, uint16_t index, const char *text, const char *opt, char *msg, size_t msglen)
{
    char *end = NULL;
    errno = 0;
    const double v = strtod(text, &end);
    if (errno != 0 || end == text || *end != '\0') {
        if (msg != NULL && msglen > 0u) {
            (void)snprintf(msg, msglen, "%s: '%s' is not a number", opt, text);
        }
        return -1;
    }
    const md_param_status_t st = md_params_set(p, index, v);
    if (st != MD_PARAM_OK) {
        const md_param_def_t *d = md_params_def((size_t)md_params_find(index));
        if (msg != NULL && msglen > 0u) {
            (void)snprintf(msg, msglen, "%s: %s rejected (status %d; range %g..%g%s)", opt, text, (int)st, d->min,
                           d->max, ((d->flags & MD_PARAM_F_INTEGER) != 0u) ? ", whole number" : "");
        }
        return -1;
    }
    return 0;
}

/* One --param NAME=VALUE: NAME looked up in the parameter table. */
static int set_named_param(md_params_t *p, const char *arg, char *msg, size_t msglen)
{
    const char *eq = strchr(arg, '=');
    const ptrdiff_t name_len = (eq == NULL) ? 0 : eq - arg;
    const size_t len = (size_t)name_len;
    for (size_t i = 0u; i < md_params_count() && len > 0u; ++i) {
        const md_param_def_t *d = md_params_def(i);
        if (strlen(d->name) == len && strncmp(d->name, arg, len) == 0) {
            char opt[128];
            (void)snprintf(opt, sizeof opt, "--param %s", d->name);
            return set_param(p, d->index, eq + 1, opt, msg, msglen);
        }
    }
    if (msg != NULL && msglen > 0u) {
        (void)snprintf(msg, msglen, "--param '%s': no parameter of that name (NAME=VALUE; see --params-markdown)", arg);
    }
    return -1;
}

fw_cli_result_t fw_cli_parse(int argc, char **argv, fw_cli_t *o, char *msg, size_t msglen)
{
    static const struct option LONG_OPTS[] = {{"bus", required_argument, NULL, 'b'},
                                              {"heartbeat-ms", required_argument, NULL, 'h'},
                                              {"heartbeat-timeout-ms", required_argument, NULL, 't'},
                                              {"auto-start", no_argument, NULL, 'a'},
                                              {"params-markdown", no_argument, NULL, 'm'},
                                              {"help", no_argument, NULL, 'H'},
                                              {"param", required_argument, NULL, 'p'},
                                              {NULL, 0, NULL, 0}};
    memset(o, 0, sizeof *o);
    o->bus_spec = "auto";
    set_msg(msg, msglen, "");
    optind = 0; /* glibc: a full restart of the scan */
    for (int guard = 0; guard < argc + 1; ++guard) {
        const int c = getopt_long(argc, argv, "", LONG_OPTS, NULL);
        switch (c) {
        case -1:
            if (optind != argc) {
                set_msg(msg, msglen, "unexpected argument (every option starts with --)");
                return FW_CLI_USAGE;
            }
            return FW_CLI_RUN;
        case 'b': o->bus_spec = optarg; break;
        case 'h': o->heartbeat_ms = optarg; break;
        case 't': o->heartbeat_timeout_ms = optarg; break;
        case 'a': o->auto_start = 1; break;
        case 'p':
            if (o->n_param >= FW_CLI_MAX_PARAMS) {
                if (msg != NULL && msglen > 0u) {
                    (void)snprintf(msg, msglen, "more than %d --param", FW_CLI_MAX_PARAMS);
                }
                return FW_CLI_USAGE;
            }
            o->param[o->n_param++] = optarg;
            break;
        case 'm': return FW_CLI_MARKDOWN;
        case 'H': return FW_CLI_HELP;
        default: return FW_CLI_USAGE; /* getopt_long printed why */
        }
    }
    return FW_CLI_USAGE;
}

int fw_cli_configure(md_params_t *p, const fw_cli_t *o, char *msg, size_t msglen)
{
    set_msg(msg, msglen, "");
    if (o->heartbeat_ms != NULL && set_param(p, md_params_def(MD_P_HEARTBEAT_PERIOD_MS)->index, o->heartbeat_ms,
                                             "--heartbeat-ms", msg, msglen) != 0) {
        return -1;
    }
    if (o->heartbeat_timeout_ms != NULL &&
        set_param(p, md_params_def(MD_P_HEARTBEAT_TIMEOUT_MS)->index, o->heartbeat_timeout_ms, "--heartbeat-timeout-ms",
                  msg, msglen) != 0) {
        return -1;
    }
    if (o->auto_start != 0 &&
        set_param(p, md_params_def(MD_P_AUTO_START)->index, "1", "--auto-start", msg, msglen) != 0) {
        return -1;
    }
    for (int i = 0; i < o->n_param && i < FW_CLI_MAX_PARAMS; ++i) {
        if (set_named_param(p, o->param[i], msg, msglen) != 0) {
            return -1;
        }
    }
    return 0;
}
