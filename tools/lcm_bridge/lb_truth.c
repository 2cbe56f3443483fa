/// @file lb_truth.c
/// Ground-truth side of the bridge core: the simulator's JSON-lines truth file
/// (docs/simulator.md section 6, written by host_sim/model/sim_world.c) into
/// the MD_TRUTH_* channels. Parsed with cJSON (Debian libcjson-dev).
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <cjson/cJSON.h>

#include "lb_internal.h"
#include "mdlcm_truth_death_t.h"
#include "mdlcm_truth_session_t.h"
#include "mdlcm_truth_spikes_t.h"
#include "mdlcm_truth_state_t.h"

_Static_assert(LB_TRUTH_SPIKE_BATCH == MDLCM_TRUTH_SPIKES_T_MAX_SPIKES, "batch size is the LCM constant");

/// Number member of obj, or fallback when absent or not a number.
static double num(const cJSON *obj, const char *key, double fallback)
{
    const cJSON *it = cJSON_GetObjectItemCaseSensitive(obj, key);
    return cJSON_IsNumber(it) ? it->valuedouble : fallback;
}

static bool has_num(const cJSON *obj, const char *key)
{
    return cJSON_IsNumber(cJSON_GetObjectItemCaseSensitive(obj, key));
}

static const char *type_of(const cJSON *root)
{
    const cJSON *t = cJSON_GetObjectItemCaseSensitive(root, "type");
    return cJSON_IsString(t) ? t->valuestring : "";
}

/// Microseconds as int64, saturated (NaN: 0): a time far outside any session
/// must not be converted out of range (undefined behaviour).
static int64_t us_sat(double us)
{
    if (isnan(us)) {
        return 0;
    }
    if (us >= 9.2e18) {
        return INT64_MAX;
    }
    if (us <= -9.2e18) {
        return INT64_MIN;
    }
    return (int64_t)llround(us);
}

static int64_t seconds_to_us(double t_s)
{
    return us_sat(t_s * 1e6);
}

static int64_t spike_time_us(const lb_t *st, double sample)
{
    const double fs = st->truth.sample_rate_hz;
    return (fs > 0.0) ? us_sat(sample * 1e6 / fs) : 0;
}

/// Integer member key of obj, checked against the LCM field it goes into:
/// absent or not a number gives fallback; a number must be whole and in
/// [lo, hi_excl), else false (the record is refused: converting an
/// out-of-range double to an integer type is undefined behaviour).
static bool int_field(const cJSON *obj, const char *key, double lo, double hi_excl, int64_t fallback, int64_t *out)
{
    const cJSON *it = cJSON_GetObjectItemCaseSensitive(obj, key);
    if (!cJSON_IsNumber(it)) {
        *out = fallback;
        return true;
    }
    const double v = it->valuedouble;
    if (!(v >= lo) || !(v < hi_excl) || floor(v) < v) {
        return false;
    }
    *out = (int64_t)v;
    return true;
}

#define I8_LIM 128.0
#define I32_LIM 2147483648.0
#define I64_LIM 9223372036854775808.0

/// An electrode index (int8 in the LCM types, from 0).
static bool electrode_field(const cJSON *obj, int8_t *e)
{
    int64_t v = 0;
    const bool ok = int_field(obj, "electrode", 0.0, I8_LIM, 0, &v);
    *e = (int8_t)v;
    return ok;
}

/// A neuron id (int32; -1 = large artifact).
static bool neuron_field(const cJSON *obj, int32_t fallback, int32_t *n)
{
    int64_t v = 0;
    const bool ok = int_field(obj, "neuron", -I32_LIM, I32_LIM, fallback, &v);
    *n = (int32_t)v;
    return ok;
}

/// A required time t_s: a finite number.
static bool time_field(const cJSON *obj, int64_t *us)
{
    const cJSON *it = cJSON_GetObjectItemCaseSensitive(obj, "t_s");
    if (!cJSON_IsNumber(it) || !isfinite(it->valuedouble)) {
        return false;
    }
    *us = seconds_to_us(it->valuedouble);
    return true;
}

static int64_t record_time_us(const lb_t *st, const cJSON *root)
{
    const char *type = type_of(root);
    if (strcmp(type, "spike") == 0) {
        return spike_time_us(st, num(root, "sample", 0.0));
    }
    if (strcmp(type, "state") == 0 || strcmp(type, "death") == 0) {
        return seconds_to_us(num(root, "t_s", 0.0));
    }
    return 0;
}

static bool blank(const char *line)
{
    for (const char *p = line; *p != '\0'; ++p) {
        if (*p != ' ' && *p != '\t' && *p != '\r' && *p != '\n') {
            return false;
        }
    }
    return true;
}

int64_t lb_truth_time_us(const lb_t *st, const char *line)
{
    cJSON *root = cJSON_Parse(line);
    if (!cJSON_IsObject(root)) {
        cJSON_Delete(root);
        return -1;
    }
    const int64_t t = record_time_us(st, root);
    cJSON_Delete(root);
    return t;
}

static void publish_session(lb_t *st)
{
    lb_truth_session_t *s = &st->truth;
    if (s->published || (!s->have_session && s->n_neurons == 0)) {
        return;
    }
    s->published = true;
    char *shapes[LB_TRUTH_MAX_NEURONS];
    for (int32_t i = 0; i < s->n_neurons; ++i) {
        shapes[i] = s->shape[i];
    }
    const mdlcm_truth_session_t m = {.utime = 0,
                                     .seed = s->seed,
                                     .sample_rate_hz = s->sample_rate_hz,
                                     .num_electrodes = s->n_electrodes,
                                     .bg_rms_uv = s->bg_rms_uv,
                                     .num_neurons = s->n_neurons,
                                     .electrode = s->electrode,
                                     .neuron = s->neuron,
                                     .x_um = s->x_um,
                                     .y_um = s->y_um,
                                     .depth_um = s->depth_um,
                                     .amp_uv = s->amp_uv,
                                     .rate_hz = s->rate_hz,
                                     .shape = shapes};
    LB_PUBLISH(st, LB_CH_TRUTH_SESSION, mdlcm_truth_session_t, &m);
}

static void publish_batch(lb_t *st)
{
    lb_truth_batch_t *b = &st->batch;
    if (b->n == 0) {
        return;
    }
    const mdlcm_truth_spikes_t m = {.utime = spike_time_us(st, (double)b->sample[0]),
                                    .electrode = b->electrode,
                                    .sample_rate_hz = st->truth.sample_rate_hz,
                                    .num_spikes = b->n,
                                    .sample = b->sample,
                                    .neuron = b->neuron,
                                    .amp_uv = b->amp_uv};
    LB_PUBLISH(st, LB_CH_TRUTH_SPIKES, mdlcm_truth_spikes_t, &m);
    b->n = 0;
}

void lb_truth_flush(lb_t *st)
{
    publish_session(st);
    publish_batch(st);
}

static int on_session(lb_t *st, const cJSON *root)
{
    lb_truth_session_t *s = &st->truth;
    const cJSON *bg = cJSON_GetObjectItemCaseSensitive(root, "bg_rms_uv");
    const double fs = num(root, "sample_rate_hz", 0.0);
    const cJSON *seed = cJSON_GetObjectItemCaseSensitive(root, "seed");
    const double sd = cJSON_IsNumber(seed) ? seed->valuedouble : 0.0;
    /* The simulator's seed is a uint64, the LCM field an int64 (same bits);
     * through a double, seeds near 2^64 - 1 arrive as exactly 2^64. */
    if (!(fs > 0.0) || !isfinite(fs) || !cJSON_IsArray(bg) || !(sd >= -I64_LIM) || !(sd <= 2.0 * I64_LIM) ||
        floor(sd) < sd) {
        return -1;
    }
    s->have_session = true;
    s->seed = (sd >= 2.0 * I64_LIM) ? -1 : (sd >= I64_LIM) ? (int64_t)(uint64_t)sd : (int64_t)sd;
    s->sample_rate_hz = fs;
    s->n_electrodes = 0;
    const cJSON *v = NULL;
    cJSON_ArrayForEach(v, bg)
    {
        if (s->n_electrodes < (int16_t)LB_MAX_ELECTRODES) {
            s->bg_rms_uv[s->n_electrodes++] = (float)(cJSON_IsNumber(v) ? v->valuedouble : 0.0);
        } else {
            st->stats.dropped++;
        }
    }
    return 0;
}

static int on_neuron(lb_t *st, const cJSON *root)
{
    lb_truth_session_t *s = &st->truth;
    int8_t e = 0;
    int32_t id = 0;
    if (!has_num(root, "electrode") || !has_num(root, "neuron") || !electrode_field(root, &e) ||
        !neuron_field(root, 0, &id)) {
        return -1;
    }
    if (s->n_neurons >= (int32_t)LB_TRUTH_MAX_NEURONS) {
        st->stats.dropped++;
        return 0;
    }
    const int32_t i = s->n_neurons++;
    s->electrode[i] = e;
    s->neuron[i] = id;
    s->x_um[i] = (float)num(root, "x_um", 0.0);
    s->y_um[i] = (float)num(root, "y_um", 0.0);
    s->depth_um[i] = (float)num(root, "depth_um", 0.0);
    s->amp_uv[i] = (float)num(root, "amp_uv", 0.0);
    s->rate_hz[i] = (float)num(root, "rate_hz", 0.0);
    const cJSON *shape = cJSON_GetObjectItemCaseSensitive(root, "shape");
    const char *text = cJSON_IsString(shape) ? shape->valuestring : "";
    (void)strncpy(s->shape[i], text, sizeof s->shape[i] - 1u);
    s->shape[i][sizeof s->shape[i] - 1u] = '\0';
    return 0;
}

static int on_spike(lb_t *st, const cJSON *root)
{
    int8_t e = 0;
    int32_t id = -1;
    int64_t sample = 0;
    if (!has_num(root, "electrode") || !has_num(root, "sample") || !has_num(root, "neuron") ||
        !electrode_field(root, &e) || !neuron_field(root, -1, &id) ||
        !int_field(root, "sample", 0.0, I64_LIM, 0, &sample)) {
        return -1;
    }
    lb_truth_batch_t *b = &st->batch;
    if (b->n > 0 && (b->electrode != e || b->n >= (int32_t)LB_TRUTH_SPIKE_BATCH)) {
        publish_batch(st);
    }
    b->electrode = e;
    b->sample[b->n] = sample;
    b->neuron[b->n] = id;
    b->amp_uv[b->n] = (float)num(root, "amp_uv", 0.0);
    b->n++;
    return 0;
}

static int on_death(lb_t *st, const cJSON *root)
{
    int8_t e = 0;
    int32_t id = 0;
    int64_t t_us = 0;
    if (!has_num(root, "electrode") || !has_num(root, "neuron") || !time_field(root, &t_us) ||
        !electrode_field(root, &e) || !neuron_field(root, 0, &id)) {
        return -1;
    }
    const mdlcm_truth_death_t m = {
        .utime = t_us, .electrode = e, .neuron = id, .distance_um = (float)num(root, "distance_um", 0.0)};
    LB_PUBLISH(st, LB_CH_TRUTH_DEATH, mdlcm_truth_death_t, &m);
    return 0;
}

/// Fills row i of the state arrays from one element of "neurons"; false if
/// its neuron id does not fit the LCM field.
static bool state_row(const cJSON *n, mdlcm_truth_state_t *m, int32_t i)
{
    const cJSON *alive = cJSON_GetObjectItemCaseSensitive(n, "alive");
    if (!neuron_field(n, -1, &m->neuron[i])) {
        return false;
    }
    m->depth_um[i] = (float)num(n, "depth_um", 0.0);
    m->alive[i] = cJSON_IsTrue(alive) ? 1 : 0;
    m->distance_um[i] = (float)num(n, "distance_um", 0.0);
    m->snr[i] = (float)num(n, "snr", 0.0);
    m->snr_peak_depth_um[i] = (float)num(n, "snr_peak_depth_um", 0.0);
    m->snr_peak[i] = (float)num(n, "snr_peak", 0.0);
    return true;
}

static int on_state(lb_t *st, const cJSON *root)
{
    const cJSON *neurons = cJSON_GetObjectItemCaseSensitive(root, "neurons");
    const cJSON *label = cJSON_GetObjectItemCaseSensitive(root, "label");
    int8_t e = 0;
    int64_t t_us = 0;
    if (!time_field(root, &t_us) || !has_num(root, "electrode") || !electrode_field(root, &e) ||
        !has_num(root, "tip_um") || !cJSON_IsArray(neurons)) {
        return -1;
    }
    static int32_t neuron[LB_TRUTH_MAX_NEURONS];
    static float depth[LB_TRUTH_MAX_NEURONS], dist[LB_TRUTH_MAX_NEURONS], snr[LB_TRUTH_MAX_NEURONS];
    static float peak_depth[LB_TRUTH_MAX_NEURONS], peak[LB_TRUTH_MAX_NEURONS];
    static int8_t alive[LB_TRUTH_MAX_NEURONS];
    mdlcm_truth_state_t m = {.utime = t_us,
                             .electrode = e,
                             .label = (char *)(cJSON_IsString(label) ? label->valuestring : ""),
                             .tip_um = num(root, "tip_um", 0.0),
                             .neuron = neuron,
                             .depth_um = depth,
                             .alive = alive,
                             .distance_um = dist,
                             .snr = snr,
                             .snr_peak_depth_um = peak_depth,
                             .snr_peak = peak};
    const cJSON *n = NULL;
    cJSON_ArrayForEach(n, neurons)
    {
        if (m.num_neurons >= (int32_t)LB_TRUTH_MAX_NEURONS) {
            st->stats.dropped++;
            break;
        }
        if (!state_row(n, &m, m.num_neurons++)) {
            return -1;
        }
    }
    LB_PUBLISH(st, LB_CH_TRUTH_STATE, mdlcm_truth_state_t, &m);
    return 0;
}

static int dispatch(lb_t *st, const cJSON *root)
{
    const char *type = type_of(root);
    const bool header = strcmp(type, "session") == 0 || strcmp(type, "neuron") == 0;
    if (!header) {
        publish_session(st); /* the header records come first; the first other record ends them */
    }
    if (strcmp(type, "spike") != 0) {
        publish_batch(st);
    }
    if (strcmp(type, "session") == 0) {
        return on_session(st, root);
    }
    if (strcmp(type, "neuron") == 0) {
        return on_neuron(st, root);
    }
    if (strcmp(type, "spike") == 0) {
        return on_spike(st, root);
    }
    if (strcmp(type, "death") == 0) {
        return on_death(st, root);
    }
    if (strcmp(type, "state") == 0) {
        return on_state(st, root);
    }
    st->stats.truth_ignored++; /* a record type without an LCM type (e.g. "interval") */
    return 0;
}

int lb_feed_truth_line(lb_t *st, const char *line)
{
    if (blank(line)) {
        return 0;
    }
    cJSON *root = cJSON_Parse(line);
    const bool typed = cJSON_IsObject(root) && cJSON_IsString(cJSON_GetObjectItemCaseSensitive(root, "type"));
    const int rc = typed ? dispatch(st, root) : -1;
    cJSON_Delete(root);
    if (rc != 0) {
        st->stats.truth_errors++;
        return -1;
    }
    st->stats.truth_records++;
    return 0;
}
