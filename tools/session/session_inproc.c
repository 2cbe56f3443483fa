/// @file session_inproc.c
/// The in-process session: the simulator's plant nodes (md_simnode) and the
/// controller (md_controller.h) in one thread, on an `inproc:` bus with three
/// endpoints (plant, controller, recorder), driven by a virtual clock.
///
/// Order of events (docs/session.md, "In-process mode"):
///  - The plant's frames are delivered at once from its sink: the controller
///    and the recorder drain their queues after every plant frame, so a
///    10 s interval (10 000 REC_DATA frames) never fills a queue.
///  - The controller's frames queue for the plant; the main loop hands them
///    to the plant one by one (each one a lockstep batch), exactly the order
///    in which a socket bus would deliver them.
///  - The virtual clock stands still while anything is queued or the
///    controller has work due; then it jumps to the next deadline (the
///    controller's, or the plant's next heartbeat every 100 ms).
///  - The virtual clock is never behind the plant's simulated time: when a
///    lockstep batch moves simulated time (a 10 s recording), the clock
///    follows it frame by frame, and every plant heartbeat and controller
///    deadline that falls in between happens at its time, as on a real bus
///    where the recording takes 10 s. Log time stamps are this clock.
/// The clock is the controller's platform time; the plant's simulated time
/// moves only by the controller's commands (lockstep), as in microdrive-sim.
///
/// Fault injection (docs/safety.md): the scenario's bus faults wrap the
/// plant's endpoint in md_bus_fault (one wrapper per fault, nested, seeded
/// from the session seed, windows on this clock); node silences act in the
/// plant (simnode_plant_silence_at; heartbeats included); a controller
/// restart re-initialises the controller like a power cycle. The counters
/// are printed at the end.
#include <inttypes.h>
#include <stdlib.h>
#include <string.h>

#include "md_bus.h"
#include "md_bus_fault.h"
#include "md_can.h"
#include "md_controller.h"
#include "md_params.h"
#include "session.h"
#include "simnode_bus_fault.h"
#include "simnode_plant.h"
#include "simnode_world.h"

#define INPROC_HB_PERIOD_US ((uint64_t)MD_CAN_HEARTBEAT_ACT_CYCLE_TIME_MS * 1000u)
/// Polls of the controller at one instant before the clock must move on.
#define INPROC_POLL_GUARD 100000u

static const md_node_id_t INPROC_PLANT_NODES[3] = {MD_NODE_ACT, MD_NODE_HALL, MD_NODE_FE};

typedef struct {
    md_bus_t plant_ep, ctrl_ep, rec_ep;            /* must not move while open: static */
    md_bus_fault_t fault[SCENARIO_BUS_FAULTS_MAX]; /* nested around plant_ep */
    uint32_t n_fault;
    md_bus_t *plant_bus;             /* the plant's endpoint as used: outermost wrapper */
    const scenario_faults_t *faults; /* the scenario's (borrowed from the world) */
    const session_opts_t *opts;
    simnode_plant_t plant;
    md_controller_t *ctrl;
    session_track_t *track;
    uint64_t now_us; /* the virtual clock */
    uint64_t next_hb_us;
    uint64_t bus_errors;
    uint64_t hb_silenced; /* plant heartbeats not sent: node silent */
    uint32_t restarts;    /* controller restarts done */
    bool restart_pending; /* due while the controller was on the stack */
    bool in_ctrl;         /* the controller is on the stack: no re-entry */
    bool in_follow;       /* clock_follow on the stack: no re-entry */
} inproc_t;

static inproc_t g_ip;

static void drain_recorder(inproc_t *ip)
{
    md_frame_t f;
    while (md_bus_receive(&ip->rec_ep, &f, 0) == 1) {
        session_track_frame(ip->track, &f, ip->now_us);
    }
}

/* Everything queued for the controller, in order. Frames it sends meanwhile
 * queue for the plant and the recorder. */
static void drain_controller(inproc_t *ip)
{
    md_frame_t f;
    if (ip->in_ctrl) {
        return;
    }
    ip->in_ctrl = true;
    while (md_bus_receive(&ip->ctrl_ep, &f, 0) == 1) {
        md_controller_on_frame(ip->ctrl, &f, ip->now_us);
        drain_recorder(ip);
    }
    ip->in_ctrl = false;
}

/* One plant frame onto the bus, then everyone who can receive it. */
static int plant_deliver(inproc_t *ip, const md_frame_t *f)
{
    const int rc = md_bus_send(ip->plant_bus, f);
    if (rc != 0) {
        ip->bus_errors++;
    }
    drain_recorder(ip);
    drain_controller(ip);
    return rc;
}

static void clock_follow(inproc_t *ip, uint64_t t_us);

static int plant_sink(void *ctx, const md_frame_t *f)
{
    inproc_t *ip = ctx;
    clock_follow(ip, ip->plant.now_us); /* the frame happens at the plant's time */
    return plant_deliver(ip, f);
}

static md_status_t ctrl_send(void *ctx, const md_frame_t *f)
{
    inproc_t *ip = ctx;
    const int rc = md_bus_send(&ip->ctrl_ep, f);
    drain_recorder(ip);
    if (rc != 0) {
        ip->bus_errors++;
        return MD_E_IO;
    }
    return MD_OK;
}

static uint64_t ctrl_now(void *ctx)
{
    const inproc_t *ip = ctx;
    return ip->now_us;
}

static void plant_heartbeats(inproc_t *ip)
{
    simnode_plant_silence_at(&ip->plant, ip->now_us);
    for (uint32_t i = 0; i < 3u; i++) {
        const simnode_t *n = simnode_plant_node(&ip->plant, INPROC_PLANT_NODES[i]);
        if (n->silent) {
            ip->hb_silenced++;
            continue;
        }
        md_frame_t f;
        simnode_heartbeat_frame(n, (uint32_t)(ip->now_us / 1000000u), &f);
        (void)plant_deliver(ip, &f);
    }
}

/* Hands every frame queued for the plant to it; each may cause a batch. */
static bool serve_plant(inproc_t *ip)
{
    md_frame_t f;
    bool any = false;
    while (md_bus_receive(ip->plant_bus, &f, 0) == 1) {
        simnode_plant_handle(&ip->plant, &f);
        any = true;
    }
    return any;
}

static void poll_controller(inproc_t *ip)
{
    drain_controller(ip);
    md_controller_poll(ip->ctrl, ip->now_us);
    drain_recorder(ip);
}

static int64_t fault_clock(void *ctx)
{
    const inproc_t *ip = ctx;
    return (int64_t)ip->now_us;
}

/* The scenario's bus faults (scenario.h), one md_bus_fault wrapper each
 * around the plant's endpoint: tx = frames the plant sends, rx = frames it
 * receives. Each stream is seeded from the session seed and its index. */
static int wrap_bus_faults(inproc_t *ip)
{
    ip->plant_bus = &ip->plant_ep;
    for (uint32_t i = 0; i < ip->faults->n_bus && i < SCENARIO_BUS_FAULTS_MAX; i++) {
        const scenario_bus_fault_t *b = &ip->faults->bus[i];
        md_bus_fault_params_t p;
        simnode_bus_fault_params(b, ip->opts->seed, i, &p);
        if (md_bus_fault_wrap(&ip->fault[i], ip->plant_bus, &p, fault_clock, ip) != 0) {
            fprintf(stderr, "microdrive-session: bus fault %u of the scenario is invalid\n", (unsigned)i);
            return -1;
        }
        ip->plant_bus = &ip->fault[i].bus;
        ip->n_fault = i + 1u;
    }
    return 0;
}

static int open_endpoints(inproc_t *ip, const char *spec)
{
    char why[160];
    if (md_bus_open(&ip->plant_ep, spec, why, sizeof why) != 0 ||
        md_bus_open(&ip->ctrl_ep, spec, why, sizeof why) != 0 || md_bus_open(&ip->rec_ep, spec, why, sizeof why) != 0) {
        fprintf(stderr, "microdrive-session: cannot open %s: %s\n", spec, why);
        return -1;
    }
    return wrap_bus_faults(ip);
}

/* Power-on of the controller (session start, or an injected restart): init
 * with the compile-time defaults, the operator's parameter writes, the boot
 * (boot-up heartbeat, pre-operational), then the launcher, as the NMT
 * master, starts it with an NMT start that the log shows. */
static int ctrl_boot(inproc_t *ip)
{
    const md_port_t port = {ctrl_send, ctrl_now, ip, NULL, NULL};
    ip->ctrl = md_controller_instance();
    if (md_controller_init(ip->ctrl, &port, ip->now_us) != MD_OK) {
        fprintf(stderr, "microdrive-session: controller init failed\n");
        return -1;
    }
    const session_opts_t *o = ip->opts;
    char why[200]; /* --param NAME=VALUE, checked at parse time, applied here before the start */
    if (session_apply_params(&md_controller_node(ip->ctrl)->params, o, why, sizeof why) != 0) {
        fprintf(stderr, "microdrive-session: %s\n", why);
        return -1;
    }
    poll_controller(ip); /* boot-up heartbeat (state 0), pre-operational */
    struct md_can_nmt_t nmt = {.nmt_command = (uint8_t)MD_NMT_START, .nmt_target = (uint8_t)MD_NODE_CTRL};
    md_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = MD_CAN_NMT_FRAME_ID;
    f.len = (uint8_t)MD_CAN_NMT_LENGTH;
    (void)md_can_nmt_pack(f.data, &nmt, sizeof f.data);
    if (md_bus_send(&ip->rec_ep, &f) != 0) { /* the recorder's endpoint is the operator's */
        ip->bus_errors++;
    }
    session_track_frame(ip->track, &f, ip->now_us); /* an endpoint does not receive its own frames */
    poll_controller(ip);
    return 0;
}

static void ctrl_restart(inproc_t *ip)
{
    ip->restart_pending = false;
    ip->restarts++;
    if (ctrl_boot(ip) != 0) {
        ip->bus_errors++; /* cannot happen after a first boot that worked; counted, not hidden */
    }
}

/* Moves the clock forward to t_us; a controller restart due in between
 * happens now (or as soon as the controller is off the stack). */
static void clock_set(inproc_t *ip, uint64_t t_us)
{
    if (t_us <= ip->now_us) {
        return;
    }
    if (scenario_faults_restarts_due(ip->faults, (double)ip->now_us * 1e-6, (double)t_us * 1e-6) > 0u) {
        ip->restart_pending = true;
    }
    ip->now_us = t_us;
    if (ip->restart_pending && !ip->in_ctrl) {
        ctrl_restart(ip);
    }
}

/* Brings the clock up to t_us (the plant's simulated time), with every
 * plant heartbeat and controller deadline in between at its own time. */
static void clock_follow(inproc_t *ip, uint64_t t_us)
{
    if (ip->in_follow || t_us <= ip->now_us) {
        return;
    }
    ip->in_follow = true;
    for (uint32_t i = 0; i < INPROC_POLL_GUARD && ip->now_us < t_us; i++) {
        uint64_t next = t_us;
        const uint64_t d = md_controller_next_deadline_us(ip->ctrl);
        next = (d > ip->now_us && d < next) ? d : next;
        next = (ip->next_hb_us < next) ? ip->next_hb_us : next;
        clock_set(ip, next);
        if (ip->now_us >= ip->next_hb_us) {
            plant_heartbeats(ip);
            ip->next_hb_us += INPROC_HB_PERIOD_US;
        }
        if (!ip->in_ctrl) {
            poll_controller(ip);
        }
    }
    clock_set(ip, t_us);
    ip->in_follow = false;
}

static int start_nodes(inproc_t *ip, simnode_world_t *world)
{
    if (ctrl_boot(ip) != 0) {
        return -1;
    }
    simnode_plant_cfg_t cfg;
    simnode_plant_cfg_default(&cfg);
    const simnode_sink_t sink = {plant_sink, ip};
    if (simnode_plant_init(&ip->plant, &cfg, world, sink) != MD_OK) {
        fprintf(stderr, "microdrive-session: the scenario's plant cannot be served\n");
        return -1;
    }
    /* the controller boots first (its boot-up heartbeat), then the simulator
     * process: boot-up heartbeats, then the plant's start-up batch */
    plant_heartbeats(ip);
    ip->next_hb_us = ip->now_us + INPROC_HB_PERIOD_US;
    simnode_plant_start(&ip->plant);
    return 0;
}

static session_end_t inproc_loop(inproc_t *ip, uint64_t idle_us)
{
    uint64_t last_activity = ip->track->activity, activity_at = ip->now_us;
    uint32_t spins = 0u; /* passes at one instant without any frame: a controller that never rests */
    for (;;) {           /* ends by the goal, idleness or a signal */
        const bool served = serve_plant(ip);
        clock_follow(ip, ip->plant.now_us); /* a batch that sent nothing may still have moved time */
        poll_controller(ip);
        if (session_track_done(ip->track)) {
            return SESSION_END_GOAL;
        }
        if (session_stop_signal != 0) {
            return SESSION_END_SIGNAL;
        }
        if (ip->track->activity != last_activity) {
            last_activity = ip->track->activity;
            activity_at = ip->now_us;
            spins = 0u;
        } else if (ip->now_us - activity_at >= idle_us) {
            return SESSION_END_IDLE;
        }
        const uint64_t d = md_controller_next_deadline_us(ip->ctrl);
        if (served || d <= ip->now_us) {
            if (++spins > INPROC_POLL_GUARD) {
                fprintf(stderr, "microdrive-session: the controller has work at %" PRIu64 " us forever\n", ip->now_us);
                return SESSION_END_ERROR;
            }
            continue; /* answers and due work first: the clock stands still */
        }
        clock_set(ip, (d < ip->next_hb_us) ? d : ip->next_hb_us);
        if (ip->now_us >= ip->next_hb_us) {
            plant_heartbeats(ip);
            ip->next_hb_us += INPROC_HB_PERIOD_US;
        }
    }
}

/* What the fault injection did, so that a reader of the output sees that
 * the faults happened (docs/safety.md). Nothing when the scenario has none. */
static void print_faults(const inproc_t *ip)
{
    const simnode_world_fault_counts_t m = simnode_world_fault_counts(ip->plant.world);
    if (m.hall_glitches + m.hall_stuck_reads + m.act_stalls + m.act_slips + m.storm_events + m.saturated_samples > 0u) {
        fprintf(stderr,
                "microdrive-session: model faults: hall glitches %" PRIu64 ", hall stuck reads %" PRIu64
                ", actuator stalls %" PRIu64 ", actuator slips %" PRIu64 ", storm events %" PRIu64
                ", saturated samples %" PRIu64 "\n",
                m.hall_glitches, m.hall_stuck_reads, m.act_stalls, m.act_slips, m.storm_events, m.saturated_samples);
    }
    for (uint32_t i = 0; i < ip->n_fault; i++) {
        simnode_bus_fault_print(stderr, "microdrive-session", i, &ip->fault[i]);
    }
    if (ip->faults->n_silent > 0u) {
        fprintf(stderr,
                "microdrive-session: node silence: frames swallowed act %" PRIu64 ", hall %" PRIu64 ", fe %" PRIu64
                "; heartbeats not sent %" PRIu64 "\n",
                ip->plant.act.node.stats.tx_silenced, ip->plant.hall.node.stats.tx_silenced,
                ip->plant.fe.node.stats.tx_silenced, ip->hb_silenced);
    }
    if (ip->faults->n_restarts > 0u) {
        fprintf(stderr, "microdrive-session: controller restarts: %u of %u scheduled\n", (unsigned)ip->restarts,
                (unsigned)ip->faults->n_restarts);
    }
}

session_end_t session_run_inproc(const session_opts_t *o, const char *resolved_bus, session_track_t *t, FILE *truth)
{
    char err[1024];
    inproc_t *ip = &g_ip;
    memset(ip, 0, sizeof *ip);
    ip->track = t;
    ip->opts = o;
    t->stamp_sim = false; /* the clock follows simulated time (see above): stamp with it */
    simnode_world_t *world = simnode_world_create(o->scenario, o->seed, err, sizeof err);
    if (world == NULL) {
        fprintf(stderr, "microdrive-session: %s\n", err);
        return SESSION_END_ERROR;
    }
    ip->faults = simnode_world_faults(world);
    simnode_world_set_truth(world, truth);
    session_end_t end = SESSION_END_ERROR;
    if (open_endpoints(ip, resolved_bus) == 0 && start_nodes(ip, world) == 0) {
        end = inproc_loop(ip, (uint64_t)(o->idle_s * 1e6));
    }
    if (ip->plant.world != NULL) {
        print_faults(ip);
    }
    md_bus_close(&ip->rec_ep);
    md_bus_close(&ip->ctrl_ep);
    md_bus_close((ip->plant_bus != NULL) ? ip->plant_bus : &ip->plant_ep); /* closes the wrappers' chain */
    if (ip->bus_errors > 0u || ip->rec_ep.stats.rx_overflow > 0u || ip->ctrl_ep.stats.rx_overflow > 0u ||
        ip->plant_ep.stats.rx_overflow > 0u) {
        fprintf(stderr,
                "microdrive-session: in-process bus lost frames (send errors %" PRIu64 ", overflow plant %" PRIu64
                " controller %" PRIu64 " recorder %" PRIu64 ")\n",
                ip->bus_errors, ip->plant_ep.stats.rx_overflow, ip->ctrl_ep.stats.rx_overflow,
                ip->rec_ep.stats.rx_overflow);
        end = SESSION_END_ERROR;
    }
    simnode_world_destroy(world);
    return end;
}
