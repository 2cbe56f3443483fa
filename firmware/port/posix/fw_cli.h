/// @file fw_cli.h
/// Command line of microdrive-fw (main_posix.c): option parsing and the
/// parameter settings it asks for (--param NAME=VALUE, --heartbeat-ms, ...).
/// No I/O besides getopt_long's own message for an unknown option; no heap.
/// tests/fuzz/fuzz_cli.c fuzzes both functions.
#ifndef FW_CLI_H
#define FW_CLI_H

#include <stddef.h>

#include "md_params.h"

/// --param options taken at most.
#define FW_CLI_MAX_PARAMS 32

typedef struct {
    const char *bus_spec;                  ///< --bus SPEC ("auto" unless given)
    const char *heartbeat_ms;              ///< --heartbeat-ms N (NULL: not given)
    const char *heartbeat_timeout_ms;      ///< --heartbeat-timeout-ms N (NULL: not given)
    int auto_start;                        ///< --auto-start
    const char *param[FW_CLI_MAX_PARAMS];  ///< --param "NAME=VALUE", in command-line order
    int n_param;
} fw_cli_t;

/// What fw_cli_parse found.
typedef enum {
    FW_CLI_USAGE = -1,   ///< usage error (reason in msg, or already printed by getopt_long)
    FW_CLI_RUN = 0,      ///< run the controller with *o
    FW_CLI_HELP = 1,     ///< --help: print the usage, exit 0
    FW_CLI_MARKDOWN = 2  ///< --params-markdown: print the parameter table, exit 0
} fw_cli_result_t;

/// Parses argv into *o (defaults first). Restarts getopt_long (optind = 0),
/// so it can be called more than once. msg gets a one-line reason (or "").
fw_cli_result_t fw_cli_parse(int argc, char **argv, fw_cli_t *o, char *msg, size_t msglen);

/// Applies the settings of *o to the parameter table p, in order
/// (--heartbeat-ms, --heartbeat-timeout-ms, --auto-start, then every --param),
/// each through md_params_set, the checks of a set over the bus. Returns 0,
/// or -1 at the first one refused with a one-line reason in msg: an unknown
/// NAME, a VALUE that is not a number, a value out of range.
int fw_cli_configure(md_params_t *p, const fw_cli_t *o, char *msg, size_t msglen);

#endif
