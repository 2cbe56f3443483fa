/// @file main_posix.c
/// microdrive-fw: the controller firmware as a Linux process. The platform
/// part of the libcanard pattern: owns the bus endpoint and the clock, pushes
/// received frames into the controller (md_controller.h: node + electrode
/// cycles), sleeps in the bus receive until the controller's next deadline.
/// No heap (md_no_heap.h; the binary is checked with nm).
#include <errno.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <stddef.h>
#include <string.h>
#include <time.h>

#include "fw_cli.h"
#include "md_bus.h"
#include "md_controller.h"

/// Longest single wait in the receive call, so that a signal is noticed soon
/// even though the bus layer restarts its wait after EINTR.
#define MAX_WAIT_US 50000

/// Frames handled per loop pass at most before the node is polled again, so a
/// flooded bus cannot starve the heartbeat and the supervision.
#define RX_BURST 64

/// Queued frames handed over at most before each poll (bounds the drain on a
/// bus flooded faster than it is read; the queue of a socket is finite).
#define RX_DRAIN_MAX 4096

typedef struct {
    md_bus_t bus;
    uint64_t send_failures;
} posix_port_ctx_t;

static volatile sig_atomic_t g_stop;

static void on_signal(int sig)
{
    (void)sig;
    g_stop = 1;
}

static uint64_t mono_us(void)
{
    struct timespec ts;
    (void)clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

static md_status_t port_send(void *ctx, const md_frame_t *frame)
{
    posix_port_ctx_t *p = ctx;
    if (md_bus_send(&p->bus, frame) != 0) {
        p->send_failures++;
        return MD_E_IO;
    }
    return MD_OK;
}

static uint64_t port_now_us(void *ctx)
{
    (void)ctx;
    return mono_us();
}

static void usage(FILE *out)
{
    (void)fprintf(out, "usage: microdrive-fw [--bus SPEC] [--heartbeat-ms N] [--heartbeat-timeout-ms N]\n"
                       "                     [--auto-start] [--param NAME=VALUE]... [--params-markdown] [--help]\n"
                       "  --bus SPEC               auto (default: vcan0 if present, else udp), udp, udp:PORT,\n"
                       "                           vcan0/can0/<ifname>, inproc:NAME\n"
                       "  --heartbeat-ms N         heartbeat period (parameter 0x1017)\n"
                       "  --heartbeat-timeout-ms N heartbeat consumer timeout (parameter 0x1016)\n"
                       "  --auto-start             go operational after boot (parameter 0x1F80)\n"
                       "  --param NAME=VALUE       set parameter NAME (see --params-markdown) before the start, with\n"
                       "                           the checks of a set over the bus; repeatable, applied in order\n"
                       "  --params-markdown        print the parameter table (docs/protocol.md) and exit\n"
                       "SIGINT/SIGTERM end the process cleanly.\n");
}

static void print_params_markdown(void)
{
    (void)printf("| index | name | unit | min | max | default | access | meaning |\n");
    (void)printf("|---|---|---|---|---|---|---|---|\n");
    for (size_t i = 0u; i < md_params_count(); ++i) {
        const md_param_def_t *d = md_params_def(i);
        const char *access = ((d->flags & MD_PARAM_F_READ_ONLY) != 0u) ? "ro"
                             : ((d->flags & MD_PARAM_F_MOTION) != 0u)  ? "rw, refused while e-stop latched"
                             : ((d->flags & MD_PARAM_F_CONFIG) != 0u)  ? "rw, refused while operational"
                                                                       : "rw";
        (void)printf("| 0x%04X | %s | %s | %.10g | %.10g | %.10g | %s%s | %s |\n", (unsigned)d->index, d->name, d->unit,
                     d->min, d->max, d->def, access, ((d->flags & MD_PARAM_F_INTEGER) != 0u) ? ", integer" : "",
                     d->doc);
    }
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

/* Hands every frame already queued on the bus to the controller (receive
 * with a zero timeout until none is left, at most RX_DRAIN_MAX), so that the
 * supervision after a long processing step sees the heartbeats that arrived
 * meanwhile instead of reporting them lost. */
static void drain(md_controller_t *ctl, posix_port_ctx_t *pc, uint64_t *bus_errors)
{
    for (int k = 0; k < RX_DRAIN_MAX && g_stop == 0; ++k) {
        md_frame_t frame;
        const int r = md_bus_receive(&pc->bus, &frame, 0);
        if (r == 1) {
            md_controller_on_frame(ctl, &frame, mono_us()); /* rejections are counted by the node */
            continue;
        }
        if (r < 0) {
            (*bus_errors)++;
            if (*bus_errors <= 10u) {
                (void)fprintf(stderr, "microdrive-fw: receive failed: %s\n", strerror(-r));
            }
        }
        return;
    }
}

/* The platform loop: drain the queue, poll, then wait for a frame until the
 * next deadline. */
static int run(md_controller_t *ctl, posix_port_ctx_t *pc)
{
    uint64_t bus_errors = 0u;
    while (g_stop == 0) {
        drain(ctl, pc, &bus_errors);
        md_controller_poll(ctl, mono_us()); /* failures are counted by the node */
        for (int burst = 0; burst < RX_BURST && g_stop == 0; ++burst) {
            const uint64_t now = mono_us();
            const uint64_t deadline = md_controller_next_deadline_us(ctl);
            if (deadline <= now) {
                break; /* periodic work is due */
            }
            const int64_t wait_us = (deadline - now > MAX_WAIT_US) ? MAX_WAIT_US : (int64_t)(deadline - now);
            md_frame_t frame;
            const int r = md_bus_receive(&pc->bus, &frame, wait_us);
            if (r == 1) {
                md_controller_on_frame(ctl, &frame, mono_us()); /* rejections are counted by the node */
                continue;
            }
            if (r < 0) {
                bus_errors++;
                if (bus_errors <= 10u) {
                    (void)fprintf(stderr, "microdrive-fw: receive failed: %s\n", strerror(-r));
                }
            }
            break;
        }
    }
    return (int)(bus_errors > 0u);
}

static void print_summary(const md_node_t *node, const posix_port_ctx_t *pc)
{
    const md_node_counters_t *c = &node->counters;
    (void)fprintf(stderr,
                  "microdrive-fw: exit: rx %u (malformed %u, unknown id %u, bad length %u, bad range %u, "
                  "bad sequence %u, id conflict %u), tx %u, send failures %u (port %llu), emcy %u, "
                  "heartbeat lost %u, e-stops %u, cycles %u (skipped %u, recordings failed %u, moves failed %u)%s\n",
                  (unsigned)c->rx_frames, (unsigned)c->rx_malformed, (unsigned)c->rx_unknown_id,
                  (unsigned)c->rx_bad_length, (unsigned)c->rx_bad_range, (unsigned)c->rx_bad_sequence,
                  (unsigned)c->rx_id_conflict, (unsigned)c->tx_frames, (unsigned)c->tx_failures,
                  (unsigned long long)pc->send_failures, (unsigned)c->emcy_sent, (unsigned)c->heartbeat_lost,
                  (unsigned)c->estop_events, (unsigned)c->cycles_done, (unsigned)c->cycles_skipped,
                  (unsigned)c->rec_failed, (unsigned)c->moves_failed, node->estop_latched ? ", e-stop LATCHED" : "");
}

int main(int argc, char **argv)
{
    md_controller_t *ctl = md_controller_instance(); /* the controller's whole state: static, no heap */
    md_node_t *node = md_controller_node(ctl);
    static posix_port_ctx_t port_ctx;
    static fw_cli_t opt;
    char msg[256];
    const fw_cli_result_t parsed = fw_cli_parse(argc, argv, &opt, msg, sizeof msg);
    if (parsed == FW_CLI_HELP) {
        usage(stdout);
        return 0;
    }
    if (parsed == FW_CLI_MARKDOWN) {
        print_params_markdown();
        return 0;
    }
    if (parsed != FW_CLI_RUN) {
        if (msg[0] != '\0') {
            (void)fprintf(stderr, "microdrive-fw: %s\n", msg);
        }
        usage(stderr);
        return 2;
    }
    const md_port_t port = {port_send, port_now_us, &port_ctx, NULL, NULL}; /* no work counter on a host */
    if (md_controller_init(ctl, &port, mono_us()) != MD_OK) {
        return 2;
    }
    if (fw_cli_configure(&node->params, &opt, msg, sizeof msg) != 0) {
        (void)fprintf(stderr, "microdrive-fw: %s\n", msg);
        return 2;
    }
    char why[160];
    const int rc = md_bus_open(&port_ctx.bus, opt.bus_spec, why, sizeof why);
    if (rc != 0) {
        (void)fprintf(stderr, "microdrive-fw: cannot open bus '%s': %s (%s)\n", opt.bus_spec, strerror(-rc), why);
        return 3;
    }
    (void)fprintf(stderr, "microdrive-fw: bus %s: %s\n", port_ctx.bus.name, why);
    (void)fprintf(stderr, "microdrive-fw: node %u, protocol %u, %u electrodes, heartbeat %u ms, timeout %u ms\n",
                  (unsigned)MD_NODE_CTRL, (unsigned)MD_PROTOCOL_VERSION, (unsigned)MD_ELECTRODES,
                  (unsigned)md_params_get_u32(&node->params, MD_P_HEARTBEAT_PERIOD_MS),
                  (unsigned)md_params_get_u32(&node->params, MD_P_HEARTBEAT_TIMEOUT_MS));
    install_signals();
    const int loop_rc = run(ctl, &port_ctx);
    print_summary(node, &port_ctx);
    char stats[200];
    (void)md_bus_stats_format(&port_ctx.bus.stats, stats, sizeof stats);
    (void)fprintf(stderr, "microdrive-fw: %s\n", stats);
    md_bus_close(&port_ctx.bus);
    return loop_rc == 0 ? 0 : 1;
}
