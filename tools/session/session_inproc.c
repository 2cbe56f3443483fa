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
/// The clock is the controller's platform time; the plant's simulated time
/// moves only by the controller's commands (lockstep), as in microdrive-sim.
#include <inttypes.h>
#include <stdlib.h>
#include <string.h>

#include "md_bus.h"
#include "md_can.h"
#include "md_controller.h"
#include "md_params.h"
#include "session.h"
#include "simnode_plant.h"
#include "simnode_world.h"

#define INPROC_HB_PERIOD_US ((uint64_t)MD_CAN_HEARTBEAT_ACT_CYCLE_TIME_MS * 1000u)
/// Polls of the controller at one instant before the clock must move on.
#define INPROC_POLL_GUARD 100000u

static const md_node_id_t INPROC_PLANT_NODES[3] = {MD_NODE_ACT, MD_NODE_HALL, MD_NODE_FE};

typedef struct {
    md_bus_t plant_ep, ctrl_ep, rec_ep;   /* must not move while open: static */
    simnode_plant_t plant;
    md_controller_t *ctrl;
    session_track_t *track;
    uint64_t now_us;                      /* the virtual clock */
    uint64_t next_hb_us;
    uint64_t bus_errors;
    bool in_ctrl;                         /* the controller is on the stack: no re-entry */
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

static int plant_sink(void *ctx, const md_frame_t *f)
{
    inproc_t *ip = ctx;
    const int rc = md_bus_send(&ip->plant_ep, f);
    if (rc != 0) {
        ip->bus_errors++;
    }
    drain_recorder(ip);
    drain_controller(ip);
    return rc;
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
    for (uint32_t i = 0; i < 3u; i++) {
        md_frame_t f;
        simnode_heartbeat_frame(simnode_plant_node(&ip->plant, INPROC_PLANT_NODES[i]),
                                (uint32_t)(ip->now_us / 1000000u), &f);
        (void)plant_sink(ip, &f);
    }
}

/* Hands every frame queued for the plant to it; each may cause a batch. */
static bool serve_plant(inproc_t *ip)
{
    md_frame_t f;
    bool any = false;
    while (md_bus_receive(&ip->plant_ep, &f, 0) == 1) {
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

static int open_endpoints(inproc_t *ip, const char *spec)
{
    char why[160];
    if (md_bus_open(&ip->plant_ep, spec, why, sizeof why) != 0 || md_bus_open(&ip->ctrl_ep, spec, why, sizeof why) != 0 ||
        md_bus_open(&ip->rec_ep, spec, why, sizeof why) != 0) {
        fprintf(stderr, "microdrive-session: cannot open %s: %s\n", spec, why);
        return -1;
    }
    return 0;
}

static int start_nodes(inproc_t *ip, simnode_world_t *world, const session_opts_t *o)
{
    const md_port_t port = {ctrl_send, ctrl_now, ip};
    ip->ctrl = md_controller_instance();
    if (md_controller_init(ip->ctrl, &port, ip->now_us) != MD_OK) {
        fprintf(stderr, "microdrive-session: controller init failed\n");
        return -1;
    }
    /* as microdrive-fw --auto-start */
    (void)md_params_set(&md_controller_node(ip->ctrl)->params, md_params_def(MD_P_AUTO_START)->index, 1.0);
    char why[200];   /* --param NAME=VALUE, checked at parse time, applied here before the start */
    if (session_apply_params(&md_controller_node(ip->ctrl)->params, o, why, sizeof why) != 0) {
        fprintf(stderr, "microdrive-session: %s\n", why);
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
    poll_controller(ip);
    plant_heartbeats(ip);
    ip->next_hb_us = ip->now_us + INPROC_HB_PERIOD_US;
    simnode_plant_start(&ip->plant);
    return 0;
}

static session_end_t inproc_loop(inproc_t *ip, uint64_t idle_us)
{
    uint64_t last_activity = ip->track->activity, activity_at = ip->now_us;
    uint32_t spins = 0u;   /* passes at one instant without any frame: a controller that never rests */
    for (;;) {   /* ends by the goal, idleness or a signal */
        const bool served = serve_plant(ip);
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
                fprintf(stderr, "microdrive-session: the controller has work at %" PRIu64 " us forever\n",
                        ip->now_us);
                return SESSION_END_ERROR;
            }
            continue;   /* answers and due work first: the clock stands still */
        }
        ip->now_us = (d < ip->next_hb_us) ? d : ip->next_hb_us;
        if (ip->now_us >= ip->next_hb_us) {
            plant_heartbeats(ip);
            ip->next_hb_us += INPROC_HB_PERIOD_US;
        }
    }
}

session_end_t session_run_inproc(const session_opts_t *o, const char *resolved_bus, session_track_t *t, FILE *truth)
{
    char err[1024];
    inproc_t *ip = &g_ip;
    memset(ip, 0, sizeof *ip);
    ip->track = t;
    simnode_world_t *world = simnode_world_create(o->scenario, o->seed, err, sizeof err);
    if (world == NULL) {
        fprintf(stderr, "microdrive-session: %s\n", err);
        return SESSION_END_ERROR;
    }
    simnode_world_set_truth(world, truth);
    session_end_t end = SESSION_END_ERROR;
    if (open_endpoints(ip, resolved_bus) == 0 && start_nodes(ip, world, o) == 0) {
        end = inproc_loop(ip, (uint64_t)(o->idle_s * 1e6));
    }
    md_bus_close(&ip->rec_ep);
    md_bus_close(&ip->ctrl_ep);
    md_bus_close(&ip->plant_ep);
    if (ip->bus_errors > 0u || ip->rec_ep.stats.rx_overflow > 0u || ip->ctrl_ep.stats.rx_overflow > 0u ||
        ip->plant_ep.stats.rx_overflow > 0u) {
        fprintf(stderr, "microdrive-session: in-process bus lost frames (send errors %" PRIu64
                ", overflow plant %" PRIu64 " controller %" PRIu64 " recorder %" PRIu64 ")\n",
                ip->bus_errors, ip->plant_ep.stats.rx_overflow, ip->ctrl_ep.stats.rx_overflow,
                ip->rec_ep.stats.rx_overflow);
        end = SESSION_END_ERROR;
    }
    simnode_world_destroy(world);
    return end;
}
