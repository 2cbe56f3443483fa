#include "scenario/scenario.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <yaml.h>

/* ---- field tables --------------------------------------------------------- */

typedef enum { FT_DOUBLE, FT_U32, FT_U64, FT_SHAPE, FT_STRING } ftype_t;

typedef struct {
    const char *key;
    ftype_t type;
    size_t off;
    double lo, hi;
    bool required;
} field_t;

/* clang-format would split these initialiser macros over lines. */
/* clang-format off */
#define FD(st, k, lo, hi) {#k, FT_DOUBLE, offsetof(st, k), (lo), (hi), false}
#define FU(st, k, lo, hi) {#k, FT_U32, offsetof(st, k), (lo), (hi), false}
/* clang-format on */
#define NFIELDS(t) (sizeof(t) / sizeof((t)[0]))

static const field_t ACTUATOR_FIELDS[] = {
    FD(actuator_params_t, step_nm, 1.0, 10000.0),      FD(actuator_params_t, step_cv, 0.0, 1.0),
    FD(actuator_params_t, retract_ratio, 0.1, 2.0),    FD(actuator_params_t, miss_prob, 0.0, 1.0),
    FD(actuator_params_t, slip_prob, 0.0, 1.0),        FD(actuator_params_t, slip_nm, 0.0, 10000.0),
    FD(actuator_params_t, max_rate_hz, 1.0, 100000.0), FD(actuator_params_t, travel_um, 100.0, 50000.0),
};

static const field_t SENSOR_FIELDS[] = {
    FD(hall_params_t, center_um, -1e5, 1e5),
    FD(hall_params_t, length_um, 10.0, 1e6),
    FD(hall_params_t, offset_codes, 0.0, 16777216.0),
    FD(hall_params_t, amplitude_codes, 1.0, 16777216.0),
    FU(hall_params_t, adc_bits, 8.0, 24.0),
    FD(hall_params_t, noise_codes, 0.0, 1e4),
    FD(hall_params_t, drift_codes_per_hour, -1e4, 1e4),
    FD(hall_params_t, drift_amp_codes, 0.0, 1e4),
    FD(hall_params_t, drift_period_s, 1.0, 1e7),
    FD(hall_params_t, report_rate_hz, 0.1, 10000.0),
    FU(hall_params_t, cal_degree, 1.0, (double)HALL_CAL_MAX_DEGREE),
};

static const field_t TISSUE_FIELDS[] = {
    FD(tissue_params_t, drift_um_per_min, -100.0, 100.0),  FD(tissue_params_t, drift_start_s, 0.0, 1e7),
    FD(tissue_params_t, insert_relax_um, -1000.0, 1000.0), FD(tissue_params_t, insert_tau_s, 1.0, 1e7),
    FD(tissue_params_t, drag_advance, 0.0, 1.0),           FD(tissue_params_t, drag_retract, 0.0, 1.0),
    FD(tissue_params_t, permanent_fraction, 0.0, 1.0),     FD(tissue_params_t, move_tau_s, 0.1, 1e6),
    FD(tissue_params_t, max_relax_um, 0.0, 1000.0),        FD(tissue_params_t, breathing_um, 0.0, 50.0),
    FD(tissue_params_t, breathing_hz, 0.01, 10.0),         FD(tissue_params_t, heartbeat_um, 0.0, 20.0),
    FD(tissue_params_t, heartbeat_hz, 0.1, 10.0),
};

static const field_t SIGNAL_FIELDS[] = {
    FD(signal_params_t, sample_rate_hz, 20000.0, 50000.0),
    FD(signal_params_t, adc_gain_uv, 0.01, 100.0),
    FD(signal_params_t, noise_uv, 0.0, 1000.0),
    FD(signal_params_t, band_low_hz, 1.0, 5000.0),
    FD(signal_params_t, band_high_hz, 100.0, 20000.0),
    FD(signal_params_t, mua_rate_hz, 0.0, 1e5),
    FD(signal_params_t, mua_amp_uv, 0.0, 1000.0),
    FD(signal_params_t, motion_artifact_uv, 0.0, 1e5),
    FD(signal_params_t, motion_artifact_tau_s, 1e-4, 10.0),
    FD(signal_params_t, motion_artifact_hz, 1.0, 20000.0),
    FD(signal_params_t, large_artifact_rate_hz, 0.0, 100.0),
    FD(signal_params_t, large_artifact_uv, 0.0, 1e5),
};

static const field_t NEURON_MODEL_FIELDS[] = {
    FD(neuron_model_params_t, falloff_um, 1.0, 1000.0),  FD(neuron_model_params_t, falloff_exp, 1.0, 4.0),
    FD(neuron_model_params_t, range_um, 10.0, 1000.0),   FD(neuron_model_params_t, damage_um, 0.0, 100.0),
    FD(neuron_model_params_t, shape_mix, 0.0, 1.0),      FD(neuron_model_params_t, window_pre_ms, 0.1, 1.5),
    FD(neuron_model_params_t, window_post_ms, 0.2, 2.5),
};

static const field_t NEURON_FIELDS[] = {
    FD(neuron_params_t, x_um, -1000.0, 1000.0),
    FD(neuron_params_t, y_um, -1000.0, 1000.0),
    {"depth_um", FT_DOUBLE, offsetof(neuron_params_t, depth_um), -1e5, 1e5, true},
    FD(neuron_params_t, amp_uv, 0.0, 5000.0),
    {"shape", FT_SHAPE, offsetof(neuron_params_t, shape), 0.0, 0.0, false},
    FD(neuron_params_t, trough_ms, 0.02, 1.0),
    FD(neuron_params_t, repol_ms, 0.02, 2.0),
    FD(neuron_params_t, repol_ratio, 0.0, 2.0),
    FD(neuron_params_t, rate_hz, 0.01, 200.0),
    FD(neuron_params_t, refractory_ms, 0.5, 20.0),
    FD(neuron_params_t, burst_prob, 0.0, 1.0),
    FU(neuron_params_t, burst_spikes, 1.0, 10.0),
    FD(neuron_params_t, burst_isi_ms, 0.5, 100.0),
    FD(neuron_params_t, burst_amp_decay, 0.05, 1.0),
    FD(neuron_params_t, amp_jitter, 0.0, 0.5),
    FD(neuron_params_t, active_mean_s, 0.0, 1e6),
    FD(neuron_params_t, silent_mean_s, 0.0, 1e6),
    FD(neuron_params_t, appear_s, 0.0, 1e7),
    FD(neuron_params_t, disappear_s, 0.0, 1e7),
    FD(neuron_params_t, drift_um_per_min, -100.0, 100.0),
    FD(neuron_params_t, drift_start_s, 0.0, 1e7),
};

static const field_t RANDOM_FIELDS[] = {
    FU(sim_random_neurons_t, count, 0.0, (double)SIM_MAX_NEURONS),
    FD(sim_random_neurons_t, depth_min_um, -1e5, 1e5),
    FD(sim_random_neurons_t, depth_max_um, -1e5, 1e5),
    FD(sim_random_neurons_t, radius_um, 0.0, 1000.0),
    FD(sim_random_neurons_t, amp_min_uv, 0.0, 5000.0),
    FD(sim_random_neurons_t, amp_max_uv, 0.0, 5000.0),
    FD(sim_random_neurons_t, rate_min_hz, 0.01, 200.0),
    FD(sim_random_neurons_t, rate_max_hz, 0.01, 200.0),
};

static const field_t EXPORT_FIELDS[] = {
    FU(scenario_export_t, intervals, 1.0, 100000.0),
    FD(scenario_export_t, interval_s, 0.01, 3600.0),
    FD(scenario_export_t, step_um, -5600.0, 5600.0),
    FD(scenario_export_t, settle_s, 0.0, 3600.0),
};

static const field_t TOP_SCALARS[] = {
    {"name", FT_STRING, offsetof(scenario_t, name), 0.0, (double)SCENARIO_NAME_MAX - 1.0, false},
    {"seed", FT_U64, offsetof(scenario_t, seed), 0.0, 0.0, false},
    FD(scenario_t, duration_s, 0.0, 1e7),
};

/* ---- error reporting ------------------------------------------------------ */

typedef struct {
    yaml_document_t *doc;
    const char *file;
    char *err;
    size_t errlen, used;
    int count;
} ctx_t;

__attribute__((format(printf, 3, 4))) static void perr(ctx_t *c, size_t line, const char *fmt, ...)
{
    char msg[320];
    va_list ap;
    va_start(ap, fmt);
    (void)vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    c->count++;
    if (c->err == NULL || c->used + 1u >= c->errlen) {
        return;
    }
    /* One line per error: a value quoted in the message may hold line breaks (a
     * plain scalar folded over blank lines, an escape in a quoted one) or other
     * control bytes; they are written as escapes. */
    char line_msg[4u * sizeof msg];
    size_t o = 0u;
    for (const char *p = msg; *p != '\0' && o + 5u < sizeof line_msg; ++p) {
        const unsigned char ch = (unsigned char)*p;
        if (ch >= 0x20u && ch != 0x7fu) {
            line_msg[o++] = (char)ch;
        } else {
            const int w = (ch == '\n')   ? snprintf(&line_msg[o], sizeof line_msg - o, "\\n")
                          : (ch == '\t') ? snprintf(&line_msg[o], sizeof line_msg - o, "\\t")
                          : (ch == '\r') ? snprintf(&line_msg[o], sizeof line_msg - o, "\\r")
                                         : snprintf(&line_msg[o], sizeof line_msg - o, "\\x%02x", (unsigned)ch);
            o += (w > 0) ? (size_t)w : 0u;
        }
    }
    line_msg[o] = '\0';
    const int n = snprintf(c->err + c->used, c->errlen - c->used, "%s:%zu: %s\n", c->file, line, line_msg);
    if (n > 0) {
        c->used += (size_t)n;
    }
    if (c->used >= c->errlen) {
        c->used = c->errlen - 1u; /* truncated; snprintf kept it terminated */
    }
}

static size_t line_of(const yaml_node_t *n)
{
    return n->start_mark.line + 1u;
}

static const char *sval(const yaml_node_t *n)
{
    return (const char *)n->data.scalar.value;
}

static yaml_node_t *node_at(ctx_t *c, int i)
{
    return yaml_document_get_node(c->doc, i);
}

static bool is_quoted(const yaml_node_t *n)
{
    return n->data.scalar.style == YAML_SINGLE_QUOTED_SCALAR_STYLE ||
           n->data.scalar.style == YAML_DOUBLE_QUOTED_SCALAR_STYLE;
}

/* ---- scalars ----------------------------------------------------------------- */

static bool parse_double(const yaml_node_t *v, double *out)
{
    if (is_quoted(v) || v->data.scalar.length == 0u) {
        return false;
    }
    char *end = NULL;
    errno = 0;
    const double d = strtod(sval(v), &end);
    if (end == sval(v) || *end != '\0' || errno != 0 || !isfinite(d)) {
        return false;
    }
    *out = d;
    return true;
}

static bool parse_u64(const yaml_node_t *v, uint64_t *out)
{
    const char *s = sval(v);
    if (is_quoted(v) || v->data.scalar.length == 0u || s[0] < '0' || s[0] > '9') {
        return false;
    }
    char *end = NULL;
    errno = 0;
    const unsigned long long u = strtoull(s, &end, 10);
    if (*end != '\0' || errno != 0) {
        return false;
    }
    *out = (uint64_t)u;
    return true;
}

/* One key/value against its field; reports type and range errors. */
static void set_field(ctx_t *c, const field_t *f, const yaml_node_t *v, void *base, const char *section)
{
    unsigned char *p = (unsigned char *)base + f->off;
    if (v->type != YAML_SCALAR_NODE) {
        perr(c, line_of(v), "'%s' in %s must be a scalar", f->key, section);
        return;
    }
    double d = 0.0;
    uint64_t u = 0u;
    switch (f->type) {
    case FT_DOUBLE:
        if (!parse_double(v, &d)) {
            perr(c, line_of(v), "'%s' must be a number, got '%s'", f->key, sval(v));
        } else if (d < f->lo || d > f->hi) {
            perr(c, line_of(v), "'%s' = %g out of range [%g, %g]", f->key, d, f->lo, f->hi);
        } else {
            memcpy(p, &d, sizeof d);
        }
        break;
    case FT_U32:
    case FT_U64:
        if (!parse_u64(v, &u)) {
            perr(c, line_of(v), "'%s' must be a non-negative integer, got '%s'", f->key, sval(v));
        } else if (f->type == FT_U32 && ((double)u < f->lo || (double)u > f->hi)) {
            perr(c, line_of(v), "'%s' = %llu out of range [%g, %g]", f->key, (unsigned long long)u, f->lo, f->hi);
        } else if (f->type == FT_U32) {
            const uint32_t u32 = (uint32_t)u;
            memcpy(p, &u32, sizeof u32);
        } else {
            memcpy(p, &u, sizeof u);
        }
        break;
    case FT_SHAPE: {
        neuron_shape_t sh = NEURON_BIPHASIC;
        if (strcmp(sval(v), "biphasic") == 0) {
            sh = NEURON_BIPHASIC;
        } else if (strcmp(sval(v), "triphasic") == 0) {
            sh = NEURON_TRIPHASIC;
        } else {
            perr(c, line_of(v), "'%s' must be biphasic or triphasic, got '%s'", f->key, sval(v));
            break;
        }
        memcpy(p, &sh, sizeof sh);
        break;
    }
    case FT_STRING:
        if ((double)v->data.scalar.length > f->hi) {
            perr(c, line_of(v), "'%s' longer than %g characters", f->key, f->hi);
        } else {
            memcpy(p, v->data.scalar.value, v->data.scalar.length);
            p[v->data.scalar.length] = '\0';
        }
        break;
    default: break;
    }
}

static const field_t *find_field(const field_t *fs, size_t n, const char *key)
{
    for (size_t i = 0u; i < n; ++i) {
        if (strcmp(fs[i].key, key) == 0) {
            return &fs[i];
        }
    }
    return NULL;
}

/* A mapping whose keys are all fields of the table. */
static void parse_section(ctx_t *c, const yaml_node_t *m, const field_t *fs, size_t n, void *base, const char *section,
                          bool check_required)
{
    if (m->type != YAML_MAPPING_NODE) {
        perr(c, line_of(m), "%s must be a mapping", section);
        return;
    }
    bool seen[32] = {false};
    for (yaml_node_pair_t *pr = m->data.mapping.pairs.start; pr < m->data.mapping.pairs.top; ++pr) {
        const yaml_node_t *k = node_at(c, pr->key), *v = node_at(c, pr->value);
        if (k->type != YAML_SCALAR_NODE) {
            perr(c, line_of(k), "keys in %s must be scalars", section);
            continue;
        }
        const field_t *f = find_field(fs, n, sval(k));
        if (f == NULL) {
            perr(c, line_of(k), "unknown key '%s' in %s", sval(k), section);
            continue;
        }
        const size_t idx = (size_t)(f - fs);
        if (idx < 32u && seen[idx]) {
            perr(c, line_of(k), "duplicate key '%s' in %s", sval(k), section);
            continue;
        }
        if (idx < 32u) {
            seen[idx] = true;
        }
        set_field(c, f, v, base, section);
    }
    for (size_t i = 0u; check_required && i < n && i < 32u; ++i) {
        if (fs[i].required && !seen[i]) {
            perr(c, line_of(m), "missing required field '%s' in %s", fs[i].key, section);
        }
    }
}

/* ---- faults ----------------------------------------------------------------- */

typedef enum {
    FK_BUS_LOSS,
    FK_BUS_CORRUPT,
    FK_BUS_DUP,
    FK_BUS_DELAY,
    FK_BUS_REORDER,
    FK_NODE_SILENT,
    FK_HALL_GLITCH,
    FK_HALL_STUCK,
    FK_ACT_STALL,
    FK_ACT_SLIP,
    FK_ADC_SATURATION,
    FK_ARTIFACT_STORM,
    FK_CTRL_RESTART,
    FK_COUNT
} fault_kind_t;

static const char *const FAULT_KIND_NAMES[FK_COUNT] = {
    "bus_loss",       "bus_corrupt",    "bus_dup",           "bus_delay",      "bus_reorder",
    "node_silent",    "hall_glitch",    "hall_stuck",        "actuator_stall", "actuator_slip",
    "adc_saturation", "artifact_storm", "controller_restart"};

#define FAULT_FOREVER_S 1e300

typedef struct {
    double from_s, to_s, at_s, prob, codes, slip_um, rate_hz, amp_uv;
    uint32_t electrode, frames, can_id;
} fault_entry_t;

/* Bits of FAULT_FIELDS, to check which keys a kind accepts. */
enum {
    FB_FROM = 1u << 0,
    FB_TO = 1u << 1,
    FB_AT = 1u << 2,
    FB_PROB = 1u << 3,
    FB_CODES = 1u << 4,
    FB_SLIP = 1u << 5,
    FB_RATE = 1u << 6,
    FB_AMP = 1u << 7,
    FB_ELECTRODE = 1u << 8,
    FB_FRAMES = 1u << 9,
    FB_CANID = 1u << 10,
    FB_NODE = 1u << 11,
    FB_DIR = 1u << 12
};

static const field_t FAULT_FIELDS[] = {
    FD(fault_entry_t, from_s, 0.0, 1e7),
    FD(fault_entry_t, to_s, 0.0, 1e7),
    FD(fault_entry_t, at_s, 0.0, 1e7),
    FD(fault_entry_t, prob, 0.0, 1.0),
    FD(fault_entry_t, codes, 1.0, 16777216.0),
    FD(fault_entry_t, slip_um, 0.001, 1000.0),
    FD(fault_entry_t, rate_hz, 0.01, 1000.0),
    FD(fault_entry_t, amp_uv, 1.0, 1e5),
    FU(fault_entry_t, electrode, 0.0, (double)SIM_MAX_ELECTRODES - 1.0),
    FU(fault_entry_t, frames, 1.0, 32.0),
    FU(fault_entry_t, can_id, 0.0, 2047.0),
};

/* Keys each kind accepts (kind itself always), and the ones it requires. */
static uint32_t fault_allowed(fault_kind_t k)
{
    const uint32_t win = FB_FROM | FB_TO;
    switch (k) {
    case FK_BUS_LOSS:
    case FK_BUS_CORRUPT:
    case FK_BUS_DUP:
    case FK_BUS_REORDER: return win | FB_PROB | FB_DIR | FB_CANID;
    case FK_BUS_DELAY: return win | FB_PROB | FB_DIR | FB_CANID | FB_FRAMES;
    case FK_NODE_SILENT: return win | FB_NODE;
    case FK_HALL_GLITCH: return win | FB_ELECTRODE | FB_PROB | FB_CODES;
    case FK_ACT_SLIP: return win | FB_ELECTRODE | FB_PROB | FB_SLIP;
    case FK_ARTIFACT_STORM: return win | FB_ELECTRODE | FB_RATE | FB_AMP;
    case FK_HALL_STUCK:
    case FK_ACT_STALL:
    case FK_ADC_SATURATION: return win | FB_ELECTRODE;
    case FK_CTRL_RESTART: return FB_AT;
    case FK_COUNT:
    default: return 0u;
    }
}

static uint32_t fault_required(fault_kind_t k)
{
    if (k <= FK_BUS_REORDER) {
        return FB_PROB;
    }
    return (k == FK_NODE_SILENT) ? FB_NODE : (k == FK_CTRL_RESTART) ? FB_AT : 0u;
}

static const char *const FAULT_KEY_NAMES[] = {"from_s", "to_s",      "at_s",   "prob",   "codes", "slip_um",  "rate_hz",
                                              "amp_uv", "electrode", "frames", "can_id", "node",  "direction"};

typedef struct {
    fault_kind_t kind;
    uint32_t seen, node, dirs;
    fault_entry_t e;
    size_t line;
} fault_item_t;

/* String-valued keys of a fault; returns false if the key is not one. */
static bool fault_string_key(ctx_t *c, const char *key, const yaml_node_t *v, fault_item_t *it)
{
    static const char *const nodes[] = {"act", "hall", "fe"};
    static const char *const dirs[] = {"tx", "rx", "both"};
    const bool is_node = strcmp(key, "node") == 0, is_dir = strcmp(key, "direction") == 0;
    if (!is_node && !is_dir) {
        return false;
    }
    const char *sv = (v->type == YAML_SCALAR_NODE) ? sval(v) : "";
    for (uint32_t i = 0u; i < 3u; ++i) {
        if (strcmp(sv, is_node ? nodes[i] : dirs[i]) == 0) {
            if (is_node) {
                it->node = i + 2u; /* md_node_id_t: 2 act, 3 hall, 4 fe */
            } else {
                it->dirs = i + 1u;
            }
            it->seen |= is_node ? FB_NODE : FB_DIR;
            return true;
        }
    }
    perr(c, line_of(v), "'%s' must be %s, got '%s'", key, is_node ? "act, hall or fe" : "tx, rx or both", sv);
    return true;
}

/* Reads one `faults` entry's keys into *it; false if the entry is unusable. */
static bool fault_read(ctx_t *c, const yaml_node_t *m, fault_item_t *it)
{
    memset(it, 0, sizeof *it);
    it->kind = FK_COUNT;
    it->dirs = 3u;
    it->line = line_of(m);
    it->e = (fault_entry_t){0.0, FAULT_FOREVER_S, 0.0, 0.0, 2000.0, 2.0, 20.0, 3000.0, UINT32_MAX, 4u, 0u};
    if (m->type != YAML_MAPPING_NODE) {
        perr(c, line_of(m), "a fault must be a mapping");
        return false;
    }
    const int before = c->count;
    for (yaml_node_pair_t *pr = m->data.mapping.pairs.start; pr < m->data.mapping.pairs.top; ++pr) {
        const yaml_node_t *k = node_at(c, pr->key), *v = node_at(c, pr->value);
        const char *key = (k->type == YAML_SCALAR_NODE) ? sval(k) : "";
        if (strcmp(key, "kind") == 0) {
            for (uint32_t i = 0u; i < (uint32_t)FK_COUNT && v->type == YAML_SCALAR_NODE; ++i) {
                it->kind = (strcmp(sval(v), FAULT_KIND_NAMES[i]) == 0) ? (fault_kind_t)i : it->kind;
            }
            if (it->kind == FK_COUNT) {
                perr(c, line_of(v), "unknown fault kind '%s'", v->type == YAML_SCALAR_NODE ? sval(v) : "");
            }
        } else if (!fault_string_key(c, key, v, it)) {
            const field_t *f = find_field(FAULT_FIELDS, NFIELDS(FAULT_FIELDS), key);
            if (f == NULL) {
                perr(c, line_of(k), "unknown key '%s' in fault", key);
                continue;
            }
            it->seen |= 1u << (uint32_t)(f - FAULT_FIELDS);
            set_field(c, f, v, &it->e, "fault");
        }
    }
    if (it->kind == FK_COUNT) {
        if (c->count == before) {
            perr(c, it->line, "missing required field 'kind' in fault");
        }
        return false;
    }
    const uint32_t bad = it->seen & ~fault_allowed(it->kind), missing = fault_required(it->kind) & ~it->seen;
    for (uint32_t b = 0u; b < NFIELDS(FAULT_KEY_NAMES); ++b) {
        if ((bad >> b) & 1u) {
            perr(c, it->line, "'%s' does not apply to fault kind %s", FAULT_KEY_NAMES[b], FAULT_KIND_NAMES[it->kind]);
        }
        if ((missing >> b) & 1u) {
            perr(c, it->line, "fault kind %s needs '%s'", FAULT_KIND_NAMES[it->kind], FAULT_KEY_NAMES[b]);
        }
    }
    if (it->kind != FK_CTRL_RESTART && !(it->e.to_s > it->e.from_s)) {
        perr(c, it->line, "fault window needs from_s < to_s (got %g, %g)", it->e.from_s, it->e.to_s);
    }
    return c->count == before;
}

/* Sets one model-fault window of electrode cfg; a second one is an error. */
static void fault_model_set(ctx_t *c, const fault_item_t *it, sim_model_faults_t *mf)
{
    sim_window_t *w = NULL;
    switch (it->kind) {
    case FK_HALL_GLITCH:
        w = &mf->hall_glitch;
        mf->hall_glitch_codes = it->e.codes;
        if (it->seen & FB_PROB) {
            mf->hall_glitch_prob = it->e.prob;
        }
        break;
    case FK_HALL_STUCK: w = &mf->hall_stuck; break;
    case FK_ACT_STALL: w = &mf->act_stall; break;
    case FK_ACT_SLIP:
        w = &mf->act_slip;
        mf->act_slip_um = it->e.slip_um;
        if (it->seen & FB_PROB) {
            mf->act_slip_prob = it->e.prob;
        }
        break;
    case FK_ADC_SATURATION: w = &mf->adc_saturation; break;
    case FK_ARTIFACT_STORM:
        w = &mf->artifact_storm;
        mf->storm_rate_hz = it->e.rate_hz;
        mf->storm_amp_uv = it->e.amp_uv;
        break;
    case FK_BUS_LOSS:
    case FK_BUS_CORRUPT:
    case FK_BUS_DUP:
    case FK_BUS_DELAY:
    case FK_BUS_REORDER:
    case FK_NODE_SILENT:
    case FK_CTRL_RESTART:
    case FK_COUNT:
    default: return;
    }
    if (w->to_s > w->from_s) {
        perr(c, it->line, "a second %s fault on one electrode", FAULT_KIND_NAMES[it->kind]);
        return;
    }
    w->from_s = it->e.from_s;
    w->to_s = it->e.to_s;
}

static void fault_store(ctx_t *c, const fault_item_t *it, scenario_t *sc)
{
    scenario_faults_t *f = &sc->faults;
    if (it->kind <= FK_BUS_REORDER) {
        if (f->n_bus >= SCENARIO_BUS_FAULTS_MAX) {
            perr(c, it->line, "more than %u bus faults", (unsigned)SCENARIO_BUS_FAULTS_MAX);
            return;
        }
        f->bus[f->n_bus++] = (scenario_bus_fault_t){
            (uint32_t)it->kind, it->e.prob,   it->e.from_s, it->e.to_s,
            it->dirs,           it->e.frames, it->e.can_id, (it->seen & FB_CANID) ? 1u : 0u};
    } else if (it->kind == FK_NODE_SILENT) {
        if (f->n_silent >= SCENARIO_SILENT_MAX) {
            perr(c, it->line, "more than %u node_silent faults", (unsigned)SCENARIO_SILENT_MAX);
            return;
        }
        f->silent[f->n_silent++] = (scenario_silence_t){it->node, it->e.from_s, it->e.to_s};
    } else if (it->kind == FK_CTRL_RESTART) {
        if (f->n_restarts >= SCENARIO_RESTARTS_MAX ||
            (f->n_restarts > 0u && !(it->e.at_s > f->restart_at_s[f->n_restarts - 1u]))) {
            perr(c, it->line, "controller restarts: at most %u, in ascending at_s", (unsigned)SCENARIO_RESTARTS_MAX);
            return;
        }
        f->restart_at_s[f->n_restarts++] = it->e.at_s;
    } else if (it->e.electrode != UINT32_MAX && it->e.electrode >= sc->n_electrodes) {
        perr(c, it->line, "fault electrode %u but the scenario has %u", (unsigned)it->e.electrode,
             (unsigned)sc->n_electrodes);
    } else {
        for (uint32_t e = 0u; e < sc->n_electrodes; ++e) {
            if (it->e.electrode == UINT32_MAX || it->e.electrode == e) {
                fault_model_set(c, it, &sc->electrodes[e].faults);
            }
        }
    }
}

static void parse_faults(ctx_t *c, const yaml_node_t *seq, scenario_t *sc)
{
    if (seq->type != YAML_SEQUENCE_NODE) {
        perr(c, line_of(seq), "faults must be a sequence");
        return;
    }
    for (yaml_node_item_t *i = seq->data.sequence.items.start; i < seq->data.sequence.items.top; ++i) {
        fault_item_t it;
        if (fault_read(c, node_at(c, *i), &it)) {
            fault_store(c, &it, sc);
        }
    }
}

/* ---- structure ------------------------------------------------------------ */

/* Where each model section was last given (for consistency messages). */
typedef struct {
    size_t actuator, sensor, tissue, signal, neuron_model;
} lines_t;

typedef struct {
    sim_electrode_config_t base;
    neuron_params_t neuron;
    lines_t lines;
} defaults_t;

static void check_hall(ctx_t *c, const sim_electrode_config_t *e, size_t line)
{
    const hall_params_t *h = &e->hall;
    const double full = ldexp(1.0, (int)h->adc_bits) - 1.0;
    const double c0 = hall_ideal_code(h, 0.0), c1 = hall_ideal_code(h, e->actuator.travel_um);
    if (c0 < 0.0 || c1 > full) {
        perr(c, line, "sensor characteristic leaves the %u-bit ADC range over the travel (codes %.0f..%.0f)",
             (unsigned)h->adc_bits, c0, c1);
    }
}

static void check_electrode(ctx_t *c, const sim_electrode_config_t *e, const lines_t *ln, size_t line)
{
    if (actuator_params_check(&e->actuator) != MD_OK) {
        perr(c, ln->actuator, "actuator: miss_prob + slip_prob must be <= 1");
    }
    check_hall(c, e, ln->sensor);
    if (e->start_um > e->actuator.travel_um) {
        perr(c, line, "start_um = %g beyond the actuator travel %g", e->start_um, e->actuator.travel_um);
    }
    const sim_random_neurons_t *r = &e->random_neurons;
    if (r->depth_min_um > r->depth_max_um || r->amp_min_uv > r->amp_max_uv || r->rate_min_hz > r->rate_max_hz) {
        perr(c, line, "random_neurons: every *_min must be <= its *_max");
    }
    if (r->count + e->n_neurons > SIM_MAX_NEURONS) {
        perr(c, line, "%u explicit + %u random neurons exceed the %u per electrode", (unsigned)e->n_neurons,
             (unsigned)r->count, (unsigned)SIM_MAX_NEURONS);
    }
}

static void parse_neurons(ctx_t *c, const yaml_node_t *seq, const defaults_t *d, sim_electrode_config_t *e)
{
    if (seq->type != YAML_SEQUENCE_NODE) {
        perr(c, line_of(seq), "neurons must be a sequence");
        return;
    }
    for (yaml_node_item_t *it = seq->data.sequence.items.start; it < seq->data.sequence.items.top; ++it) {
        const yaml_node_t *item = node_at(c, *it);
        if (e->n_neurons >= SIM_MAX_NEURONS) {
            perr(c, line_of(item), "more than %u neurons on one electrode", (unsigned)SIM_MAX_NEURONS);
            return;
        }
        neuron_params_t np = d->neuron;
        const int before = c->count;
        parse_section(c, item, NEURON_FIELDS, NFIELDS(NEURON_FIELDS), &np, "neuron", true);
        const char *why = NULL;
        if (c->count == before && neuron_params_check(&np, &why) != MD_OK) {
            perr(c, line_of(item), "neuron: %s", why != NULL ? why : "inconsistent parameters");
        }
        e->neurons[e->n_neurons++] = np;
    }
}

static void parse_electrode(ctx_t *c, const yaml_node_t *m, const defaults_t *d, sim_electrode_config_t *e)
{
    *e = d->base;
    lines_t ln = d->lines;
    if (m->type != YAML_MAPPING_NODE) {
        perr(c, line_of(m), "an electrode must be a mapping");
        return;
    }
    for (yaml_node_pair_t *pr = m->data.mapping.pairs.start; pr < m->data.mapping.pairs.top; ++pr) {
        const yaml_node_t *k = node_at(c, pr->key), *v = node_at(c, pr->value);
        const char *key = (k->type == YAML_SCALAR_NODE) ? sval(k) : "";
        if (strcmp(key, "start_um") == 0) {
            static const field_t f = {"start_um", FT_DOUBLE, offsetof(sim_electrode_config_t, start_um),
                                      0.0,        1e5,       false};
            set_field(c, &f, v, e, "electrode");
        } else if (strcmp(key, "actuator") == 0) {
            parse_section(c, v, ACTUATOR_FIELDS, NFIELDS(ACTUATOR_FIELDS), &e->actuator, "actuator", false);
            ln.actuator = line_of(v);
        } else if (strcmp(key, "sensor") == 0) {
            parse_section(c, v, SENSOR_FIELDS, NFIELDS(SENSOR_FIELDS), &e->hall, "sensor", false);
            ln.sensor = line_of(v);
        } else if (strcmp(key, "tissue") == 0) {
            parse_section(c, v, TISSUE_FIELDS, NFIELDS(TISSUE_FIELDS), &e->tissue, "tissue", false);
        } else if (strcmp(key, "neurons") == 0) {
            parse_neurons(c, v, d, e);
        } else if (strcmp(key, "random_neurons") == 0) {
            parse_section(c, v, RANDOM_FIELDS, NFIELDS(RANDOM_FIELDS), &e->random_neurons, "random_neurons", false);
        } else {
            perr(c, line_of(k), "unknown key '%s' in electrode", key);
        }
    }
    check_electrode(c, e, &ln, line_of(m));
}

static void parse_electrodes(ctx_t *c, const yaml_node_t *seq, const defaults_t *d, scenario_t *sc)
{
    if (seq->type != YAML_SEQUENCE_NODE) {
        perr(c, line_of(seq), "electrodes must be a sequence");
        return;
    }
    const ptrdiff_t n = seq->data.sequence.items.top - seq->data.sequence.items.start;
    if (n < 1 || n > (ptrdiff_t)SIM_MAX_ELECTRODES) {
        perr(c, line_of(seq), "electrodes must have 1..%u entries, got %td", (unsigned)SIM_MAX_ELECTRODES, n);
        return;
    }
    sc->n_electrodes = 0u;
    for (yaml_node_item_t *it = seq->data.sequence.items.start; it < seq->data.sequence.items.top; ++it) {
        parse_electrode(c, node_at(c, *it), d, &sc->electrodes[sc->n_electrodes++]);
    }
}

/* Top-level keys other than `electrodes`; returns whether it was known. */
static bool parse_top_key(ctx_t *c, const char *key, const yaml_node_t *v, defaults_t *d, scenario_t *sc)
{
    sim_electrode_config_t *b = &d->base;
    if (strcmp(key, "signal") == 0) {
        parse_section(c, v, SIGNAL_FIELDS, NFIELDS(SIGNAL_FIELDS), &b->signal, "signal", false);
        d->lines.signal = line_of(v);
    } else if (strcmp(key, "actuator") == 0) {
        parse_section(c, v, ACTUATOR_FIELDS, NFIELDS(ACTUATOR_FIELDS), &b->actuator, "actuator", false);
        d->lines.actuator = line_of(v);
    } else if (strcmp(key, "sensor") == 0) {
        parse_section(c, v, SENSOR_FIELDS, NFIELDS(SENSOR_FIELDS), &b->hall, "sensor", false);
        d->lines.sensor = line_of(v);
    } else if (strcmp(key, "tissue") == 0) {
        parse_section(c, v, TISSUE_FIELDS, NFIELDS(TISSUE_FIELDS), &b->tissue, "tissue", false);
    } else if (strcmp(key, "neuron_model") == 0) {
        parse_section(c, v, NEURON_MODEL_FIELDS, NFIELDS(NEURON_MODEL_FIELDS), &b->neuron_model, "neuron_model", false);
        d->lines.neuron_model = line_of(v);
    } else if (strcmp(key, "neuron_defaults") == 0) {
        parse_section(c, v, NEURON_FIELDS, NFIELDS(NEURON_FIELDS), &d->neuron, "neuron_defaults", false);
    } else if (strcmp(key, "export") == 0) {
        parse_section(c, v, EXPORT_FIELDS, NFIELDS(EXPORT_FIELDS), &sc->export_cfg, "export", false);
    } else {
        const field_t *f = find_field(TOP_SCALARS, NFIELDS(TOP_SCALARS), key);
        if (f == NULL) {
            return false;
        }
        set_field(c, f, v, sc, "scenario");
    }
    return true;
}

static void check_signal(ctx_t *c, const defaults_t *d)
{
    const signal_params_t *s = &d->base.signal;
    if (!(s->band_high_hz < 0.45 * s->sample_rate_hz) || !(s->band_low_hz < s->band_high_hz)) {
        perr(c, d->lines.signal, "signal: need band_low_hz < band_high_hz < 0.45 * sample_rate_hz");
    }
    if (neuron_model_params_check(&d->base.neuron_model, s->sample_rate_hz) != MD_OK) {
        perr(c, d->lines.neuron_model, "neuron_model: spike window longer than %u samples at %g Hz",
             (unsigned)SIM_WAVE_MAX, s->sample_rate_hz);
    }
}

static void parse_root(ctx_t *c, const yaml_node_t *root, scenario_t *sc)
{
    if (root->type != YAML_MAPPING_NODE) {
        perr(c, line_of(root), "a scenario must be a mapping");
        return;
    }
    static defaults_t d;
    d.base = sc->electrodes[0];
    neuron_default_params(&d.neuron);
    d.lines = (lines_t){line_of(root), line_of(root), line_of(root), line_of(root), line_of(root)};
    const yaml_node_t *electrodes = NULL, *faults = NULL;
    const char *seen[32];
    size_t n_seen = 0u;
    for (yaml_node_pair_t *pr = root->data.mapping.pairs.start; pr < root->data.mapping.pairs.top; ++pr) {
        const yaml_node_t *k = node_at(c, pr->key), *v = node_at(c, pr->value);
        if (k->type != YAML_SCALAR_NODE) {
            perr(c, line_of(k), "keys must be scalars");
            continue;
        }
        bool dup = false;
        for (size_t i = 0u; i < n_seen; ++i) {
            dup = dup || strcmp(seen[i], sval(k)) == 0;
        }
        if (dup) {
            perr(c, line_of(k), "duplicate key '%s'", sval(k));
            continue;
        }
        if (n_seen < 32u) {
            seen[n_seen++] = sval(k);
        }
        if (strcmp(sval(k), "electrodes") == 0) {
            electrodes = v;
        } else if (strcmp(sval(k), "faults") == 0) {
            faults = v; /* after the electrodes: model faults go into them */
        } else if (!parse_top_key(c, sval(k), v, &d, sc)) {
            perr(c, line_of(k), "unknown key '%s'", sval(k));
        }
    }
    check_signal(c, &d);
    if (electrodes == NULL) {
        perr(c, line_of(root), "missing required field 'electrodes'");
        return;
    }
    parse_electrodes(c, electrodes, &d, sc);
    if (faults != NULL) {
        parse_faults(c, faults, sc);
    }
}

void scenario_default(scenario_t *sc)
{
    memset(sc, 0, sizeof *sc);
    (void)snprintf(sc->name, sizeof sc->name, "%s", "default");
    sc->seed = 1u;
    sc->duration_s = 600.0;
    sc->n_electrodes = 1u;
    for (uint32_t e = 0u; e < SIM_MAX_ELECTRODES; ++e) {
        sim_electrode_default_config(&sc->electrodes[e]);
    }
    sc->export_cfg.intervals = 20u;
    sc->export_cfg.interval_s = 10.0;
    sc->export_cfg.step_um = 10.0;
    sc->export_cfg.settle_s = 1.0;
}

int scenario_parse(scenario_t *sc, const char *text, size_t len, const char *file, char *err, size_t errlen)
{
    ctx_t c = {NULL, file != NULL ? file : "<string>", err, errlen, 0u, 0};
    if (err != NULL && errlen > 0u) {
        err[0] = '\0';
    }
    scenario_default(sc);
    yaml_parser_t parser;
    yaml_document_t doc;
    if (!yaml_parser_initialize(&parser)) {
        perr(&c, 1u, "cannot initialise the YAML parser");
        return c.count;
    }
    yaml_parser_set_input_string(&parser, (const unsigned char *)text, len);
    if (!yaml_parser_load(&parser, &doc)) {
        perr(&c, parser.problem_mark.line + 1u, "YAML syntax error: %s",
             parser.problem != NULL ? parser.problem : "unknown");
        yaml_parser_delete(&parser);
        return c.count;
    }
    c.doc = &doc;
    const yaml_node_t *root = yaml_document_get_root_node(&doc);
    if (root == NULL) {
        perr(&c, 1u, "empty scenario");
    } else {
        parse_root(&c, root, sc);
    }
    yaml_document_delete(&doc);
    yaml_parser_delete(&parser);
    return c.count;
}

int scenario_load(scenario_t *sc, const char *path, char *err, size_t errlen)
{
    FILE *f = fopen(path, "rb");
    if (f == NULL) {
        if (err != NULL && errlen > 0u) {
            (void)snprintf(err, errlen, "%s:0: cannot open: %s\n", path, strerror(errno));
        }
        return -1;
    }
    char *buf = NULL;
    size_t len = 0u, cap = 0u;
    for (;;) { /* bounded by the file's size */
        if (len + 4096u > cap) {
            cap = (cap == 0u) ? 65536u : cap * 2u;
            char *nb = realloc(buf, cap);
            if (nb == NULL) {
                free(buf);
                (void)fclose(f);
                return -1;
            }
            buf = nb;
        }
        const size_t got = fread(buf + len, 1u, cap - len, f);
        len += got;
        if (got == 0u) {
            break;
        }
    }
    (void)fclose(f);
    const int n = scenario_parse(sc, buf, len, path, err, errlen);
    free(buf);
    return n;
}

md_status_t scenario_make_world(const scenario_t *sc, uint64_t seed, sim_world_t *w)
{
    return sim_world_init(w, sc->electrodes, sc->n_electrodes, seed);
}

bool scenario_node_silent(const scenario_t *sc, uint32_t node, double t_s)
{
    return scenario_faults_node_silent(&sc->faults, node, t_s);
}

uint32_t scenario_restarts_due(const scenario_t *sc, double t_prev_s, double t_now_s)
{
    return scenario_faults_restarts_due(&sc->faults, t_prev_s, t_now_s);
}

bool scenario_has_faults(const scenario_t *sc)
{
    bool any = sc->faults.n_bus + sc->faults.n_silent + sc->faults.n_restarts > 0u;
    for (uint32_t e = 0u; e < sc->n_electrodes && e < SIM_MAX_ELECTRODES; ++e) {
        any = any || sim_model_faults_any(&sc->electrodes[e].faults);
    }
    return any;
}
