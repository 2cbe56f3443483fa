/// @file spike_pipeline.c
/// Detector + extractor of one channel (see spike_pipeline.h).
#include "signal/spike_pipeline.h"

#include <stdbool.h>
#include <string.h>

#define SP_IDLE 0
#define SP_STREAMING 1
#define SP_DONE 2

md_status_t sp_init(sp_channel_t *ch, const sd_config_t *dcfg, const sx_config_t *xcfg, sx_windows_t *win,
                    sx_snippets_t *noise)
{
    if (ch == NULL) {
        return MD_E_ARG;
    }
    ch->state = SP_IDLE;
    md_status_t r = sd_stream_init(&ch->det, dcfg);
    if (r == MD_OK) {
        r = sx_stream_init(&ch->ext, xcfg, &ch->det, win, noise);
    }
    ch->n_stage = 0u;
    ch->slot = 0u;
    ch->state = (r == MD_OK) ? SP_STREAMING : SP_IDLE;
    return r;
}

md_status_t sp_restart(sp_channel_t *ch)
{
    if ((ch == NULL) || (ch->state == SP_IDLE)) {
        return MD_E_STATE;
    }
    const md_status_t r = sd_stream_restart(&ch->det);
    ch->n_stage = 0u;
    ch->slot = 0u;
    ch->state = SP_STREAMING;
    return (r == MD_OK) ? sx_stream_restart(&ch->ext) : r;
}

/* Steps the detector through x (and through a pending warm-up replay),
 * servicing the extractor after every step. Each sd_stream_push call
 * consumes input or advances the replay, so the loop bound is never hit. */
static md_status_t sp_drive(sp_channel_t *ch, const int16_t *x, size_t n)
{
    size_t off = 0u;
    md_status_t r = MD_OK;
    uint32_t before = sd_stream_processed(&ch->det);
    for (size_t it = 0u; (it <= n + SD_WARMUP_MAX + 2u) && ((off < n) || sd_stream_busy(&ch->det)); ++it) {
        size_t used = 0u;
        r = sd_stream_push(&ch->det, (x != NULL) ? &x[off] : NULL, n - off, &used);
        off += used;
        if (r < 0) {
            return r;
        }
        const uint32_t now = sd_stream_processed(&ch->det);
        if ((now != before) && ((now % SX_SERVICE_MAX) == 0u)) { /* fixed sample indices: chunk-independent */
            r = sx_stream_service(&ch->ext, &ch->det, false);
            if (r < 0) {
                return r;
            }
        }
        before = now;
    }
    return r;
}

/* sp_drive for one whole step, with the common case kept short. A push of
 * samples that succeeds either leaves sd_stream_processed() at 0 (warm-up)
 * or advances it (a replay step or an online step), so "processed() > 0"
 * stands for sp_drive's "processed() changed"; and a push that took the
 * whole step and left processed() > 0 was an online step (a replay takes no
 * input, the warm-up leaves the count at 0), so no replay can be pending and
 * the step is done once the extractor is serviced. Any other outcome
 * continues in sp_drive. */
static md_status_t sp_step(sp_channel_t *ch, const int16_t *x)
{
    size_t used = 0u;
    md_status_t r = sd_stream_push(&ch->det, x, SD_STEP_SAMPLES, &used);
    if (r != MD_OK) { /* every error code is negative */
        return r;
    }
    const uint32_t now = sd_stream_processed(&ch->det);
    if ((now > 0u) && ((now % SX_SERVICE_MAX) == 0u)) {
        r = sx_stream_service(&ch->ext, &ch->det, false);
        if (r != MD_OK) {
            return r;
        }
    }
    if ((used == SD_STEP_SAMPLES) && (now > 0u)) {
        return r;
    }
    return sp_drive(ch, &x[used], SD_STEP_SAMPLES - used);
}

/* Completes the staged step with x[0 .. room) and drives it. If the rest of
 * x (< one step) fits the next slot it is copied along in the same memcpy
 * and staged there (*done: x used up); otherwise the caller goes on at
 * x[room]. As before, nothing stays staged after a failed step. */
static md_status_t sp_complete(sp_channel_t *ch, const int16_t *x, size_t n, bool *done)
{
    *done = true;
    if (x == NULL) {
        return MD_E_ARG; /* not reached: n > 0 here */
    }
    const size_t room = SD_STEP_SAMPLES - ch->n_stage;
    const size_t rest = n - room;
    int16_t *cur = &ch->stage[(size_t)ch->slot * SD_STEP_SAMPLES];
    const uint32_t slots = (uint32_t)(sizeof ch->stage / sizeof ch->stage[0]) / SD_STEP_SAMPLES;
    *done = (rest < SD_STEP_SAMPLES) && ((ch->slot + 1u) < slots);
    memcpy(&cur[ch->n_stage], x, (*done ? n : room) * sizeof x[0]);
    ch->n_stage = 0u;
    const md_status_t r = sp_step(ch, cur);
    if (*done && (r == MD_OK) && (rest > 0u)) {
        ch->slot++;
        ch->n_stage = (uint32_t)rest;
    }
    return r;
}

md_status_t sp_push(sp_channel_t *ch, const int16_t *x, size_t n)
{
    if ((ch == NULL) || ((x == NULL) && (n > 0u))) {
        return MD_E_ARG;
    }
    if (ch->state != SP_STREAMING) {
        return MD_E_STATE;
    }
    size_t off = 0u;
    md_status_t r = MD_OK;
    if (ch->n_stage > 0u) { /* complete the staged step first */
        const size_t room = SD_STEP_SAMPLES - ch->n_stage;
        if (n < room) {
            memcpy(&ch->stage[((size_t)ch->slot * SD_STEP_SAMPLES) + ch->n_stage], x, n * sizeof x[0]);
            ch->n_stage += (uint32_t)n;
            return MD_OK;
        }
        bool done = false;
        r = sp_complete(ch, x, n, &done);
        if (done) {
            return r;
        }
        off = room;
    }
    const size_t whole = (n - off) / SD_STEP_SAMPLES * SD_STEP_SAMPLES;
    if ((r == MD_OK) && (whole > 0u)) {
        r = sp_drive(ch, &x[off], whole);
    }
    off += whole;
    if ((r == MD_OK) && (off < n)) {
        ch->slot = 0u;
        memcpy(ch->stage, &x[off], (n - off) * sizeof x[0]);
        ch->n_stage = (uint32_t)(n - off);
    }
    return r;
}

md_status_t sp_finish(sp_channel_t *ch)
{
    if (ch == NULL) {
        return MD_E_ARG;
    }
    if (ch->state != SP_STREAMING) {
        return MD_E_STATE;
    }
    ch->state = SP_DONE;
    md_status_t r = sp_drive(ch, &ch->stage[(size_t)ch->slot * SD_STEP_SAMPLES], ch->n_stage);
    ch->n_stage = 0u;
    if (r < 0) {
        return r;
    }
    r = sd_stream_end(&ch->det);
    if (r == MD_OK) {
        r = sp_drive(ch, NULL, 0u);
    }
    if (r == MD_OK) {
        r = sd_stream_finish(&ch->det);
    }
    if (r == MD_OK) {
        r = sx_stream_service(&ch->ext, &ch->det, true);
    }
    return r;
}

const sd_events_t *sp_events(const sp_channel_t *ch)
{
    return (ch == NULL) ? NULL : sd_stream_events(&ch->det);
}
