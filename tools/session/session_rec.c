/// @file session_rec.c
/// The session's recording: the samples the controller recorded (REC_DATA),
/// written as they pass into a raw int16 binary, and at the end a JSON
/// sidecar with one entry per interval (start sample, length, the
/// controller's depth, the Hall reading) in the format tools/recording reads
/// (recording.h; docs/session.md "The recording").
#include <errno.h>
#include <inttypes.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/types.h>
#include <unistd.h>

#include "md_can.h"
#include "md_cycle.h"
#include "md_protocol.h"
#include "session.h"

#define REC_NONE (-1)

static void rec_paths(const session_rec_t *r, uint32_t e, char *bin, char *json, size_t len)
{
    if (r->electrodes == 1u) {
        (void)snprintf(bin, len, "%s/recording.bin", r->dir);
        (void)snprintf(json, len, "%s/recording.json", r->dir);
    } else {
        (void)snprintf(bin, len, "%s/recording-e%u.bin", r->dir, (unsigned)e);
        (void)snprintf(json, len, "%s/recording-e%u.json", r->dir, (unsigned)e);
    }
}

int session_rec_open(session_rec_t *r, const char *dir, uint32_t electrodes, const char *scenario, uint64_t seed,
                     char *msg, size_t msglen)
{
    memset(r, 0, sizeof *r);
    (void)snprintf(r->dir, sizeof r->dir, "%s", dir);
    r->electrodes = (electrodes > SESSION_MAX_ELECTRODES) ? SESSION_MAX_ELECTRODES : electrodes;
    r->seed = seed;
    /* the scenario's name goes into a JSON string: keep plain characters only */
    size_t k = 0u;
    for (const char *s = scenario; s != NULL && *s != '\0' && k + 1u < sizeof r->scenario; s++) {
        const char c = *s;
        const bool plain = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
                           c == '-' || c == '.';
        r->scenario[k++] = plain ? c : '_';
    }
    r->scenario[k] = '\0';
    for (uint32_t e = 0u; e < r->electrodes; e++) {
        session_rec_electrode_t *el = &r->el[e];
        char bin[SESSION_REC_PATH_MAX + 32u], json[SESSION_REC_PATH_MAX + 32u];
        rec_paths(r, e, bin, json, sizeof bin);
        el->bin = fopen(bin, "wb");
        if (el->bin == NULL) {
            (void)snprintf(msg, msglen, "cannot write %s: %s", bin, strerror(errno));
            session_rec_abandon(r);
            return -1;
        }
        el->open = REC_NONE;
        el->await_status = REC_NONE;
        el->last_hall = REC_NONE;
    }
    r->active = true;
    return 0;
}

static void on_req(session_rec_electrode_t *el, const md_frame_t *f, uint64_t clock_us, bool clock_seen)
{
    struct md_can_rec_req_t m;
    if (md_can_rec_req_unpack(&m, f->data, f->len) != 0) {
        return;
    }
    el->open = REC_NONE; /* an interval without its REC_END stays as recorded, incomplete */
    if (el->n >= SESSION_REC_MAX_INTERVALS) {
        el->dropped++;
        return;
    }
    session_rec_interval_t *iv = &el->iv[el->n];
    memset(iv, 0, sizeof *iv);
    iv->start_sample = el->written;
    iv->requested = m.num_samples;
    iv->interval_id = m.interval_id;
    iv->cycle = REC_NONE;
    iv->start_s = clock_seen ? (double)clock_us * 1e-6 : nan("");
    iv->depth_um = nan("");
    iv->hall_code = REC_NONE;
    el->open = (int32_t)el->n;
    el->await_status = REC_NONE;
    el->next_seq = 0u;
    el->n++;
}

static void on_data(session_rec_t *r, session_rec_electrode_t *el, const md_frame_t *f, uint64_t clock_us)
{
    if (el->open == REC_NONE || f->len < 4u) {
        return;
    }
    session_rec_interval_t *iv = &el->iv[el->open];
    const uint32_t count = (f->data[1] <= MD_REC_SAMPLES_PER_FRAME) ? f->data[1] : MD_REC_SAMPLES_PER_FRAME;
    const uint16_t seq = (uint16_t)((uint16_t)f->data[2] | (uint16_t)((uint16_t)f->data[3] << 8));
    const size_t bytes = 2u * (size_t)count;
    if (4u + bytes > f->len) {
        iv->gap = true; /* a frame shorter than its SampleCount: nothing of it is kept */
        return;
    }
    if (seq != el->next_seq) {
        iv->gap = true;
    }
    if (iv->num_samples == 0u && !isnan(iv->start_s)) {
        iv->start_s = (double)clock_us * 1e-6; /* lockstep: the SIM_CLOCK that opens the stream */
    }
    el->next_seq = (uint16_t)(seq + 1u);
    /* DBC: Sample00.. little-endian int16 at bit 32 + 16 i; the binary is
     * little-endian int16 too, so the bytes go out as they came */
    if (fwrite(&f->data[4], 1u, bytes, el->bin) != bytes) {
        r->write_error = errno != 0 ? errno : EIO;
    }
    iv->num_samples += count;
    el->written += count;
}

static void on_end(session_rec_electrode_t *el, const md_frame_t *f)
{
    struct md_can_rec_end_t m;
    if (el->open == REC_NONE || md_can_rec_end_unpack(&m, f->data, f->len) != 0) {
        return;
    }
    session_rec_interval_t *iv = &el->iv[el->open];
    if (m.interval_id != iv->interval_id) {
        return;
    }
    iv->ended = true;
    iv->complete = m.status == MD_REC_COMPLETE && !iv->gap && iv->num_samples == iv->requested &&
                   m.total_samples == iv->num_samples;
    iv->hall_code = el->last_hall;
    el->await_status = el->open;
    el->open = REC_NONE;
}

static void on_status(session_rec_electrode_t *el, const md_frame_t *f)
{
    struct md_can_tlm_status_t s;
    if (el->await_status == REC_NONE || md_can_tlm_status_unpack(&s, f->data, f->len) != 0) {
        return;
    }
    session_rec_interval_t *iv = &el->iv[el->await_status];
    iv->cycle = (int32_t)s.cycle;
    /* the depth the controller measured after the recording, before any move */
    iv->depth_um = ((s.flags & MD_TLM_F_NO_DEPTH) != 0u) ? nan("") : (double)s.depth_um;
    el->await_status = REC_NONE;
}

void session_rec_frame(session_rec_t *r, const md_frame_t *f, uint64_t clock_us, bool clock_seen)
{
    if (r == NULL || !r->active || (f->flags & MD_FRAME_FLAG_EXT) != 0u || f->len < 1u || f->data[0] >= r->electrodes) {
        return;
    }
    session_rec_electrode_t *el = &r->el[f->data[0]];
    switch (f->id) {
    case MD_CAN_FE_INFO_FRAME_ID: {
        struct md_can_fe_info_t m;
        if (md_can_fe_info_unpack(&m, f->data, f->len) == 0) {
            el->fs_hz = m.sample_rate_hz;
            el->gain_uv = (double)m.gain_u_v_per_lsb;
        }
        break;
    }
    case MD_CAN_REC_REQ_FRAME_ID: on_req(el, f, clock_us, clock_seen); break;
    case MD_CAN_REC_DATA_FRAME_ID: on_data(r, el, f, clock_us); break;
    case MD_CAN_HALL_READING_FRAME_ID: {
        struct md_can_hall_reading_t m;
        if (md_can_hall_reading_unpack(&m, f->data, f->len) == 0) {
            el->last_hall = (int32_t)m.raw_code;
        }
        break;
    }
    case MD_CAN_REC_END_FRAME_ID: on_end(el, f); break;
    case MD_CAN_TLM_STATUS_FRAME_ID: on_status(el, f); break;
    default: break;
    }
}

static void json_number_or_null(FILE *out, const char *key, double v, int decimals)
{
    (void)fprintf(out, ", \"%s\": ", key);
    if (isfinite(v)) {
        (void)fprintf(out, "%.*f", decimals, v);
    } else {
        (void)fprintf(out, "null");
    }
}

/* A number written so that it reads back as the same double (17 significant
 * digits), or null. */
static void json_number_or_null_exact(FILE *out, const char *key, double v)
{
    (void)fprintf(out, ", \"%s\": ", key);
    if (isfinite(v)) {
        (void)fprintf(out, "%.17g", v);
    } else {
        (void)fprintf(out, "null");
    }
}

/* Drops the intervals that never ended or hold no sample (a session that
 * stopped mid-recording, a request that got nothing); the binary is cut at
 * the end of the last one kept, so every sample in it belongs to an interval. */
static void rec_trim(session_rec_electrode_t *el)
{
    uint32_t keep = 0u;
    uint64_t end = 0u;
    for (uint32_t i = 0u; i < el->n; i++) {
        const session_rec_interval_t *iv = &el->iv[i];
        if (iv->ended && iv->num_samples > 0u) {
            keep = i + 1u;
            end = iv->start_sample + iv->num_samples;
        }
    }
    el->n = keep;
    el->written = end;
}

/* Writes electrode e's sidecar; *written: the intervals it lists. 0 ok, -1 (errno set).
 * gain_uV with 17 significant digits: the FE_INFO float32 as the double the controller
 * computes with, so a replay (mhtc-replay) scales by the same gain and gives the same
 * labels (7 digits, 0.195 for 0.19499999284744263, does not: docs/mhtc.md). */
static int rec_write_sidecar(const session_rec_t *r, uint32_t e, const char *json, const char *bin_name,
                             uint32_t *written)
{
    const session_rec_electrode_t *el = &r->el[e];
    FILE *out = fopen(json, "w");
    if (out == NULL) {
        return -1;
    }
    (void)fprintf(out,
                  "{\n  \"sampling_frequency\": %" PRIu32 ",\n  \"num_channels\": 1,\n  \"num_samples\": %" PRIu64
                  ",\n  \"dtype\": \"int16\",\n  \"gain_uV\": %.17g,\n  \"offset_uV\": 0.0,\n"
                  "  \"byte_order\": \"little\",\n  \"layout\": \"interleaved\",\n  \"file\": \"%s\",\n"
                  "  \"scenario\": \"%s\",\n  \"seed\": %" PRIu64 ",\n  \"source\": \"microdrive-session\",\n"
                  "  \"electrode\": %u,\n  \"intervals\": [",
                  el->fs_hz, el->written, el->gain_uv, bin_name, r->scenario, r->seed, (unsigned)e);
    uint32_t k = 0u;
    for (uint32_t i = 0u; i < el->n; i++) {
        const session_rec_interval_t *iv = &el->iv[i];
        if (!iv->ended || iv->num_samples == 0u) {
            continue; /* an empty one: nothing to replay; its samples are none */
        }
        (void)fprintf(out,
                      "%s\n    {\"index\": %u, \"start_sample\": %" PRIu64 ", \"num_samples\": %" PRIu32
                      ", \"duration_s\": %.6f",
                      k > 0u ? "," : "", (unsigned)k, iv->start_sample, iv->num_samples,
                      (double)iv->num_samples / (double)el->fs_hz);
        json_number_or_null(out, "start_s", iv->start_s, 6);
        (void)fprintf(out, ", \"interval_id\": %u", (unsigned)iv->interval_id);
        json_number_or_null(out, "cycle", iv->cycle >= 0 ? (double)iv->cycle : nan(""), 0);
        json_number_or_null_exact(out, "depth_um", iv->depth_um);
        json_number_or_null(out, "hall_code", iv->hall_code >= 0 ? (double)iv->hall_code : nan(""), 0);
        (void)fprintf(out, ", \"complete\": %s}", iv->complete ? "true" : "false");
        k++;
    }
    (void)fprintf(out, "\n  ]\n}\n");
    *written = k;
    const int bad = ferror(out);
    return (fclose(out) != 0 || bad != 0) ? -1 : 0;
}

int session_rec_close(session_rec_t *r, FILE *report)
{
    if (r == NULL || !r->active) {
        return 0;
    }
    r->active = false;
    int rc = 0;
    for (uint32_t e = 0u; e < r->electrodes; e++) {
        session_rec_electrode_t *el = &r->el[e];
        char bin[SESSION_REC_PATH_MAX + 32u], json[SESSION_REC_PATH_MAX + 32u];
        rec_paths(r, e, bin, json, sizeof bin);
        rec_trim(el);
        const int flushed = fflush(el->bin);
        const int cut = ftruncate(fileno(el->bin), (off_t)(el->written * 2u));
        const int closed = fclose(el->bin);
        el->bin = NULL;
        if (r->write_error != 0 || flushed != 0 || cut != 0 || closed != 0) {
            (void)fprintf(report, "microdrive-session: recording %s failed: %s\n", bin,
                          strerror(r->write_error != 0 ? r->write_error : errno));
            rc = -1;
            continue;
        }
        if (el->n == 0u || el->fs_hz == 0u) {
            (void)unlink(bin);
            (void)fprintf(report, "microdrive-session: electrode %u recorded no complete interval%s: no %s\n",
                          (unsigned)e, el->fs_hz == 0u && el->n > 0u ? " with a known sampling rate (no FE_INFO)" : "",
                          bin);
            continue;
        }
        const char *slash = strrchr(bin, '/');
        uint32_t listed = 0u;
        if (rec_write_sidecar(r, e, json, slash != NULL ? slash + 1 : bin, &listed) != 0) {
            (void)fprintf(report, "microdrive-session: cannot write %s: %s\n", json, strerror(errno));
            rc = -1;
            continue;
        }
        (void)fprintf(report, "microdrive-session: recording %s (%" PRIu32 " intervals, %" PRIu64 " samples)%s\n", json,
                      listed, el->written, el->dropped > 0u ? "; intervals past the reader's limit not saved" : "");
    }
    return rc;
}

void session_rec_abandon(session_rec_t *r)
{
    for (uint32_t e = 0u; e < SESSION_MAX_ELECTRODES; e++) {
        if (r->el[e].bin != NULL) {
            (void)fclose(r->el[e].bin);
            r->el[e].bin = NULL;
        }
    }
    r->active = false;
}
