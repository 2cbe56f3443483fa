/* Host unit: the plant nodes behind a real md_bus endpoint (in-process bus),
 * as microdrive-sim wires them, with a second endpoint playing the controller:
 * frames cross the transport's validation and queues both ways. */
#include <string.h>

#include "md_bus.h"
#include "md_can.h"
#include "md_protocol.h"
#include "simnode_plant.h"
#include "simnode_world.h"
#include "unity.h"

static md_bus_t sim_ep, ctrl_ep;
static simnode_world_t *world;
static simnode_plant_t plant;

static int bus_sink(void *ctx, const md_frame_t *f)
{
    return md_bus_send((md_bus_t *)ctx, f);
}

void setUp(void)
{
    char why[128];
    TEST_ASSERT_EQUAL_INT(0, md_bus_open(&sim_ep, "inproc:simnode", why, sizeof why));
    TEST_ASSERT_EQUAL_INT(0, md_bus_open(&ctrl_ep, "inproc:simnode", why, sizeof why));
    char err[256];
    world = simnode_world_create(NULL, 11u, err, sizeof err);
    TEST_ASSERT_MESSAGE(world != NULL, err);
    simnode_plant_cfg_t cfg;
    simnode_plant_cfg_default(&cfg);
    const simnode_sink_t sink = {bus_sink, &sim_ep};
    TEST_ASSERT_EQUAL_INT(MD_OK, simnode_plant_init(&plant, &cfg, world, sink));
    simnode_plant_start(&plant);
}

void tearDown(void)
{
    md_bus_close(&sim_ep);
    md_bus_close(&ctrl_ep);
    simnode_world_destroy(world);
    world = NULL;
}

/* Delivers every frame queued for the simulator's endpoint to the plant. */
static void pump_sim(void)
{
    md_frame_t f;
    for (int i = 0; i < 64 && md_bus_receive(&sim_ep, &f, 0) == 1; i++) {
        simnode_plant_handle(&plant, &f);
    }
}

static void ctrl_send(uint32_t id, const uint8_t *data, uint8_t len)
{
    md_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = id;
    f.len = len;
    memcpy(f.data, data, len);
    TEST_ASSERT_EQUAL_INT(0, md_bus_send(&ctrl_ep, &f));
}

static void drain_ctrl(void)
{
    md_frame_t f;
    for (int i = 0; i < 4096 && md_bus_receive(&ctrl_ep, &f, 0) == 1; i++) {
    }
}

static void test_rec_req_over_the_bus(void)
{
    drain_ctrl(); /* start-up announcements */
    const struct md_can_rec_req_t req = {1u, 500u, 95u};
    uint8_t d[8];
    TEST_ASSERT_EQUAL_INT(8, md_can_rec_req_pack(d, &req, sizeof d));
    ctrl_send(MD_CAN_REC_REQ_FRAME_ID, d, 8u);
    pump_sim();
    md_frame_t f;
    uint32_t frames = 0u, samples = 0u;
    bool ended = false;
    uint64_t last_clock = 0u;
    for (int i = 0; i < 4096 && md_bus_receive(&ctrl_ep, &f, 0) == 1; i++) {
        if (f.id == MD_CAN_REC_DATA_FRAME_ID) {
            struct md_can_rec_data_t r;
            TEST_ASSERT_EQUAL_INT(0, md_can_rec_data_unpack(&r, f.data, f.len));
            TEST_ASSERT_EQUAL_UINT8(1u, r.electrode);
            TEST_ASSERT_EQUAL_UINT16(frames, r.seq);
            samples += r.sample_count;
            frames++;
        } else if (f.id == MD_CAN_REC_END_FRAME_ID) {
            struct md_can_rec_end_t e;
            TEST_ASSERT_EQUAL_INT(0, md_can_rec_end_unpack(&e, f.data, f.len));
            TEST_ASSERT_EQUAL_UINT16(500u, e.interval_id);
            TEST_ASSERT_EQUAL_UINT32(95u, e.total_samples);
            TEST_ASSERT_EQUAL_UINT8(MD_REC_COMPLETE, e.status);
            ended = true;
        } else if (f.id == MD_CAN_SIM_CLOCK_FRAME_ID) {
            struct md_can_sim_clock_t c;
            TEST_ASSERT_EQUAL_INT(0, md_can_sim_clock_unpack(&c, f.data, f.len));
            last_clock = c.sim_time_us;
        }
    }
    TEST_ASSERT_TRUE(ended);
    TEST_ASSERT_EQUAL_UINT32(4u, frames);
    TEST_ASSERT_EQUAL_UINT32(95u, samples);
    TEST_ASSERT_EQUAL_UINT64(3167u, last_clock); /* ceil(95 / 30 kHz) in us */
    TEST_ASSERT_EQUAL_UINT64(0u, sim_ep.stats.tx_errors);
}

static void test_estop_and_nmt_over_the_bus(void)
{
    drain_ctrl();
    const uint8_t estop[2] = {MD_NODE_CTRL, 3u};
    ctrl_send(MD_CAN_ESTOP_FRAME_ID, estop, 2u);
    const uint8_t nmt_stop_fe[2] = {MD_NMT_STOP, MD_NODE_FE};
    ctrl_send(MD_CAN_NMT_FRAME_ID, nmt_stop_fe, 2u);
    pump_sim();
    TEST_ASSERT_TRUE(plant.act.node.estop_latched);
    TEST_ASSERT_EQUAL_INT(MD_NODE_STATE_STOPPED, plant.fe.node.state);
    md_frame_t f;
    bool emcy = false;
    for (int i = 0; i < 64 && md_bus_receive(&ctrl_ep, &f, 0) == 1; i++) {
        emcy = emcy || f.id == MD_CAN_EMCY_ACT_FRAME_ID;
    }
    TEST_ASSERT_TRUE(emcy);
    const uint8_t clear[2] = {MD_NMT_CLEAR_ESTOP, 0u};
    ctrl_send(MD_CAN_NMT_FRAME_ID, clear, 2u);
    pump_sim();
    TEST_ASSERT_FALSE(plant.act.node.estop_latched);
    TEST_ASSERT_EQUAL_UINT64(3u, plant.stats.rx_frames);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_rec_req_over_the_bus);
    RUN_TEST(test_estop_and_nmt_over_the_bus);
    return UNITY_END();
}
