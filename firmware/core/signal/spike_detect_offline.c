/// @file spike_detect_offline.c
/// The offline convenience path over the streaming detector (see
/// spike_detect_offline.h).
#include "signal/spike_detect_offline.h"

#include <string.h>

#define SD_DET_IDLE 0
#define SD_DET_STREAMING 1
#define SD_DET_DONE 2

md_status_t sd_init(sd_detector_t *det, const sd_config_t *cfg, int16_t *buf, size_t cap)
{
    if ((det == NULL) || (buf == NULL) || (cap == 0u) || (cap > SD_MAX_INTERVAL_SAMPLES)) {
        return MD_E_ARG;
    }
    det->state = SD_DET_IDLE;
    const md_status_t r = sd_stream_init(&det->s, cfg);
    if (r < 0) {
        return r;
    }
    det->buf = buf;
    det->cap = cap;
    det->n = 0u;
    det->n_dropped = 0u;
    det->state = SD_DET_STREAMING;
    return MD_OK;
}

md_status_t sd_restart(sd_detector_t *det)
{
    if ((det == NULL) || (det->state == SD_DET_IDLE)) {
        return MD_E_STATE;
    }
    det->n = 0u;
    det->n_dropped = 0u;
    det->state = SD_DET_STREAMING;
    return sd_stream_restart(&det->s);
}

/* Streams x through the detector (no consumer to service between steps). */
static void sd_feed(sd_stream_t *st, const int16_t *x, size_t n)
{
    size_t off = 0u;
    for (size_t it = 0u; (it <= n + SD_WARMUP_MAX + 2u) && ((off < n) || sd_stream_busy(st)); ++it) {
        size_t used = 0u;
        if (sd_stream_push(st, &x[off], n - off, &used) < 0) {
            return; /* flat warm-up or capacity: reported by sd_finish */
        }
        off += used;
    }
}

md_status_t sd_push(sd_detector_t *det, const int16_t *samples, size_t n)
{
    if ((det == NULL) || ((samples == NULL) && (n > 0u))) {
        return MD_E_ARG;
    }
    if (det->state != SD_DET_STREAMING) {
        return MD_E_STATE;
    }
    const size_t room = det->cap - det->n;
    const size_t take = (n < room) ? n : room;
    memcpy(&det->buf[det->n], samples, take * sizeof samples[0]);
    sd_feed(&det->s, &det->buf[det->n], take);
    det->n += take;
    if (take < n) {
        const size_t lost = n - take;
        det->n_dropped += (lost > 0xFFFFFFFFu - det->n_dropped) ? (0xFFFFFFFFu - det->n_dropped) : (uint32_t)lost;
        return MD_E_CAPACITY;
    }
    return MD_OK;
}

md_status_t sd_finish(sd_detector_t *det, sd_events_t *ev)
{
    if ((det == NULL) || (ev == NULL)) {
        return MD_E_ARG;
    }
    if (det->state != SD_DET_STREAMING) {
        return MD_E_STATE;
    }
    det->state = SD_DET_DONE;
    md_status_t r = sd_stream_end(&det->s);
    if (r == MD_OK) {
        sd_feed(&det->s, NULL, 0u);
        r = sd_stream_finish(&det->s);
    }
    *ev = det->s.ev;
    ev->n_samples = (uint32_t)det->n;
    ev->flags |= (det->n_dropped > 0u) ? SD_FLAG_TRUNCATED : 0u;
    return r;
}

const int16_t *sd_samples(const sd_detector_t *det, size_t *n)
{
    if (det == NULL) {
        return NULL;
    }
    if (n != NULL) {
        *n = det->n;
    }
    return det->buf;
}
