/// @file fuzz_scenario.c
/// Fuzz target: the simulator's scenario parser (host_sim/scenario/scenario.h,
/// libyaml document API) through scenario_parse, the same entry point
/// scenario_load uses after reading the file. The whole input is the YAML
/// text, in an exact-size heap copy without a terminating NUL (so ASan sees
/// any read past the length the parser was given).
/// Invariants: the error count is >= 0; the messages are NUL-terminated
/// inside the buffer, one line "fuzz.yaml:LINE: reason" per error (as many
/// lines as errors when the buffer did not fill up), nothing when the count
/// is 0; a scenario with no error is valid: 1..SIM_MAX_ELECTRODES
/// electrodes, neurons and faults within their capacities, restarts
/// ascending, and its world builds (scenario_make_world returns MD_OK).
#include <ctype.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "fuzz_input.h"
#include "scenario/scenario.h"

#define ERR_LEN 65536u

static scenario_t g_sc;
static sim_world_t g_world;
static char g_err[ERR_LEN];

/* One line "fuzz.yaml:LINE: reason" (LINE >= 1), n bytes without its '\n'. */
static void check_line(const char *s, size_t n)
{
    static const char PREFIX[] = "fuzz.yaml:";
    size_t i = sizeof PREFIX - 1u;
    bool ok = n > i && memcmp(s, PREFIX, i) == 0 && isdigit((unsigned char)s[i]) && s[i] != '0';
    while (ok && i < n && isdigit((unsigned char)s[i])) {
        i++;
    }
    ok = ok && i + 2u < n && s[i] == ':' && s[i + 1u] == ' ';
    if (!ok) {
        (void)fprintf(stderr, "not a \"fuzz.yaml:LINE: reason\" line: '%.*s' in:\n%s", (int)n, s, g_err);
    }
    FUZZ_CHECK(ok);
}

static void check_messages(int errors)
{
    const size_t len = strlen(g_err);
    FUZZ_CHECK(len < ERR_LEN);
    if (errors == 0) {
        FUZZ_CHECK(len == 0u);
        return;
    }
    FUZZ_CHECK(len > 0u);
    const bool full = len + 1u >= ERR_LEN - 2000u; /* a message may have been cut or left out */
    int lines = 0;
    size_t at = 0u;
    while (at < len) {
        const char *nl = memchr(&g_err[at], '\n', len - at);
        if (nl == NULL) {
            FUZZ_CHECK(full); /* only a truncated message lacks its newline */
            break;
        }
        (void)check_line(&g_err[at], (size_t)(nl - &g_err[at]));
        lines++;
        at = (size_t)(nl - g_err) + 1u;
    }
    FUZZ_CHECK(lines <= errors);
    FUZZ_CHECK(full || lines == errors);
}

static void check_valid(void)
{
    const scenario_t *sc = &g_sc;
    FUZZ_CHECK(memchr(sc->name, '\0', sizeof sc->name) != NULL);
    FUZZ_CHECK(sc->n_electrodes >= 1u && sc->n_electrodes <= SIM_MAX_ELECTRODES);
    FUZZ_CHECK(isfinite(sc->duration_s) && sc->duration_s >= 0.0);
    for (uint32_t e = 0u; e < sc->n_electrodes; ++e) {
        FUZZ_CHECK(sc->electrodes[e].n_neurons <= SIM_MAX_NEURONS);
        FUZZ_CHECK(isfinite(sc->electrodes[e].start_um));
    }
    const scenario_faults_t *f = &sc->faults;
    FUZZ_CHECK(f->n_bus <= SCENARIO_BUS_FAULTS_MAX && f->n_silent <= SCENARIO_SILENT_MAX &&
               f->n_restarts <= SCENARIO_RESTARTS_MAX);
    for (uint32_t i = 0u; i < f->n_bus; ++i) {
        const scenario_bus_fault_t *b = &f->bus[i];
        FUZZ_CHECK(b->kind <= 4u && b->prob >= 0.0 && b->prob <= 1.0);
        FUZZ_CHECK(b->directions >= 1u && b->directions <= 3u);
        FUZZ_CHECK(!(b->from_s > b->to_s));
    }
    for (uint32_t i = 0u; i < f->n_silent; ++i) {
        FUZZ_CHECK(f->silent[i].node >= 2u && f->silent[i].node <= 4u);
        FUZZ_CHECK(!(f->silent[i].from_s > f->silent[i].to_s));
    }
    for (uint32_t i = 1u; i < f->n_restarts; ++i) {
        FUZZ_CHECK(f->restart_at_s[i - 1u] <= f->restart_at_s[i]);
    }
    FUZZ_CHECK(isfinite(sc->export_cfg.interval_s) && sc->export_cfg.interval_s > 0.0 &&
               sc->export_cfg.intervals >= 1u);
    FUZZ_CHECK(scenario_make_world(sc, sc->seed, &g_world) == MD_OK);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    char *text = (char *)malloc(size > 0u ? size : 1u);
    FUZZ_CHECK(text != NULL);
    if (size > 0u) {
        memcpy(text, data, size);
    }
    memset(g_err, 0x55, sizeof g_err); /* no stale terminator to hide a missing one */
    const int errors = scenario_parse(&g_sc, text, size, "fuzz.yaml", g_err, sizeof g_err);
    free(text);
    FUZZ_CHECK(errors >= 0);
    FUZZ_CHECK(memchr(g_err, '\0', sizeof g_err) != NULL);
    check_messages(errors);
    if (errors == 0) {
        check_valid();
    }
    return 0;
}
