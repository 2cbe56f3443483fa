#define _POSIX_C_SOURCE 200809L
#include "export/sim_export.h"

#include <errno.h>
#include <inttypes.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#define EXPORT_CHUNK 4096u
#define EXPORT_GT_CAP 8192u

typedef struct {
    uint64_t sample;
    uint32_t channel;
    int32_t neuron;
} gt_row_t;

typedef struct {
    sim_world_t world;
    int16_t buf[SIM_MAX_ELECTRODES][EXPORT_CHUNK];
    int16_t inter[SIM_MAX_ELECTRODES * EXPORT_CHUNK];
    sim_gt_spike_t gt[EXPORT_GT_CAP];
    gt_row_t rows[EXPORT_GT_CAP];
    FILE *bin, *csv, *jsonl, *json;
} export_state_t;

static int row_cmp(const void *pa, const void *pb)
{
    const gt_row_t *a = pa, *b = pb;
    if (a->sample != b->sample) return (a->sample < b->sample) ? -1 : 1;
    if (a->channel != b->channel) return (a->channel < b->channel) ? -1 : 1;
    return (a->neuron < b->neuron) ? -1 : (a->neuron > b->neuron) ? 1 : 0;
}

static void put_le16(int16_t *v, size_t n)
{
    /* recording.bin is little-endian whatever the host */
    const uint16_t probe = 1u;
    unsigned char first;
    memcpy(&first, &probe, 1u);
    for (size_t i = 0u; first == 0u && i < n; ++i) {
        const uint16_t u = (uint16_t)v[i];
        const uint16_t s = (uint16_t)((uint16_t)(u << 8) | (uint16_t)(u >> 8));
        memcpy(&v[i], &s, sizeof s);
    }
}

/* Records n samples on every channel; file_pos is the interval's file start. */
static md_status_t record_span(export_state_t *x, size_t n, uint64_t file_pos)
{
    sim_world_t *w = &x->world;
    const uint32_t nc = w->n_electrodes;
    size_t n_rows = 0u;
    for (uint32_t e = 0u; e < nc; ++e) {
        const uint64_t abs0 = w->el[e].cursor;
        const size_t ng = sim_electrode_generate(&w->el[e], x->buf[e], n, x->gt, EXPORT_GT_CAP);
        for (size_t k = 0u; k < ng; ++k) {
            if (x->gt[k].neuron_id < 0) {
                continue;
            }
            if (n_rows >= EXPORT_GT_CAP) {
                return MD_E_CAPACITY; /* never drop truth silently */
            }
            x->rows[n_rows++] = (gt_row_t){file_pos + (x->gt[k].sample - abs0), e, x->gt[k].neuron_id};
        }
    }
    for (size_t i = 0u; i < n; ++i) {
        for (uint32_t e = 0u; e < nc; ++e) {
            x->inter[i * nc + e] = x->buf[e][i];
        }
    }
    put_le16(x->inter, n * nc);
    if (fwrite(x->inter, sizeof(int16_t), n * nc, x->bin) != n * nc) {
        return MD_E_IO;
    }
    qsort(x->rows, n_rows, sizeof x->rows[0], row_cmp);
    for (size_t k = 0u; k < n_rows; ++k) {
        (void)fprintf(x->csv, "%" PRIu64 ",%" PRIu32 ",%" PRId32 "\n", x->rows[k].sample, x->rows[k].channel,
                      x->rows[k].neuron);
    }
    return MD_OK;
}

/* The scripted move between intervals; time passes without recording. */
static void scripted_move(sim_world_t *w, const scenario_export_t *ex)
{
    double longest_s = 0.0;
    for (uint32_t e = 0u; e < w->n_electrodes && (ex->step_um > 0.0 || ex->step_um < 0.0); ++e) {
        const actuator_params_t *ap = &w->el[e].act.p;
        const uint32_t steps = actuator_steps_for(ap, ex->step_um);
        (void)sim_electrode_command(&w->el[e], steps, ex->step_um > 0.0 ? 1 : -1, ap->max_rate_hz);
        longest_s = fmax(longest_s, (double)steps / ap->max_rate_hz);
    }
    sim_world_advance_s(w, longest_s + 0.01);
    for (uint32_t guard = 0u; !sim_world_idle(w) && guard < 100000u; ++guard) {
        sim_world_advance_s(w, 0.01);
    }
    sim_world_advance_s(w, ex->settle_s);
}

static void write_interval_json(export_state_t *x, uint32_t i, uint64_t start, size_t n, double t0, const double *d0,
                                const double *d1, const double *hall)
{
    const uint32_t nc = x->world.n_electrodes;
    const double fs = x->world.el[0].fs;
    (void)fprintf(x->json,
                  "%s\n    {\"index\": %" PRIu32 ", \"start_sample\": %" PRIu64 ", \"num_samples\": %zu"
                  ", \"start_s\": %.6f, \"duration_s\": %.6f,",
                  i ? "," : "", i, start, n, t0, (double)n / fs);
    const char *names[3] = {"depth_um", "depth_end_um", "sensor_depth_um"};
    const double *vals[3] = {d0, d1, hall};
    for (uint32_t k = 0u; k < 3u; ++k) {
        (void)fprintf(x->json, " \"%s\": [", names[k]);
        for (uint32_t e = 0u; e < nc; ++e) {
            (void)fprintf(x->json, "%s%.4f", e ? ", " : "", vals[k][e]);
        }
        (void)fprintf(x->json, "]%s", k < 2u ? "," : "}");
    }
}

static md_status_t export_run(export_state_t *x, const scenario_t *sc)
{
    sim_world_t *w = &x->world;
    const scenario_export_t *ex = &sc->export_cfg;
    const double fs = w->el[0].fs;
    const size_t per = (size_t)floor(ex->interval_s * fs + 0.5);
    (void)fprintf(x->csv, "sample_index,channel,neuron_id\n");
    (void)fprintf(x->json,
                  "{\n  \"sampling_frequency\": %.3f,\n  \"num_channels\": %" PRIu32 ",\n  \"num_samples\": %zu,\n"
                  "  \"dtype\": \"int16\",\n  \"gain_uV\": %.6f,\n  \"offset_uV\": 0.0,\n"
                  "  \"byte_order\": \"little\",\n  \"layout\": \"interleaved\",\n  \"seed\": %" PRIu64 ",\n"
                  "  \"scenario\": \"%s\",\n  \"intervals\": [",
                  fs, w->n_electrodes, per * ex->intervals, sc->electrodes[0].signal.adc_gain_uv, w->seed, sc->name);
    for (uint32_t i = 0u; i < ex->intervals; ++i) {
        double d0[SIM_MAX_ELECTRODES], d1[SIM_MAX_ELECTRODES], hall[SIM_MAX_ELECTRODES];
        char label[32];
        (void)snprintf(label, sizeof label, "interval %" PRIu32, i);
        sim_world_truth_snapshot(w, label);
        const double t0 = sim_electrode_time_s(&w->el[0]);
        for (uint32_t e = 0u; e < w->n_electrodes; ++e) {
            d0[e] = sim_electrode_tip_um(&w->el[e]);
            hall[e] = hall_cal_depth_um(&w->el[e].hall.cal, (double)sim_electrode_hall_read(&w->el[e]));
        }
        const uint64_t start = (uint64_t)i * per;
        for (size_t done = 0u; done < per;) {
            const size_t n = (per - done < EXPORT_CHUNK) ? per - done : EXPORT_CHUNK;
            const md_status_t st = record_span(x, n, start + done);
            if (st != MD_OK) {
                return st;
            }
            done += n;
        }
        for (uint32_t e = 0u; e < w->n_electrodes; ++e) {
            d1[e] = sim_electrode_tip_um(&w->el[e]);
        }
        write_interval_json(x, i, start, per, t0, d0, d1, hall);
        if (i + 1u < ex->intervals) {
            scripted_move(w, ex);
        }
    }
    (void)fprintf(x->json, "\n  ]\n}\n");
    return MD_OK;
}

__attribute__((format(printf, 3, 4))) static void set_err(char *err, size_t errlen, const char *fmt, ...)
{
    if (err == NULL || errlen == 0u) {
        return;
    }
    va_list ap;
    va_start(ap, fmt);
    (void)vsnprintf(err, errlen, fmt, ap);
    va_end(ap);
}

static FILE *open_in(const char *dir, const char *name, const char *mode)
{
    char path[4096];
    const int n = snprintf(path, sizeof path, "%s/%s", dir, name);
    if (n < 0 || (size_t)n >= sizeof path) {
        return NULL;
    }
    return fopen(path, mode);
}

md_status_t sim_export_recording(const scenario_t *sc, uint64_t seed, const char *dir, char *err, size_t errlen)
{
    if (sc == NULL || dir == NULL) {
        set_err(err, errlen, "sim_export_recording: NULL argument");
        return MD_E_ARG;
    }
    if (mkdir(dir, 0755) != 0 && errno != EEXIST) {
        set_err(err, errlen, "%s: cannot create: %s", dir, strerror(errno));
        return MD_E_IO;
    }
    export_state_t *x = calloc(1u, sizeof *x);
    if (x == NULL) {
        set_err(err, errlen, "out of memory");
        return MD_E_CAPACITY;
    }
    md_status_t st = scenario_make_world(sc, seed, &x->world);
    if (st != MD_OK) {
        set_err(err, errlen, "scenario '%s': cannot build the world (%s)", sc->name, md_status_name(st));
        free(x);
        return st;
    }
    x->bin = open_in(dir, "recording.bin", "wb");
    x->csv = open_in(dir, "ground_truth.csv", "w");
    x->jsonl = open_in(dir, "ground_truth.jsonl", "w");
    x->json = open_in(dir, "recording.json", "w");
    if (x->bin == NULL || x->csv == NULL || x->jsonl == NULL || x->json == NULL) {
        set_err(err, errlen, "%s: cannot write the export files: %s", dir, strerror(errno));
        st = MD_E_IO;
    } else {
        sim_world_set_truth(&x->world, x->jsonl);
        st = export_run(x, sc);
        if (st != MD_OK) {
            set_err(err, errlen, "%s: export failed (%s): %s", dir, md_status_name(st), strerror(errno));
        }
    }
    FILE *files[4] = {x->bin, x->csv, x->jsonl, x->json};
    for (uint32_t i = 0u; i < 4u; ++i) {
        if (files[i] != NULL && fclose(files[i]) != 0 && st == MD_OK) {
            set_err(err, errlen, "%s: close failed: %s", dir, strerror(errno));
            st = MD_E_IO;
        }
    }
    free(x);
    return st;
}
