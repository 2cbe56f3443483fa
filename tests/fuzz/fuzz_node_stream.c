/// @file fuzz_node_stream.c
/// Fuzz target 4: the controller's handling of the recording stream
/// (REC_DATA sequences closed by REC_END, md_node.c handle_rec_data /
/// handle_rec_end), checked against an independent model of the DBC rules:
///  - REC_DATA Seq counts the frames of one interval from 0; a frame with the
///    expected Seq adds its SampleCount, any other Seq is a sequence error
///    (counted, samples unchanged) after which the stream resynchronises on
///    Seq + 1;
///  - SampleCount > MD_REC_SAMPLES_PER_FRAME, an electrode out of range or a
///    REC_END status above MD_REC_OVERFLOW is a range error and changes nothing;
///  - a wrong length or a missing FD flag is a length error and changes nothing;
///  - REC_END and NMT reset-node restart the interval (Seq 0, no samples).
/// After every frame the node's per-electrode Seq/sample state and the
/// rx_bad_* counters must equal the model's, exactly.
#include <stdbool.h>
#include <stdint.h>
#include <string.h>

#include "fuzz_input.h"
#include "md_can.h"
#include "md_node.h"

typedef struct {
    uint16_t next_seq[MD_ELECTRODES];
    uint32_t samples[MD_ELECTRODES];
    uint32_t bad_range, bad_seq, bad_length, accepted;
} stream_model_t;

static md_status_t port_send(void *ctx, const md_frame_t *frame)
{
    (void)ctx;
    FUZZ_CHECK(md_frame_valid(frame));
    return MD_OK;
}

static uint64_t port_now(void *ctx)
{
    (void)ctx;
    return 0u;
}

/* A REC_DATA frame (well-formed or not) and what the model expects of it. */
static md_status_t rec_data(md_node_t *node, stream_model_t *m, fz_t *in, uint64_t now_us)
{
    const uint8_t shape = fz_u8(in);
    const uint8_t e = (uint8_t)(fz_u8(in) % (MD_ELECTRODES + 1u));
    const uint8_t count = (uint8_t)(fz_u8(in) % (MD_REC_SAMPLES_PER_FRAME + 3u));
    const uint16_t expected = (e < MD_ELECTRODES) ? m->next_seq[e] : 0u;
    uint16_t seq = expected;
    if ((shape & 3u) == 1u) {
        seq = (uint16_t)(expected + (uint16_t)(int16_t)(int8_t)fz_u8(in)); /* near misses: loss, duplicate */
    } else if ((shape & 3u) == 2u) {
        seq = fz_u16(in);
    }
    md_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = MD_CAN_REC_DATA_FRAME_ID;
    f.len = MD_CAN_REC_DATA_LENGTH;
    f.flags = (uint8_t)(MD_FRAME_FLAG_FD | (((shape & 4u) != 0u) ? MD_FRAME_FLAG_BRS : 0u));
    const bool bad_form = (shape & 0xF0u) == 0xF0u;
    if (bad_form) {
        f.flags = (uint8_t)(((shape & 8u) != 0u) ? 0u : MD_FRAME_FLAG_FD);
        f.len = (uint8_t)(((shape & 8u) != 0u) ? 8u : 48u);
    }
    f.data[0] = e;
    f.data[1] = count;
    f.data[2] = (uint8_t)(seq & 0xFFu);
    f.data[3] = (uint8_t)(seq >> 8u);
    memset(&f.data[4], fz_u8(in), MD_FRAME_MAX_DATA - 4u); /* samples: their values do not matter here */

    const md_status_t st = md_node_on_frame(node, &f, now_us);
    if (bad_form) {
        m->bad_length++;
        FUZZ_CHECK(st == MD_E_FRAME);
    } else if (e >= MD_ELECTRODES || count > MD_REC_SAMPLES_PER_FRAME) {
        m->bad_range++;
        FUZZ_CHECK(st == MD_E_FRAME);
    } else if (seq != expected) {
        m->bad_seq++;
        m->next_seq[e] = (uint16_t)(seq + 1u);
        FUZZ_CHECK(st == MD_E_FRAME);
    } else {
        m->accepted++;
        m->next_seq[e] = (uint16_t)(seq + 1u);
        m->samples[e] += count;
        FUZZ_CHECK(st == MD_OK);
    }
    return st;
}

static void rec_end(md_node_t *node, stream_model_t *m, fz_t *in, uint64_t now_us)
{
    const uint8_t e = (uint8_t)(fz_u8(in) % (MD_ELECTRODES + 1u));
    const uint8_t status = (uint8_t)(fz_u8(in) % (MD_REC_OVERFLOW + 2u));
    md_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = MD_CAN_REC_END_FRAME_ID;
    f.len = MD_CAN_REC_END_LENGTH;
    f.data[0] = e;
    f.data[1] = status;
    fz_bytes(in, &f.data[2], 6u);
    const md_status_t st = md_node_on_frame(node, &f, now_us);
    if (e >= MD_ELECTRODES || status > MD_REC_OVERFLOW) {
        m->bad_range++;
        FUZZ_CHECK(st == MD_E_FRAME);
    } else {
        m->accepted++;
        m->next_seq[e] = 0u;
        m->samples[e] = 0u;
        FUZZ_CHECK(st == MD_OK);
    }
}

static void nmt_reset(md_node_t *node, stream_model_t *m, uint64_t now_us)
{
    md_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = MD_CAN_NMT_FRAME_ID;
    f.len = MD_CAN_NMT_LENGTH;
    f.data[0] = (uint8_t)MD_NMT_RESET_NODE;
    f.data[1] = (uint8_t)MD_NODE_CTRL;
    FUZZ_CHECK(md_node_on_frame(node, &f, now_us) == MD_OK);
    m->accepted++;
    memset(m->next_seq, 0, sizeof m->next_seq);
    memset(m->samples, 0, sizeof m->samples);
}

static void check(const md_node_t *node, const stream_model_t *m, const md_node_counters_t *c0)
{
    for (size_t e = 0u; e < MD_ELECTRODES; ++e) {
        FUZZ_CHECK(node->electrode[e].rec_next_seq == m->next_seq[e]);
        FUZZ_CHECK(node->electrode[e].rec_samples == m->samples[e]);
    }
    const md_node_counters_t *c = &node->counters;
    FUZZ_CHECK(c->rx_bad_sequence - c0->rx_bad_sequence == m->bad_seq);
    FUZZ_CHECK(c->rx_bad_range - c0->rx_bad_range == m->bad_range);
    FUZZ_CHECK(c->rx_bad_length - c0->rx_bad_length == m->bad_length);
    FUZZ_CHECK(c->rx_malformed - c0->rx_malformed == m->bad_range + m->bad_length);
    FUZZ_CHECK(c->rx_frames - c0->rx_frames == m->bad_range + m->bad_length + m->bad_seq + m->accepted);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fz_t in;
    fz_init(&in, data, size);
    const md_port_t port = {port_send, port_now, NULL, NULL, NULL};
    static md_node_t node;
    uint64_t now_us = 1000u;
    FUZZ_CHECK(md_node_init(&node, &port, now_us) == MD_OK);
    (void)md_node_poll(&node, now_us);
    const md_node_counters_t c0 = node.counters;
    stream_model_t m;
    memset(&m, 0, sizeof m);
    for (size_t ops = 0u; ops < 1024u && fz_left(&in) > 0u; ++ops) {
        const uint8_t op = fz_u8(&in);
        now_us += op; /* time does not matter to the stream, but must not stand still */
        if (op < 200u) {
            (void)rec_data(&node, &m, &in, now_us);
        } else if (op < 250u) {
            rec_end(&node, &m, &in, now_us);
        } else {
            nmt_reset(&node, &m, now_us);
        }
        check(&node, &m, &c0);
    }
    return 0;
}
