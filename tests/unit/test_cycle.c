/* The controller cycle (md_controller.h → md_cycle) against a scripted fake
 * plant in lockstep: a front-end streaming synthetic spikes whose amplitude
 * depends on depth, a linear Hall sensor, a piezo of 40 nm steps. Checks the
 * safety rules and the telemetry of every cycle. */
#include <math.h>
#include <string.h>

#include "md_can.h"
#include "md_controller.h"
#include "md_interval.h"
#include "md_telemetry.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

#define FS_HZ 20000u
#define OUTBOX 512u
#define WIN_MIN_UM 900.0
#define WIN_MAX_UM 1100.0

typedef struct {
    md_frame_t out[OUTBOX];
    uint32_t n_out;
    uint64_t sim_us;
    double pos_um;
    uint32_t rng;
    int flat;      /* next interval: a flat signal (numeric failure) */
    int recording; /* a REC_REQ is being answered */
    uint8_t hall_seq;
    /* observations */
    uint32_t steps_cmds, steps_while_recording, steps_unasked;
    uint32_t tlm_status, tlm_cycle0, tlm_cycle1, tlm_spikes_parts, spikes_listed, emcy_software;
    uint32_t move_flags_pending; /* TLM_STATUS with MD_TLM_F_MOVE not yet followed by motion */
    double cycle_start_um, max_excursion_um, min_pos, max_pos;
    uint16_t last_cycle[MD_ELECTRODES];
    uint32_t last_status_spikes;
    uint16_t last_interval;
    uint64_t last_start_us;
    uint64_t now_us; /* platform time given to the controller with every frame */
    /* work counter of the port (test_cycle_cost_from_the_work_counter) */
    int work_port; /* the port has work_now/work_section */
    uint64_t work; /* advances WORK_PER_CALL per work_now call */
    int section_open;
    uint32_t section_errors; /* enter while open, or leave while closed */
    uint32_t rec_frames;     /* REC_DATA frames of the current interval */
    uint32_t costs_checked;
} plant_t;

static plant_t P;

static md_status_t port_send(void *ctx, const md_frame_t *f)
{
    (void)ctx;
    if (P.n_out >= OUTBOX) {
        return MD_E_IO;
    }
    P.out[P.n_out++] = *f;
    return MD_OK;
}

static uint64_t port_now(void *ctx)
{
    (void)ctx;
    return 0u;
}

/* A work counter that advances a fixed amount per reading: every measured
 * stretch then costs exactly WORK_PER_CALL. */
#define WORK_PER_CALL 7u

static uint64_t port_work(void *ctx)
{
    (void)ctx;
    P.work += WORK_PER_CALL;
    return P.work;
}

static void port_section(void *ctx, bool enter)
{
    (void)ctx;
    P.section_errors += ((P.section_open != 0) == enter) ? 1u : 0u; /* strictly alternating */
    P.section_open = enter ? 1 : 0;
}

static double noise(void)
{
    double s = 0.0;
    for (int i = 0; i < 4; ++i) {
        P.rng = P.rng * 1664525u + 1013904223u;
        s += (double)(P.rng >> 8) / 16777216.0 - 0.5;
    }
    return s * 1.7; /* sd ~ 1 */
}

static void deliver(const md_frame_t *f)
{
    md_controller_on_frame(md_controller_instance(), f, P.now_us);
}

static void frame_init(md_frame_t *f, uint32_t id, int len, int fd)
{
    memset(f, 0, sizeof *f);
    f->id = id;
    f->len = (uint8_t)len;
    f->flags = fd ? MD_FRAME_FLAG_FD : 0u;
}

static void send_clock(void)
{
    struct md_can_sim_clock_t m = {P.sim_us};
    md_frame_t f;
    frame_init(&f, MD_CAN_SIM_CLOCK_FRAME_ID, MD_CAN_SIM_CLOCK_LENGTH, 0);
    (void)md_can_sim_clock_pack(f.data, &m, sizeof f.data);
    deliver(&f);
}

static void send_hall(uint8_t e)
{
    struct md_can_hall_reading_t m = {e, P.hall_seq++, 0u, (uint32_t)(P.sim_us / 1000u)};
    const double pos = (e == 0u) ? P.pos_um : 1000.0;
    m.raw_code = (uint16_t)floor(30000.0 + 5.0 * pos + 0.5); /* 0.2 um per code */
    if (e != 0u) {
        return; /* the test drives electrode 0's sensor only; others stay uncalibrated */
    }
    md_frame_t f;
    frame_init(&f, MD_CAN_HALL_READING_FRAME_ID, MD_CAN_HALL_READING_LENGTH, 0);
    (void)md_can_hall_reading_pack(f.data, &m, sizeof f.data);
    deliver(&f);
}

/* Time passes: Hall readings every 10 ms. */
static void pass_time(uint64_t us)
{
    const uint64_t end = P.sim_us + us;
    while (P.sim_us + 10000u <= end) {
        P.sim_us += 10000u;
        send_hall(0u);
    }
    P.sim_us = end;
}

static void heartbeat(uint32_t id, uint8_t flags)
{
    struct md_can_heartbeat_act_t m = {MD_NODE_STATE_OPERATIONAL, MD_PROTOCOL_VERSION, flags, MD_ELECTRODES, 0u};
    md_frame_t f;
    frame_init(&f, id, MD_CAN_HEARTBEAT_ACT_LENGTH, 0);
    (void)md_can_heartbeat_act_pack(f.data, &m, sizeof f.data);
    deliver(&f);
}

static void answer_rec_req(const md_frame_t *req)
{
    struct md_can_rec_req_t r;
    TEST_ASSERT_EQUAL_INT(0, md_can_rec_req_unpack(&r, req->data, req->len));
    P.recording = 1;
    P.rec_frames = 0u;
    send_clock();
    /* amplitude peaks at 1050 um: SNR rises with depth in the window */
    const double amp = 10.0 + 60.0 * exp(-pow((P.pos_um - 1050.0) / 80.0, 2.0));
    uint16_t seq = 0u;
    for (uint32_t i0 = 0u; i0 < r.num_samples; i0 += 30u) {
        md_frame_t f;
        frame_init(&f, MD_CAN_REC_DATA_FRAME_ID, MD_CAN_REC_DATA_LENGTH, 1);
        P.rec_frames++;
        const uint32_t cnt = (r.num_samples - i0 < 30u) ? r.num_samples - i0 : 30u;
        f.data[0] = r.electrode;
        f.data[1] = (uint8_t)cnt;
        f.data[2] = (uint8_t)(seq & 0xFFu);
        f.data[3] = (uint8_t)(seq >> 8);
        for (uint32_t k = 0u; k < cnt; ++k) {
            const uint32_t i = i0 + k;
            double x = P.flat ? 0.0 : 4.0 * noise();
            const uint32_t ph = i % 1000u; /* a spike every 50 ms */
            if (!P.flat && ph >= 100u && ph < 112u) {
                x -= amp * sin(3.14159265 * (double)(ph - 100u) / 12.0);
            }
            const int16_t v = (int16_t)floor(x + 0.5);
            f.data[4u + 2u * k] = (uint8_t)((uint16_t)v & 0xFFu);
            f.data[5u + 2u * k] = (uint8_t)((uint16_t)v >> 8);
        }
        deliver(&f);
        seq++;
        if ((i0 / 30u) % 7u == 0u) {
            pass_time(10000u);
        }
    }
    struct md_can_rec_end_t e = {r.electrode, MD_REC_COMPLETE, r.interval_id, r.num_samples};
    md_frame_t f;
    frame_init(&f, MD_CAN_REC_END_FRAME_ID, MD_CAN_REC_END_LENGTH, 0);
    (void)md_can_rec_end_pack(f.data, &e, sizeof f.data);
    P.recording = 0;
    P.flat = 0;
    deliver(&f);
    send_clock();
}

static void answer_act_cmd(const md_frame_t *cmd)
{
    struct md_can_act_cmd_t c;
    TEST_ASSERT_EQUAL_INT(0, md_can_act_cmd_unpack(&c, cmd->data, cmd->len));
    if (c.command != MD_ACT_CMD_STEP) {
        return;
    }
    P.steps_cmds++;
    P.steps_while_recording += (uint32_t)P.recording;
    P.steps_unasked += (P.move_flags_pending == 0u) ? 1u : 0u;
    struct md_can_act_status_t s = {c.electrode, MD_ACT_MOVING, c.seq, 0u, 0u, c.step_count};
    md_frame_t f;
    frame_init(&f, MD_CAN_ACT_STATUS_FRAME_ID, MD_CAN_ACT_STATUS_LENGTH, 0);
    send_clock();
    (void)md_can_act_status_pack(f.data, &s, sizeof f.data);
    deliver(&f);
    const double dir = (c.direction == MD_ACT_DIR_ADVANCE) ? 1.0 : -1.0;
    P.pos_um += dir * 0.040 * (double)c.step_count;
    P.min_pos = fmin(P.min_pos, P.pos_um);
    P.max_pos = fmax(P.max_pos, P.pos_um);
    P.max_excursion_um = fmax(P.max_excursion_um, fabs(P.pos_um - P.cycle_start_um));
    P.sim_us += (uint64_t)c.step_count * 1000u;
    s.state = MD_ACT_IDLE;
    s.steps_done = c.step_count;
    s.steps_remaining = 0u;
    (void)md_can_act_status_pack(f.data, &s, sizeof f.data);
    deliver(&f);
    send_clock();
}

static void observe_tlm(const md_frame_t *f)
{
    if (f->id == MD_CAN_TLM_STATUS_FRAME_ID) {
        struct md_can_tlm_status_t s;
        TEST_ASSERT_TRUE((f->flags & MD_FRAME_FLAG_FD) != 0u);
        TEST_ASSERT_EQUAL_INT(0, md_can_tlm_status_unpack(&s, f->data, f->len));
        P.tlm_status++;
        TEST_ASSERT_EQUAL_UINT16(P.last_cycle[s.electrode], s.cycle);
        if (P.work_port == 0) {
            TEST_ASSERT_EQUAL_UINT32(0u, s.cycle_cost); /* no work counter: no cost */
            TEST_ASSERT_EQUAL_UINT32(0u, s.process_cost);
        } else if ((s.flags & (MD_TLM_F_SKIPPED | MD_TLM_F_REC_FAILED)) == 0u) {
            /* one stretch per REC_DATA frame pushed, one for the processing */
            TEST_ASSERT_EQUAL_UINT32(WORK_PER_CALL, s.process_cost);
            TEST_ASSERT_EQUAL_UINT32(WORK_PER_CALL * (P.rec_frames + 1u), s.cycle_cost);
            TEST_ASSERT_EQUAL_INT(0, P.section_open);
            P.costs_checked++;
        } else {
            /* skipped or failed: checked by the tests of those paths */
        }
        P.last_status_spikes = s.num_spikes;
        P.cycle_start_um = P.pos_um;
        if ((s.flags & MD_TLM_F_MOVE) != 0u) {
            P.move_flags_pending = 1u;
            TEST_ASSERT_LESS_OR_EQUAL_DOUBLE(30.0 + 1e-3, fabs((double)s.target_depth_um - (double)s.depth_um));
        } else {
            P.move_flags_pending = 0u;
        }
    } else if (f->id == MD_CAN_TLM_CYCLE_FRAME_ID) {
        struct md_can_tlm_cycle_t m;
        TEST_ASSERT_EQUAL_INT(0, md_can_tlm_cycle_unpack(&m, f->data, f->len));
        TEST_ASSERT_EQUAL_UINT32(FS_HZ, m.sample_rate_hz);
        if (m.phase == MD_TLM_PHASE_REQUESTED) {
            P.tlm_cycle0++;
            P.last_cycle[m.electrode] = m.cycle;
            P.last_interval = m.interval_id;
        } else {
            P.tlm_cycle1++;
            TEST_ASSERT_EQUAL_UINT16(P.last_interval, m.interval_id);
            TEST_ASSERT_EQUAL_UINT16(P.last_cycle[m.electrode], m.cycle);
            TEST_ASSERT_TRUE(m.start_time_us >= P.last_start_us);
            P.last_start_us = m.start_time_us;
        }
    } else if (f->id == MD_CAN_TLM_SPIKES_FRAME_ID) {
        struct md_can_tlm_spikes_t m;
        TEST_ASSERT_EQUAL_INT(0, md_can_tlm_spikes_unpack(&m, f->data, f->len));
        TEST_ASSERT_LESS_OR_EQUAL_UINT(11u, m.count);
        P.tlm_spikes_parts++;
        P.spikes_listed += m.count;
        if (m.count > 0u) { /* a spike every 50 ms at sample 100 + trough offset */
            TEST_ASSERT_DOUBLE_WITHIN(12.0, 106.0, (double)(m.sample00 % 1000u));
        }
    } else if (f->id == MD_CAN_EMCY_CTRL_FRAME_ID) {
        struct md_can_emcy_ctrl_t m;
        TEST_ASSERT_EQUAL_INT(0, md_can_emcy_ctrl_unpack(&m, f->data, f->len));
        P.emcy_software += (m.error_code == MD_EMCY_SOFTWARE) ? 1u : 0u;
    } else {
        /* other frames */
    }
}

/* Answers the controller's frames until it waits; polls it in between. */
static void run(uint32_t rounds)
{
    md_controller_t *c = md_controller_instance();
    for (uint32_t r = 0u; r < rounds; ++r) {
        md_controller_poll(c, 0u);
        for (uint32_t i = 0u; i < P.n_out; ++i) {
            const md_frame_t f = P.out[i];
            observe_tlm(&f);
            if (f.id == MD_CAN_REC_REQ_FRAME_ID) {
                answer_rec_req(&f);
            } else if (f.id == MD_CAN_ACT_CMD_FRAME_ID) {
                answer_act_cmd(&f);
            } else if (f.id == MD_CAN_SIM_ADVANCE_FRAME_ID) {
                struct md_can_sim_advance_t s;
                TEST_ASSERT_EQUAL_INT(0, md_can_sim_advance_unpack(&s, f.data, f.len));
                TEST_ASSERT_FALSE(P.recording);
                send_clock();
                pass_time(s.duration_us);
                send_clock();
            } else {
                /* telemetry, heartbeats */
            }
        }
        P.n_out = 0u;
    }
}

static void boot_with(int work_port)
{
    memset(&P, 0, sizeof P);
    P.rng = 7u;
    P.pos_um = 1000.0;
    P.min_pos = P.max_pos = P.pos_um;
    P.work_port = work_port;
    const md_port_t port = {port_send, port_now, NULL, work_port != 0 ? port_work : NULL,
                            work_port != 0 ? port_section : NULL};
    md_controller_t *c = md_controller_instance();
    TEST_ASSERT_EQUAL_INT(MD_OK, md_controller_init(c, &port, 0u));
    md_node_t *n = md_controller_node(c);
    TEST_ASSERT_EQUAL_INT(MD_PARAM_OK, md_params_set(&n->params, 0x2000u, 1.0));        /* interval_s */
    TEST_ASSERT_EQUAL_INT(MD_PARAM_OK, md_params_set(&n->params, 0x2010u, WIN_MIN_UM)); /* depth window */
    TEST_ASSERT_EQUAL_INT(MD_PARAM_OK, md_params_set(&n->params, 0x2011u, WIN_MAX_UM));
    TEST_ASSERT_EQUAL_INT(MD_PARAM_OK, md_params_set(&n->params, 0x1F80u, 1.0));     /* auto start */
    TEST_ASSERT_EQUAL_INT(MD_PARAM_OK, md_params_set(&n->params, 0x1016u, 60000.0)); /* no timeouts in a test */
    heartbeat(MD_CAN_HEARTBEAT_ACT_FRAME_ID, 0u);
    heartbeat(MD_CAN_HEARTBEAT_HALL_FRAME_ID, 0u);
    heartbeat(MD_CAN_HEARTBEAT_FE_FRAME_ID, MD_HB_FLAG_LOCKSTEP);
    /* FE_INFO for electrode 0 only: the round robin waits on the others, so
     * the test drives electrode 0 and checks that the others never record */
    struct md_can_fe_info_t fi = {0u, 1u, FS_HZ, 1.0f};
    md_frame_t f;
    frame_init(&f, MD_CAN_FE_INFO_FRAME_ID, MD_CAN_FE_INFO_LENGTH, 1);
    (void)md_can_fe_info_pack(f.data, &fi, sizeof f.data);
    deliver(&f);
    const double cal[4][2] = {{0.0, -6000.0}, {1.0, 6000.0}, {240.0, 0.0}, {241.0, 30000.0}};
    for (int k = 0; k < 4; ++k) { /* depth = -6000 + 6000 x, x = code / 30000: 0.2 um per code */
        struct md_can_hall_calib_t hc = {0u, (uint8_t)cal[k][0], 2u, (float)cal[k][1]};
        frame_init(&f, MD_CAN_HALL_CALIB_FRAME_ID, MD_CAN_HALL_CALIB_LENGTH, 0);
        (void)md_can_hall_calib_pack(f.data, &hc, sizeof f.data);
        deliver(&f);
    }
    pass_time(100000u);
}

static void boot(void)
{
    boot_with(0);
}

/* A cycle counts when it ends (after its move and settling), its interval
 * is processed before: 1 if the run stopped between the two. */
static uint32_t processed_uncounted(const md_electrode_t *el)
{
    return ((el->phase == MD_CYC_MOVING) || (el->phase == MD_CYC_SETTLING)) ? 1u : 0u;
}

/* 1 if the run stopped in a cycle whose interval is recorded but not yet processed. */
static uint32_t unprocessed(const md_electrode_t *el)
{
    return ((el->phase == MD_CYC_RECORDING) || (el->phase == MD_CYC_PROCESS)) ? 1u : 0u;
}

static void test_cycles_move_safely_with_telemetry(void)
{
    boot();
    md_controller_t *c = md_controller_instance();
    run(60u); /* rounds: recording, processing and the servo moves the SFSM asks for */
    const md_electrode_t *el = &c->cycle.el[0];
    TEST_ASSERT_GREATER_OR_EQUAL_UINT(4u, el->cycles);
    TEST_ASSERT_EQUAL_UINT32(el->cycles + processed_uncounted(el), P.tlm_status); /* one per processed interval */
    TEST_ASSERT_EQUAL_UINT32(P.tlm_cycle0, P.tlm_cycle1 + unprocessed(el));
    TEST_ASSERT_GREATER_OR_EQUAL_UINT(el->cycles, P.tlm_spikes_parts);
    TEST_ASSERT_EQUAL_UINT32(0u, el->skipped);
    TEST_ASSERT_GREATER_THAN_UINT(0u, P.steps_cmds);                  /* the SFSM searched */
    TEST_ASSERT_EQUAL_UINT32(0u, P.steps_while_recording);            /* never moves while recording */
    TEST_ASSERT_EQUAL_UINT32(0u, P.steps_unasked);                    /* never unless the SFSM asked */
    TEST_ASSERT_LESS_OR_EQUAL_DOUBLE(30.0 + 2.0, P.max_excursion_um); /* Δmax per cycle (+ servo tolerance) */
    TEST_ASSERT_GREATER_OR_EQUAL_DOUBLE(WIN_MIN_UM - 2.0, P.min_pos);
    TEST_ASSERT_LESS_OR_EQUAL_DOUBLE(WIN_MAX_UM + 2.0, P.max_pos);
    TEST_ASSERT_EQUAL_UINT32(0u, c->cycle.el[1].cycles); /* no FE_INFO: never recorded */
    TEST_ASSERT_GREATER_THAN_UINT(0u, el->mhtc.interval);
}

/* The `tracker` parameter (0x2041) selects a baseline; the cycle applies it
 * at the next cycle start with fresh tracks, and the loop still runs. */
/* The cycle's cost (TLM_STATUS CycleCost, ProcessCost) comes from the port's
 * work counter: detection of every REC_DATA frame plus the processing, each
 * a stretch bracketed by work_section enter/leave. */
static void test_cycle_cost_from_the_work_counter(void)
{
    boot_with(1);
    run(40u);
    TEST_ASSERT_GREATER_OR_EQUAL_UINT(3u, P.costs_checked);
    TEST_ASSERT_EQUAL_UINT32(0u, P.section_errors);
    TEST_ASSERT_EQUAL_INT(0, P.section_open);
}

/* mhtc_unimodal_ratio (0x2042) reaches the running tracker at the next cycle start, the
 * tracker kept (its tracks too): it is read per fit. */
static void test_unimodal_ratio_parameter_reaches_the_tracker(void)
{
    boot();
    md_controller_t *c = md_controller_instance();
    md_node_t *n = md_controller_node(c);
    TEST_ASSERT_EQUAL_DOUBLE(MHTC_UNIMODAL_RATIO_DEFAULT, c->cycle.el[0].mhtc.cfg.unimodal_ratio);
    TEST_ASSERT_EQUAL_INT(MD_PARAM_OUT_OF_RANGE, md_params_set(&n->params, 0x2042u, 1.5));
    TEST_ASSERT_EQUAL_INT(MD_PARAM_OK, md_params_set(&n->params, 0x2042u, 0.5));
    run(20u);
    const md_electrode_t *el = &c->cycle.el[0];
    TEST_ASSERT_EQUAL_INT(MHTC_TRACKER_MHTC, el->mhtc.cfg.tracker);
    TEST_ASSERT_EQUAL_DOUBLE(0.5, el->mhtc.cfg.unimodal_ratio);
    TEST_ASSERT_GREATER_THAN_UINT(0u, el->mhtc.interval);
}

static void test_tracker_parameter_selects_baseline(void)
{
    boot();
    md_controller_t *c = md_controller_instance();
    md_node_t *n = md_controller_node(c);
    TEST_ASSERT_EQUAL_INT(MHTC_TRACKER_MHTC, c->cycle.el[0].mhtc.cfg.tracker);
    TEST_ASSERT_EQUAL_INT(MD_PARAM_OUT_OF_RANGE, md_params_set(&n->params, 0x2041u, 4.0));
    TEST_ASSERT_EQUAL_INT(MD_PARAM_OUT_OF_RANGE, md_params_set(&n->params, 0x2041u, 1.5));
    TEST_ASSERT_EQUAL_INT(MD_PARAM_OK, md_params_set(&n->params, 0x2041u, 3.0)); /* GNN */
    TEST_ASSERT_EQUAL_INT(MHTC_TRACKER_GNN, md_interval_tracker(&n->params));
    run(30u);
    const md_electrode_t *el = &c->cycle.el[0];
    TEST_ASSERT_EQUAL_INT(MHTC_TRACKER_GNN, el->mhtc.cfg.tracker);
    TEST_ASSERT_GREATER_OR_EQUAL_UINT(2u, el->cycles);
    TEST_ASSERT_EQUAL_UINT32(0u, el->skipped);
    TEST_ASSERT_EQUAL_UINT32(el->cycles + processed_uncounted(el), el->mhtc.interval); /* all to the baseline */
    TEST_ASSERT_EQUAL_UINT32(0u, P.steps_unasked);
    const mhtc_tracker_t want[4] = {MHTC_TRACKER_MHTC, MHTC_TRACKER_MAP_NN, MHTC_TRACKER_ML_NN, MHTC_TRACKER_GNN};
    for (uint32_t v = 0u; v < 4u; ++v) {
        n->params.value[MD_P_TRACKER] = (double)v;
        TEST_ASSERT_EQUAL_INT(want[v], md_interval_tracker(&n->params));
    }
}

/* Lockstep: a recording whose answer is slow (a loaded host, a slow VM) does
 * not time out while the plant keeps answering, whatever the platform time;
 * once the plant falls silent the answer timeout fires 5 s after its last
 * frame. */
static void recording_request_unanswered(void)
{
    boot();
    md_controller_t *c = md_controller_instance();
    md_controller_poll(c, 0u);
    const md_electrode_t *el = &c->cycle.el[0];
    TEST_ASSERT_EQUAL_INT(MD_CYC_RECORDING, el->phase);
    TEST_ASSERT_TRUE(c->cycle.lockstep);
}

/* Heartbeats of all three plant nodes at P.now_us (+ a Hall reading: an answer frame). */
static void plant_alive(bool answering)
{
    heartbeat(MD_CAN_HEARTBEAT_ACT_FRAME_ID, 0u);
    heartbeat(MD_CAN_HEARTBEAT_HALL_FRAME_ID, 0u);
    heartbeat(MD_CAN_HEARTBEAT_FE_FRAME_ID, MD_HB_FLAG_LOCKSTEP);
    if (answering) {
        send_hall(0u);
    }
}

static void test_lockstep_timeout_waits_for_a_live_plant(void)
{
    recording_request_unanswered();
    md_controller_t *c = md_controller_instance();
    const md_electrode_t *el = &c->cycle.el[0];
    for (uint32_t k = 1u; k <= 600u; ++k) { /* 60 s of platform time, frames every 100 ms */
        P.now_us = (uint64_t)k * 100000u;
        plant_alive(true);
        md_controller_poll(c, P.now_us);
        P.n_out = 0u;
    }
    TEST_ASSERT_EQUAL_INT(MD_CYC_RECORDING, el->phase);
    TEST_ASSERT_EQUAL_UINT32(0u, el->timeouts);
    TEST_ASSERT_EQUAL_UINT32(0u, el->rec_failed);
    const uint64_t last = P.now_us;
    TEST_ASSERT_EQUAL_UINT64(last + 5000000u, md_cycle_next_deadline_us(&c->cycle, &c->node));
    md_controller_poll(c, last + 4999999u); /* silent plant, not yet late */
    TEST_ASSERT_EQUAL_UINT32(0u, el->timeouts);
    md_controller_poll(c, last + 5000000u);
    TEST_ASSERT_EQUAL_UINT32(1u, el->timeouts);
    TEST_ASSERT_EQUAL_UINT32(1u, el->rec_failed);
}

/* Lockstep, a live plant (heartbeats) that never answers: a lost request or
 * answer on a socket bus. The cycle gives up 30 s after the request instead
 * of waiting for ever. */
static void test_lockstep_lost_answer_times_out(void)
{
    recording_request_unanswered();
    md_controller_t *c = md_controller_instance();
    const md_electrode_t *el = &c->cycle.el[0];
    for (uint32_t k = 1u; k < 300u; ++k) { /* heartbeats only, up to 29.9 s */
        P.now_us = (uint64_t)k * 100000u;
        plant_alive(false);
        md_controller_poll(c, P.now_us);
        P.n_out = 0u;
    }
    TEST_ASSERT_EQUAL_UINT32(0u, el->timeouts);
    TEST_ASSERT_EQUAL_UINT64(30000000u, md_cycle_next_deadline_us(&c->cycle, &c->node));
    P.now_us = 30000000u;
    plant_alive(false);
    md_controller_poll(c, P.now_us);
    TEST_ASSERT_EQUAL_UINT32(1u, el->timeouts);
    TEST_ASSERT_EQUAL_UINT32(1u, el->rec_failed);
}

/* Without lockstep the platform clock is the session's clock: the answer
 * bound (2 × interval + 5 s) holds even while heartbeats arrive. */
static void test_realtime_timeout_is_platform_time(void)
{
    recording_request_unanswered();
    md_controller_t *c = md_controller_instance();
    const md_electrode_t *el = &c->cycle.el[0];
    for (uint32_t k = 1u; k <= 80u; ++k) { /* 8 s: past 2 × 1 s + 5 s */
        P.now_us = (uint64_t)k * 100000u;
        heartbeat(MD_CAN_HEARTBEAT_ACT_FRAME_ID, 0u);
        heartbeat(MD_CAN_HEARTBEAT_HALL_FRAME_ID, 0u);
        heartbeat(MD_CAN_HEARTBEAT_FE_FRAME_ID, 0u); /* no lockstep flag */
        md_controller_poll(c, P.now_us);
        P.n_out = 0u;
    }
    TEST_ASSERT_FALSE(c->cycle.lockstep);
    TEST_ASSERT_EQUAL_UINT32(1u, el->timeouts);
}

static void test_numeric_failure_keeps_state(void)
{
    boot();
    md_controller_t *c = md_controller_instance();
    run(12u);
    const md_electrode_t *el = &c->cycle.el[0];
    while (el->phase != MD_CYC_IDLE) {
        run(1u);
    }
    const uint32_t next_id = el->mhtc.next_id;
    const size_t n_hyp = el->mhtc.n_hyp;
    const uint32_t interval = el->mhtc.interval;
    const sfsm_state_t sm = el->sfsm.state;
    const uint32_t sm_cycles = el->sfsm.cycles;
    const uint32_t steps = P.steps_cmds;
    const uint32_t status_before = P.tlm_status;
    P.flat = 1;
    run(2u); /* record the flat interval, then process it */
    TEST_ASSERT_EQUAL_UINT32(1u, el->skipped);
    TEST_ASSERT_EQUAL_UINT32(1u, c->node.counters.cycles_skipped);
    TEST_ASSERT_EQUAL_UINT32(1u, P.emcy_software);
    TEST_ASSERT_EQUAL_UINT32(next_id, el->mhtc.next_id);
    TEST_ASSERT_EQUAL_size_t(n_hyp, el->mhtc.n_hyp);
    TEST_ASSERT_EQUAL_UINT32(interval, el->mhtc.interval);
    TEST_ASSERT_EQUAL_INT(sm, el->sfsm.state);
    TEST_ASSERT_EQUAL_UINT32(sm_cycles, el->sfsm.cycles);
    TEST_ASSERT_EQUAL_UINT32(steps, P.steps_cmds);              /* no motion */
    TEST_ASSERT_EQUAL_UINT32(status_before + 1u, P.tlm_status); /* telemetry all the same */
    TEST_ASSERT_TRUE((el->flags & MD_TLM_F_SKIPPED) != 0u);
    run(4u); /* and the next cycles run again */
    TEST_ASSERT_GREATER_THAN_UINT(interval, el->mhtc.interval);
}

static void test_estop_stops_the_cycle(void)
{
    boot();
    md_controller_t *c = md_controller_instance();
    run(6u);
    const uint32_t steps = P.steps_cmds;
    md_frame_t f;
    frame_init(&f, MD_CAN_ESTOP_FRAME_ID, MD_CAN_ESTOP_LENGTH, 0);
    f.data[0] = MD_NODE_OPER;
    deliver(&f);
    run(10u);
    TEST_ASSERT_EQUAL_UINT32(steps, P.steps_cmds);
    TEST_ASSERT_EQUAL_INT(MD_CYC_IDLE, c->cycle.el[c->cycle.active].phase);
    TEST_ASSERT_EQUAL_UINT64(UINT64_MAX, md_cycle_next_deadline_us(&c->cycle, &c->node));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_cycles_move_safely_with_telemetry);
    RUN_TEST(test_cycle_cost_from_the_work_counter);
    RUN_TEST(test_tracker_parameter_selects_baseline);
    RUN_TEST(test_unimodal_ratio_parameter_reaches_the_tracker);
    RUN_TEST(test_lockstep_timeout_waits_for_a_live_plant);
    RUN_TEST(test_lockstep_lost_answer_times_out);
    RUN_TEST(test_realtime_timeout_is_platform_time);
    RUN_TEST(test_numeric_failure_keeps_state);
    RUN_TEST(test_estop_stops_the_cycle);
    return UNITY_END();
}
