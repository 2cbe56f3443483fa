/// microdrive-sim: the plant nodes of the microdrive on a bus, or the export of
/// a scripted recording. Design: docs/sim-process.md.
#include <errno.h>
#include <inttypes.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "export/sim_export.h"
#include "md_bus.h"
#include "md_bus_fault.h"
#include "md_can.h"
#include "scenario/scenario.h"
#include "sim_cli.h"
#include "simnode_bus_fault.h"
#include "simnode_plant.h"
#include "simnode_world.h"

#define SIMPROC_HB_PERIOD_US ((uint64_t)MD_CAN_HEARTBEAT_ACT_CYCLE_TIME_MS * 1000u)
#define SIMPROC_MAX_WAIT_US 100000  ///< longest receive wait: signals and heartbeats stay prompt
#define SIMPROC_PACE_BURST 64u      ///< frames a paced sender may send back to back
#define SIMPROC_TX_RETRIES 200u     ///< 1 ms waits on a full transmit queue before giving up

static const md_node_id_t SIMPROC_NODES[3] = {MD_NODE_ACT, MD_NODE_HALL, MD_NODE_FE};

typedef struct {
    md_bus_t raw_bus;                               ///< the endpoint as opened
    md_bus_fault_t fault[SCENARIO_BUS_FAULTS_MAX];  ///< the scenario's bus faults, nested around it
    uint32_t n_fault;
    md_bus_t *busp;  ///< what the plant uses: the outermost wrapper or raw_bus
    simnode_plant_t plant;
    uint64_t origin_us;  ///< wall time of simulated time 0 (realtime)
    uint64_t next_hb_us;
    uint64_t node_origin_us[3];  ///< wall time of each node's last (re)boot
    uint32_t node_resets_seen[3];
    uint32_t pace_fps;
    uint64_t pace_t0_us, pace_sent, last_tx_us;
    uint64_t tx_frames, tx_errors, tx_retries, heartbeats, hb_silenced;
    uint64_t tx_abandoned;  ///< frames of the batch in progress not sent after SIGINT/SIGTERM
    uint32_t since_hb_check;
} simproc_t;

static volatile sig_atomic_t g_stop = 0;

static void on_signal(int sig)
{
    g_stop = sig;
}

static uint64_t mono_us(void)
{
    struct timespec ts;
    (void)clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

static void sleep_us(uint64_t us)
{
    struct timespec ts = {(time_t)(us / 1000000u), (long)((us % 1000000u) * 1000u)};
    (void)nanosleep(&ts, NULL);
}

static void send_heartbeats(simproc_t *sp, uint64_t now)
{
    simnode_plant_silence_at(&sp->plant, sp->plant.now_us);
    for (uint32_t i = 0; i < 3u; i++) {
        const simnode_t *n = simnode_plant_node(&sp->plant, SIMPROC_NODES[i]);
        if (n->resets != sp->node_resets_seen[i]) { /* an NMT reset restarts the uptime */
            sp->node_resets_seen[i] = n->resets;
            sp->node_origin_us[i] = now;
        }
        if (n->silent) { /* injected node silence: heartbeat included */
            sp->hb_silenced++;
            continue;
        }
        md_frame_t f;
        simnode_heartbeat_frame(n, (uint32_t)((now - sp->node_origin_us[i]) / 1000000u), &f);
        if (md_bus_send(sp->busp, &f) < 0) {
            sp->tx_errors++;
        } else {
            sp->heartbeats++;
        }
    }
}

/* Heartbeats run on the wall clock whatever simulated time does, so that a
 * controller can tell a dead simulator from a quiet one. */
static void heartbeat_check(simproc_t *sp, uint64_t now)
{
    if (now < sp->next_hb_us) {
        return;
    }
    send_heartbeats(sp, now);
    sp->next_hb_us += SIMPROC_HB_PERIOD_US;
    if (sp->next_hb_us <= now) {
        sp->next_hb_us = now + SIMPROC_HB_PERIOD_US;
    }
}

/* Token bucket: at most pace_fps frames per wall second after a burst. */
static void pace(simproc_t *sp, uint64_t now)
{
    if (sp->pace_fps == 0u) {
        return;
    }
    if (now - sp->last_tx_us > 100000u) {
        sp->pace_t0_us = now;
        sp->pace_sent = 0u;
    }
    sp->last_tx_us = now;
    if (++sp->pace_sent <= SIMPROC_PACE_BURST) {
        return;
    }
    const uint64_t due = sp->pace_t0_us + (sp->pace_sent - SIMPROC_PACE_BURST) * 1000000u / sp->pace_fps;
    if (due > now) {
        sleep_us(due - now);
    }
}

/* The plant's sink: pacing, bounded retry on a full queue, heartbeats
 * interleaved during long lockstep batches. */
static int simproc_send(void *ctx, const md_frame_t *f)
{
    simproc_t *sp = ctx;
    if (g_stop != 0) {
        /* Told to stop: the rest of the batch in progress is not sent, so
         * the process exits at once even where a batch takes seconds of
         * wall time (a loaded machine, flow control waiting for a reader). */
        sp->tx_abandoned++;
        return -ECANCELED;
    }
    uint64_t now = mono_us();
    pace(sp, now);
    int rc = md_bus_send(sp->busp, f);
    for (uint32_t i = 0; rc == -EAGAIN && i < SIMPROC_TX_RETRIES && g_stop == 0; i++) {
        sp->tx_retries++;
        sleep_us(1000u);
        rc = md_bus_send(sp->busp, f);
    }
    if (rc < 0) {
        sp->tx_errors++;
    } else {
        sp->tx_frames++;
    }
    if (++sp->since_hb_check >= 32u) {
        sp->since_hb_check = 0u;
        heartbeat_check(sp, mono_us());
    }
    return rc;
}

static void print_stats(simproc_t *sp)
{
    const simnode_plant_stats_t *ps = &sp->plant.stats;
    fprintf(stderr,
            "microdrive-sim: sim time %.6f s; rx %" PRIu64 " (ignored %" PRIu64 ", malformed %" PRIu64
            ", foreign clock %" PRIu64 ", steps %" PRIu64 "); tx %" PRIu64 " + %" PRIu64
            " heartbeats, tx errors %" PRIu64 ", retries %" PRIu64 ", not sent after the stop signal %" PRIu64
            "; bus rx overflow %" PRIu64 "\n",
            (double)sp->plant.now_us * 1e-6, ps->rx_frames, ps->rx_ignored, ps->rx_malformed, ps->rx_foreign_clock,
            ps->steps, sp->tx_frames, sp->heartbeats, sp->tx_errors, sp->tx_retries, sp->tx_abandoned,
            sp->raw_bus.stats.rx_overflow);
    char bus_stats[200];
    (void)md_bus_stats_format(&sp->raw_bus.stats, bus_stats, sizeof bus_stats);
    fprintf(stderr, "microdrive-sim: %s\n", bus_stats);
    for (uint32_t i = 0; i < 3u; i++) {
        const simnode_t *n = simnode_plant_node(&sp->plant, SIMPROC_NODES[i]);
        fprintf(stderr,
                "microdrive-sim: node %u state %u: rx %" PRIu64 ", malformed %" PRIu64 ", refused %" PRIu64
                ", tx %" PRIu64 ", tx errors %" PRIu64 ", emcy %" PRIu64 "\n",
                (unsigned)n->id, (unsigned)n->state, n->stats.rx_frames, n->stats.rx_malformed, n->stats.rx_refused,
                n->stats.tx_frames, n->stats.tx_errors, n->stats.emcy_sent);
    }
}

static void install_signals(void)
{
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal; /* no SA_RESTART: a waiting receive returns at once */
    (void)sigemptyset(&sa.sa_mask);
    (void)sigaction(SIGINT, &sa, NULL);
    (void)sigaction(SIGTERM, &sa, NULL);
}

/* Wall-clock wait until the next thing to do: heartbeat, or (realtime) the
 * plant's next event. */
static int64_t wait_budget_us(const simproc_t *sp, uint64_t now)
{
    uint64_t until = sp->next_hb_us;
    if (!sp->plant.cfg.lockstep) {
        const uint64_t ev = simnode_plant_next_event_us(&sp->plant);
        if (ev != UINT64_MAX && sp->origin_us + ev < until) {
            until = sp->origin_us + ev;
        }
    }
    const uint64_t w = (until > now) ? until - now : 0u;
    return (w > (uint64_t)SIMPROC_MAX_WAIT_US) ? SIMPROC_MAX_WAIT_US : (int64_t)w;
}

/* Serves the bus until a signal, the simulated duration or a bus error. */
static int simproc_loop(simproc_t *sp, uint64_t duration_us)
{
    for (;;) { /* runs until told to stop: the process's main loop */
        const uint64_t now = mono_us();
        heartbeat_check(sp, now);
        if (!sp->plant.cfg.lockstep) {
            (void)simnode_plant_advance(&sp->plant, now - sp->origin_us);
        }
        if (g_stop != 0) {
            fprintf(stderr, "microdrive-sim: signal %d, exiting\n", (int)g_stop);
            return 0;
        }
        if (duration_us > 0u && sp->plant.now_us >= duration_us) {
            fprintf(stderr, "microdrive-sim: simulated duration reached, exiting\n");
            return 0;
        }
        md_frame_t f;
        const int rc = md_bus_receive(sp->busp, &f, wait_budget_us(sp, mono_us()));
        if (rc == 1) {
            simnode_plant_handle(&sp->plant, &f);
        } else if (rc < 0 && rc != -EINTR) {
            fprintf(stderr, "microdrive-sim: bus receive failed: %s\n", strerror(-rc));
            return 1;
        }
    }
}

/* Runs the plant on the open bus until the end of the session. */
static int serve(simproc_t *sp, const sim_cli_t *cli, const scenario_t *sc, simnode_world_t *world, uint64_t seed)
{
    simnode_plant_cfg_t cfg;
    simnode_plant_cfg_default(&cfg);
    cfg.lockstep = !cli->realtime;
    cfg.autostart = cli->autostart;
    cfg.hall_rate_hz = cli->hall_rate_hz;
    cfg.calib_period_ms = cli->calib_period_ms;
    const simnode_sink_t sink = {simproc_send, sp};
    if (simnode_plant_init(&sp->plant, &cfg, world, sink) != MD_OK) {
        fprintf(stderr, "microdrive-sim: the scenario's plant cannot be served\n");
        return 1;
    }
    const double dur = (cli->duration_s >= 0.0) ? cli->duration_s : sc->duration_s;
    sp->pace_fps = cli->realtime ? 0u : cli->pace_fps;
    sp->origin_us = mono_us();
    for (uint32_t i = 0; i < 3u; i++) {
        sp->node_origin_us[i] = sp->origin_us;
    }
    fprintf(stderr, "microdrive-sim: nodes 2, 3, 4; %u electrodes; %s mode; seed %" PRIu64 "\n",
            (unsigned)simnode_world_electrodes(world), cli->realtime ? "realtime" : "lockstep", seed);
    send_heartbeats(sp, sp->origin_us); /* boot-up messages (NodeState 0) */
    sp->next_hb_us = sp->origin_us + SIMPROC_HB_PERIOD_US;
    simnode_plant_start(&sp->plant);
    install_signals();
    const int rc = simproc_loop(sp, (dur > 0.0) ? (uint64_t)(dur * 1e6) : 0u);
    print_stats(sp);
    return rc;
}

static int64_t fault_clock(void *ctx)
{
    const simproc_t *sp = ctx;
    return (int64_t)sp->plant.now_us; /* fault windows are simulated time */
}

/* The scenario's bus faults (scenario.h): one md_bus_fault wrapper each
 * around the endpoint (tx = frames the simulator sends, rx = frames it
 * receives), seeded from the session seed and the fault's index. */
static int wrap_bus_faults(simproc_t *sp, const scenario_t *sc, uint64_t seed)
{
    sp->busp = &sp->raw_bus;
    for (uint32_t i = 0; i < sc->faults.n_bus && i < SCENARIO_BUS_FAULTS_MAX; i++) {
        const scenario_bus_fault_t *b = &sc->faults.bus[i];
        md_bus_fault_params_t p;
        simnode_bus_fault_params(b, seed, i, &p);
        if (md_bus_fault_wrap(&sp->fault[i], sp->busp, &p, fault_clock, sp) != 0) {
            fprintf(stderr, "microdrive-sim: bus fault %u of the scenario is invalid\n", (unsigned)i);
            return 1;
        }
        sp->busp = &sp->fault[i].bus;
        sp->n_fault = i + 1u;
    }
    return 0;
}

/* What the fault injection did (docs/safety.md); nothing without faults. */
static void print_faults(const simproc_t *sp, const scenario_t *sc)
{
    for (uint32_t i = 0; i < sp->n_fault; i++) {
        simnode_bus_fault_print(stderr, "microdrive-sim", i, &sp->fault[i]);
    }
    if (sc->faults.n_silent > 0u) {
        fprintf(stderr,
                "microdrive-sim: node silence: frames swallowed act %" PRIu64 ", hall %" PRIu64 ", fe %" PRIu64
                "; heartbeats not sent %" PRIu64 "\n",
                sp->plant.act.node.stats.tx_silenced, sp->plant.hall.node.stats.tx_silenced,
                sp->plant.fe.node.stats.tx_silenced, sp->hb_silenced);
    }
    if (sc->faults.n_restarts > 0u) {
        fprintf(stderr, "microdrive-sim: controller_restart is done by the launcher (in-process sessions only)\n");
    }
}

static int run_bus(const sim_cli_t *cli, const scenario_t *sc, uint64_t seed)
{
    char err[1024];
    simnode_world_t *world = simnode_world_create_scenario(sc, seed, err, sizeof err);
    if (world == NULL) {
        fprintf(stderr, "microdrive-sim: %s\n", err);
        return 1;
    }
    FILE *truth = NULL;
    if (cli->truth != NULL && (truth = fopen(cli->truth, "w")) == NULL) {
        fprintf(stderr, "microdrive-sim: cannot write %s: %s\n", cli->truth, strerror(errno));
        simnode_world_destroy(world);
        return 1;
    }
    simnode_world_set_truth(world, truth);
    simproc_t *sp = calloc(1u, sizeof *sp); /* md_bus_t must not move while open */
    int rc = (sp == NULL) ? -ENOMEM : md_bus_open(&sp->raw_bus, cli->bus, err, sizeof err);
    if (rc == 0 && sp->raw_bus.kind == MD_BUS_INPROC) {
        md_bus_close(&sp->raw_bus);
        snprintf(err, sizeof err, "an in-process bus has no other node in this process");
        rc = -EINVAL;
    }
    if (rc != 0) {
        fprintf(stderr, "microdrive-sim: cannot open bus '%s': %s\n", cli->bus, (sp != NULL) ? err : "no memory");
    } else {
        fprintf(stderr, "microdrive-sim: bus %s (%s)\n", sp->raw_bus.name, err);
        rc = wrap_bus_faults(sp, sc, seed);
        if (rc == 0) {
            rc = serve(sp, cli, sc, world, seed);
            print_faults(sp, sc);
        }
        md_bus_close(sp->busp); /* closes the wrappers' chain and the endpoint */
    }
    free(sp);
    if (truth != NULL) {
        (void)fclose(truth);
    }
    simnode_world_destroy(world);
    return (rc == 0) ? 0 : 1;
}

int main(int argc, char *argv[])
{
    sim_cli_t cli;
    char msg[1024];
    if (sim_cli_parse(&cli, argc, argv, msg, sizeof msg) != 0) {
        fprintf(stderr, "microdrive-sim: %s (try --help)\n", msg);
        return 2;
    }
    if (cli.help) {
        fputs(sim_cli_usage(), stdout);
        return 0;
    }
    scenario_t *sc = malloc(sizeof *sc);
    if (sc == NULL || scenario_load(sc, cli.scenario, msg, sizeof msg) != 0) {
        fprintf(stderr, "microdrive-sim: %s", (sc != NULL) ? msg : "out of memory\n");
        free(sc);
        return 1;
    }
    const uint64_t seed = cli.seed_given ? cli.seed : sc->seed;
    int rc;
    if (cli.export_dir != NULL) {
        const md_status_t st = sim_export_recording(sc, seed, cli.export_dir, msg, sizeof msg);
        if (st == MD_OK) {
            fprintf(stderr, "microdrive-sim: recording of '%s' (seed %" PRIu64 ") written to %s\n", sc->name, seed,
                    cli.export_dir);
        } else {
            fprintf(stderr, "microdrive-sim: export failed: %s\n", msg);
        }
        rc = (st == MD_OK) ? 0 : 1;
    } else {
        rc = run_bus(&cli, sc, seed);
    }
    free(sc);
    return rc;
}
