/// @file session_track.c
/// The session's recorder: every frame into the candump -L log, and the
/// controller's telemetry followed for progress lines and the end of the
/// session (docs/session.md, "When a session ends").
#include <inttypes.h>
#include <string.h>

#include "control/sfsm.h"
#include "md_bus_text.h"
#include "md_can.h"
#include "md_protocol.h"
#include "session.h"

void session_track_init(session_track_t *t, FILE *log, const char *iface, uint32_t electrodes, session_goal_t goal,
                        bool quiet)
{
    memset(t, 0, sizeof *t);
    t->log = log;
    (void)snprintf(t->iface, sizeof t->iface, "%s", iface);
    t->electrodes = (electrodes > SESSION_MAX_ELECTRODES) ? SESSION_MAX_ELECTRODES : electrodes;
    t->goal = goal;
    t->quiet = quiet;
    t->log_samples = false;
    for (uint32_t e = 0; e < SESSION_MAX_ELECTRODES; e++) {
        t->status_last_cycle[e] = -1;
        t->need_cycle[e] = -1;
    }
}

static void track_log(session_track_t *t, const md_frame_t *f, uint64_t stamp_us)
{
    char text[MD_BUS_TEXT_MAX];
    if (t->log == NULL || (!t->log_samples && f->id == MD_CAN_REC_DATA_FRAME_ID) ||
        md_bus_text_format(f, text, sizeof text) < 0) {
        return;
    }
    (void)fprintf(t->log, "(%010" PRIu64 ".%06" PRIu64 ") %s %s\n", stamp_us / 1000000u, stamp_us % 1000000u, t->iface,
                  text);
}

static void track_status(session_track_t *t, const md_frame_t *f)
{
    struct md_can_tlm_status_t s;
    if (f->len != MD_CAN_TLM_STATUS_LENGTH || md_can_tlm_status_unpack(&s, f->data, f->len) != 0 ||
        s.electrode >= SESSION_MAX_ELECTRODES) {
        return;
    }
    t->status_count[s.electrode]++;
    t->status_last_cycle[s.electrode] = (int32_t)s.cycle;
    t->moved_on = false; /* its TLM_TRACK, TLM_WAVE, TLM_HYP and TLM_SPIKES follow */
    if (t->quiet) {
        return;
    }
    (void)printf("e%u cycle %4u  %-18s depth %8.1f um  target %8.1f um  track %5u  SNR %6.2f  IQM %7.2f"
                 "  spikes %5u  t %8.1f s\n",
                 (unsigned)s.electrode, (unsigned)s.cycle, sfsm_state_name((sfsm_state_t)s.sfsm_state),
                 (double)s.depth_um, (double)s.target_depth_um, (unsigned)s.dominant_track, (double)s.snr,
                 (double)s.iqm, (unsigned)s.num_spikes, (double)t->sim_clock_us * 1e-6);
    (void)fflush(stdout);
}

static void track_cycle(session_track_t *t, const md_frame_t *f)
{
    struct md_can_tlm_cycle_t c;
    if (f->len != MD_CAN_TLM_CYCLE_LENGTH || md_can_tlm_cycle_unpack(&c, f->data, f->len) != 0 ||
        c.electrode >= SESSION_MAX_ELECTRODES || c.phase != 0u) {
        return;
    }
    if (t->goal.duration_us > 0u && c.start_time_us < t->goal.duration_us &&
        (int32_t)c.cycle > t->need_cycle[c.electrode]) {
        t->need_cycle[c.electrode] = (int32_t)c.cycle;
    }
}

static void track_heartbeat(session_track_t *t, const md_frame_t *f)
{
    const uint32_t node = f->id - 0x700u;
    if (node >= 1u && node <= 5u && f->len >= 1u) {
        t->hb_seen[node]++;
        if (node == MD_NODE_CTRL && f->data[0] == (uint8_t)MD_NODE_STATE_BOOT) {
            t->fw_booted = true;
        }
    }
}

static void track_clock(session_track_t *t, const md_frame_t *f)
{
    struct md_can_sim_clock_t c;
    if ((f->flags & MD_FRAME_FLAG_EXT) == 0u && f->id == MD_CAN_SIM_CLOCK_FRAME_ID &&
        f->len == MD_CAN_SIM_CLOCK_LENGTH && md_can_sim_clock_unpack(&c, f->data, f->len) == 0) {
        t->sim_clock_us = c.sim_time_us;
        t->clock_seen = true;
    }
}

void session_track_frame(session_track_t *t, const md_frame_t *f, uint64_t stamp_us)
{
    t->frames++;
    track_clock(t, f);
    track_log(t, f, t->stamp_sim ? t->sim_clock_us : stamp_us);
    session_rec_frame(t->rec, f, t->sim_clock_us, t->clock_seen);
    if ((f->flags & MD_FRAME_FLAG_EXT) != 0u) {
        return;
    }
    if (f->id >= 0x701u && f->id <= 0x705u) {
        track_heartbeat(t, f);
        return;
    }
    t->activity++;
    switch (f->id) {
    case MD_CAN_FE_INFO_FRAME_ID:
        if (f->len == MD_CAN_FE_INFO_LENGTH && f->data[0] < SESSION_MAX_ELECTRODES) {
            t->fe_info_mask |= 1u << f->data[0];
        }
        break;
    case MD_CAN_TLM_STATUS_FRAME_ID: track_status(t, f); break;
    case MD_CAN_TLM_CYCLE_FRAME_ID:
        track_cycle(t, f);
        t->moved_on = true;
        break;
    case MD_CAN_REC_REQ_FRAME_ID:
    case MD_CAN_ACT_CMD_FRAME_ID: t->moved_on = true; break;
    default: break;
    }
}

bool session_track_done(const session_track_t *t)
{
    if (t->goal.cycles > 0u) {
        for (uint32_t e = 0; e < t->electrodes; e++) {
            if (t->status_count[e] < t->goal.cycles) {
                return false;
            }
        }
        return true;
    }
    if (t->goal.duration_us > 0u) {
        if (!t->clock_seen || t->sim_clock_us < t->goal.duration_us) {
            return false;
        }
        /* every interval that started before the end has been reported */
        for (uint32_t e = 0; e < t->electrodes; e++) {
            if (t->need_cycle[e] >= 0 && t->status_last_cycle[e] < t->need_cycle[e]) {
                return false;
            }
        }
        return true;
    }
    return false;
}

bool session_track_done_complete(const session_track_t *t)
{
    return session_track_done(t) && t->moved_on;
}

void session_track_summary(const session_track_t *t, FILE *out)
{
    (void)fprintf(out,
                  "microdrive-session: %" PRIu64 " frames, simulated time %.3f s, cycles per electrode:", t->frames,
                  (double)t->sim_clock_us * 1e-6);
    for (uint32_t e = 0; e < t->electrodes; e++) {
        (void)fprintf(out, " e%u=%u", (unsigned)e, (unsigned)t->status_count[e]);
    }
    (void)fprintf(out, "\n");
}

const char *session_end_name(session_end_t e)
{
    switch (e) {
    case SESSION_END_GOAL: return "goal reached";
    case SESSION_END_IDLE: return "idle (no plant or telemetry frame for --idle-s)";
    case SESSION_END_SIGNAL: return "signal";
    case SESSION_END_ERROR:
    default: return "error";
    }
}
