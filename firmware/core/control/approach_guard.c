/// @file approach_guard.c
/// Approach guard. See approach_guard.h; defaults and measurements in
/// docs/sfsm.md ("Approach guard").
#include "control/approach_guard.h"

#include <math.h>
#include <string.h>

void ag_config_default(ag_config_t *cfg)
{
    if (cfg == NULL) {
        return;
    }
    cfg->growth_stop = 0.022;
    cfg->growth_slow = 0.011;
    cfg->baseline_min_um = 15.0;
    cfg->baseline_new_um = 8.0;
    cfg->amp_floor = 12.0;
    cfg->amp_slow = 15.0;
    cfg->amp_stop = 80.0;
    cfg->move_near_um = 10.0;
    cfg->climb_frac = 0.06;
    cfg->climb_free_frac = 0.15;
    cfg->retract_um = 10.0;
    cfg->still_um = 3.0;
    cfg->growth_max = 1.0 / 30.0;
    cfg->fence_drop_frac = 0.15;
    cfg->relax_frac = 0.24;
    cfg->relax_tau_s = 120.0;
    cfg->creep_horizon_s = 30.0;
    cfg->fence_lapse = 30u;
    cfg->probe_um = 5.0;
    cfg->pace_um = 0.0;
    cfg->settle_um = 2.0;
    cfg->follow = false;
    cfg->near_scale = false;
    cfg->top_k = 5u;
}

static bool positive(double v)
{
    return isfinite(v) && v > 0.0;
}

static bool fraction(double v)
{
    return v > 0.0 && v < 1.0;
}

md_status_t ag_config_check(const ag_config_t *cfg)
{
    if (cfg == NULL || !positive(cfg->growth_stop) || !positive(cfg->baseline_min_um) ||
        !positive(cfg->baseline_new_um) || cfg->baseline_new_um > cfg->baseline_min_um || !positive(cfg->amp_floor) ||
        !positive(cfg->amp_slow) || !positive(cfg->amp_stop) || !positive(cfg->move_near_um) ||
        !positive(cfg->climb_frac) || !(cfg->climb_free_frac >= cfg->climb_frac) || !positive(cfg->retract_um) ||
        !positive(cfg->still_um) || cfg->amp_floor > cfg->amp_slow || !(cfg->amp_slow < cfg->amp_stop) ||
        cfg->top_k < 1u || cfg->top_k > AG_TOP_K_MAX) {
        return MD_E_ARG;
    }
    if (!positive(cfg->growth_max) || cfg->growth_stop > cfg->growth_max || !positive(cfg->growth_slow) ||
        cfg->growth_slow > cfg->growth_stop || !fraction(cfg->fence_drop_frac) || !fraction(cfg->relax_frac) ||
        !positive(cfg->relax_tau_s) || !positive(cfg->creep_horizon_s) || cfg->fence_lapse < 1u ||
        !positive(cfg->probe_um) || !(isfinite(cfg->pace_um) && cfg->pace_um >= 0.0) ||
        !(isfinite(cfg->settle_um) && cfg->settle_um >= 0.0)) {
        return MD_E_ARG;
    }
    return MD_OK;
}

md_status_t ag_init(ag_state_t *s, const ag_config_t *cfg)
{
    if (s == NULL || ag_config_check(cfg) != MD_OK) {
        return MD_E_ARG;
    }
    memset(s, 0, sizeof *s);
    s->cfg = *cfg;
    s->fence_um = HUGE_VAL;
    return MD_OK;
}

/* Peak-to-peak of one window, in counts. */
static int32_t window_ptp(const int16_t *w, size_t d_w)
{
    int32_t lo = w[0];
    int32_t hi = w[0];
    for (size_t i = 1u; i < d_w; ++i) {
        lo = (w[i] < lo) ? w[i] : lo;
        hi = (w[i] > hi) ? w[i] : hi;
    }
    return hi - lo;
}

/* Inserts v into top[0..k) kept in descending order (k-th largest last). */
static void keep_top(int32_t *top, size_t k, size_t *filled, int32_t v)
{
    size_t pos = (*filled < k) ? *filled : k;
    if (pos == k && v <= top[k - 1u]) {
        return;
    }
    if (pos == k) {
        pos = k - 1u; /* the smallest falls out */
    } else {
        (*filled)++;
    }
    while (pos > 0u && top[pos - 1u] < v) {
        top[pos] = top[pos - 1u];
        --pos;
    }
    top[pos] = v;
}

md_status_t ag_robust_amplitude_i16(const int16_t *wave, size_t n, size_t stride, size_t d_w, double gain,
                                    double noise_rms_uv, uint8_t k, double *amp)
{
    if (amp == NULL || (wave == NULL && n > 0u) || d_w < 2u || d_w > stride || k < 1u || k > AG_TOP_K_MAX ||
        !positive(gain) || !positive(noise_rms_uv)) {
        return MD_E_ARG;
    }
    *amp = 0.0;
    if (n < (size_t)k) {
        return MD_OK;
    }
    int32_t top[AG_TOP_K_MAX] = {0};
    size_t filled = 0u;
    for (size_t j = 0u; j < n; ++j) {
        keep_top(top, k, &filled, window_ptp(&wave[j * stride], d_w));
    }
    *amp = (double)top[k - 1u] * gain / noise_rms_uv;
    return MD_OK;
}

/* Amplitude of unit `id` in a snapshot; 0 if it is not there. */
static double unit_amp(const ag_snapshot_t *snap, uint32_t id)
{
    for (uint8_t u = 0u; u < snap->n; ++u) {
        if (snap->unit[u].id == id) {
            return snap->unit[u].amp;
        }
    }
    return 0.0;
}

static double largest_amp(const ag_snapshot_t *snap)
{
    double a = 0.0;
    for (uint8_t u = 0u; u < snap->n; ++u) {
        a = fmax(a, snap->unit[u].amp);
    }
    return a;
}

static const ag_snapshot_t *history_back(const ag_state_t *s, uint8_t i)
{
    return &s->hist[(s->hist_head + AG_HISTORY - 1u - i) % AG_HISTORY];
}

/* Rule 1 for one unit: growth per µm of advance against the newest interval
 * recorded at least baseline_min_um shallower that saw it; for a unit first
 * seen less than that far back (a new track), against the newest at least
 * baseline_new_um shallower. */
static bool unit_growth(const ag_state_t *s, const ag_snapshot_t *now, const ag_unit_t *u, double *g, bool *short_base)
{
    *short_base = false;
    double new_travel = 0.0;
    double new_before = 0.0;
    for (uint8_t i = 0u; i < s->hist_n; ++i) {
        const ag_snapshot_t *then = history_back(s, i);
        const double travel = now->depth_um - then->depth_um;
        const double before = unit_amp(then, u->id);
        if (before > 0.0 && travel >= s->cfg.baseline_min_um) {
            *g = log(u->amp / before) / travel;
            return true;
        }
        if (before > 0.0 && travel >= s->cfg.baseline_new_um && !(new_before > 0.0)) {
            new_travel = travel;
            new_before = before;
        }
    }
    if (new_before > 0.0) {
        *short_base = true;
        *g = log(u->amp / new_before) / new_travel;
        return true;
    }
    return false;
}

static void push_history(ag_state_t *s, const ag_snapshot_t *now)
{
    s->hist[s->hist_head] = *now;
    s->hist_head = (uint8_t)((s->hist_head + 1u) % AG_HISTORY);
    s->hist_n = (s->hist_n < AG_HISTORY) ? (uint8_t)(s->hist_n + 1u) : s->hist_n;
}

static ag_ceiling_t *find_ceiling(ag_state_t *s, uint32_t id)
{
    for (uint8_t i = 0u; i < s->n_ceil; ++i) {
        if (s->ceil[i].id == id) {
            return &s->ceil[i];
        }
    }
    return NULL;
}

/* A lower ceiling replaces a higher one; the growth kept is the larger. */
static void set_ceiling(ag_state_t *s, uint32_t id, double amp, double growth, double depth_um)
{
    ag_ceiling_t *c = find_ceiling(s, id);
    if (c == NULL && s->n_ceil < AG_UNITS_MAX) {
        c = &s->ceil[s->n_ceil++];
        *c = (ag_ceiling_t){id, amp, growth, depth_um, s->pending_um, 0u};
        s->ceilings_set++;
        return;
    }
    if (c != NULL) {
        c->amp = fmin(c->amp, amp);
        c->growth = fmax(c->growth, growth);
    }
}

/* A unit's growth on the latest advance; false if it was not measured. */
static bool advance_growth(const ag_state_t *s, uint32_t id, double *g)
{
    for (uint8_t u = 0u; u < s->n_grown; ++u) {
        if (s->grown[u].id == id) {
            *g = s->grown[u].growth;
            return true;
        }
    }
    return false;
}

/* Rule 1: units steep on this advance and the one before get a ceiling; a
 * loud one (amp_slow) on the first: one more advance of its growth could
 * take it inside the damage radius. A new unit, measured over a short
 * baseline, is steep from growth_max on: that short a reading is noisier,
 * and a neuron beside the track reads up to growth_stop there when its track
 * is born. Growth over the long baseline is kept for rule 5. */
static void mark_steep(ag_state_t *s, const ag_snapshot_t *now, ag_output_t *out)
{
    ag_growth_t grown[AG_UNITS_MAX] = {{0u, 0.0}}; /* the previous advance is read until the end */
    uint8_t n_grown = 0u;
    for (uint8_t k = 0u; k < now->n; ++k) {
        const ag_unit_t *u = &now->unit[k];
        double g = 0.0;
        double g_before = 0.0;
        bool short_base = false;
        if (u->amp < s->cfg.amp_floor || !unit_growth(s, now, u, &g, &short_base)) {
            continue;
        }
        if (g > out->growth) {
            out->growth = g;
            out->growth_unit = u->id;
        }
        const bool steep_before = advance_growth(s, u->id, &g_before) && g_before >= s->cfg.growth_stop;
        const double stop = short_base ? s->cfg.growth_max : s->cfg.growth_stop;
        if (g >= stop && (u->amp >= s->cfg.amp_slow || steep_before)) {
            set_ceiling(s, u->id, u->amp, g, now->depth_um);
        }
        if (!short_base) { /* over a short baseline rule 5 still counts it unmeasured */
            grown[n_grown++] = (ag_growth_t){u->id, g};
        }
    }
    memcpy(s->grown, grown, (size_t)n_grown * sizeof grown[0]);
    s->n_grown = n_grown;
}

/* Rule 4: ceilings of units not seen for AG_HISTORY intervals lapse. */
static void age_ceilings(ag_state_t *s, const ag_snapshot_t *now)
{
    uint8_t kept = 0u;
    for (uint8_t i = 0u; i < s->n_ceil; ++i) {
        ag_ceiling_t c = s->ceil[i];
        c.unseen = (unit_amp(now, c.id) > 0.0) ? 0u : (uint8_t)(c.unseen + 1u);
        if (c.unseen < AG_HISTORY) {
            s->ceil[kept++] = c;
        } else {
            s->lapses++;
        }
    }
    s->n_ceil = kept;
}

/* A unit's level at a standstill: the mean of its amplitude in this
 * interval and the AG_STILL_INTERVALS - 1 before, when all were recorded at
 * this depth and saw it. Averaging six intervals shrinks the interval-to-
 * interval noise (a few per cent) by about 2.4, so that a creep of a few per
 * cent per minute stands out of it. */
static bool still_level(const ag_state_t *s, const ag_snapshot_t *now, const ag_unit_t *u, double *level)
{
    if (s->hist_n < AG_STILL_INTERVALS - 1u) {
        return false;
    }
    double sum = u->amp;
    for (uint8_t i = 0u; i + 1u < AG_STILL_INTERVALS; ++i) {
        const ag_snapshot_t *then = history_back(s, i);
        const double a = unit_amp(then, u->id);
        if (fabs(then->depth_um - now->depth_um) >= s->cfg.still_um || !(a > 0.0)) {
            return false;
        }
        sum += a;
    }
    *level = sum / (double)AG_STILL_INTERVALS;
    return true;
}

/* Rule 3's reference: a unit's lowest level at this standstill, so that a
 * slow approach (relaxing tissue creeps by a fraction of a µm per interval)
 * adds up instead of hiding in the interval-to-interval noise. */
static void lowest_level(ag_snapshot_t *ref, uint32_t id, double level)
{
    for (uint8_t k = 0u; k < ref->n; ++k) {
        if (ref->unit[k].id == id) {
            ref->unit[k].amp = fmin(ref->unit[k].amp, level);
            return;
        }
    }
    if (ref->n < AG_UNITS_MAX) {
        ref->unit[ref->n] = (ag_unit_t){id, level};
        ref->n++;
    }
}

/* Rule 3: a unit came closer while the electrode stood still. */
static bool climbed(ag_state_t *s, const ag_snapshot_t *now, bool still)
{
    if (!still) {
        s->still_ref.n = 0u;
        return false;
    }
    bool up = false;
    for (uint8_t k = 0u; k < now->n; ++k) {
        const ag_unit_t *u = &now->unit[k];
        double level = 0.0;
        if (!still_level(s, now, u, &level) || level < s->cfg.amp_slow) {
            continue;
        }
        const ag_ceiling_t *c = find_ceiling(s, u->id);
        const double ref = unit_amp(&s->still_ref, u->id);
        up = up || (c != NULL && level >= (1.0 + s->cfg.climb_frac) * c->amp);
        up = up || (c == NULL && ref > 0.0 && level >= (1.0 + s->cfg.climb_free_frac) * ref);
        lowest_level(&s->still_ref, u->id, level);
    }
    return up;
}

/* Rule 4: the longest advance that keeps every unit seen now below its
 * ceiling (and amp_stop), predicted with the unit's growth. A ceiling unit
 * not seen now limits nothing: tracker IDs come and go, and the robust
 * amplitude, always seen, stands for the loudest unit. */
static double ceiling_room_um(const ag_state_t *s, const ag_snapshot_t *now)
{
    double room = HUGE_VAL;
    for (uint8_t i = 0u; i < s->n_ceil; ++i) {
        const double a = unit_amp(now, s->ceil[i].id);
        const double g = fmax(s->ceil[i].growth, s->cfg.growth_stop);
        if (a > 0.0) {
            room = fmin(room, (a < s->ceil[i].amp) ? log(s->ceil[i].amp / a) / g : 0.0);
        }
    }
    for (uint8_t k = 0u; k < now->n; ++k) {
        const double a = now->unit[k].amp;
        room = fmin(room, (a < s->cfg.amp_stop) ? log(s->cfg.amp_stop / a) / s->cfg.growth_stop : 0.0);
    }
    return room;
}

/* Rule 6: the tip may not pass z. A fence deeper than the one in force
 * changes nothing. */
static void put_fence(ag_state_t *s, double z)
{
    if (z < s->fence_um) {
        s->fence_um = z;
        s->fence_amp = 0.0;
        s->fence_quiet = 0u;
        s->probing = false;
        s->probe_barred = false;
        s->fences_set++;
    }
}

/* Rule 6, a probe judged on its level: growth from the level at the old
 * fence to the level probe_um deeper. Steep: the fence goes back (the tip
 * follows it, limit_step) and no probe is made from it until its level falls. */
static void judge_probe(ag_state_t *s, double level)
{
    if (!s->probing) {
        return;
    }
    s->probing = false;
    const double g = log(level / s->probe_level) / (s->fence_um - s->probe_from_um);
    if (g >= s->cfg.growth_stop) {
        s->fence_um = s->probe_from_um;
        s->fence_amp = s->probe_level;
        s->probe_barred = true;
        s->probes_steep++;
    }
}

/* Rule 6 over time: quiet intervals lapse the fence; at the fence the level
 * of the robust amplitude is taken, and a fall of it moves the fence deeper
 * by the least distance the unit must have receded to fall that much. */
static void tend_fence(ag_state_t *s, const ag_snapshot_t *now)
{
    if (isinf(s->fence_um) != 0) {
        return;
    }
    s->fence_quiet = (largest_amp(now) < s->cfg.amp_floor) ? (uint16_t)(s->fence_quiet + 1u) : 0u;
    if (s->fence_quiet >= s->cfg.fence_lapse) {
        s->fence_um = HUGE_VAL;
        s->fence_amp = 0.0;
        s->fence_lapses++;
        return;
    }
    const ag_unit_t raw = {AG_UNIT_RAW, unit_amp(now, AG_UNIT_RAW)};
    double level = 0.0;
    if (fabs(now->depth_um - s->fence_um) >= s->cfg.still_um || !(raw.amp > 0.0) ||
        !still_level(s, now, &raw, &level)) {
        return;
    }
    if (!(s->fence_amp > 0.0)) {
        s->fence_amp = level;
        judge_probe(s, level);
        return;
    }
    if (level <= (1.0 - s->cfg.fence_drop_frac) * s->fence_amp) {
        s->fence_um += log(s->fence_amp / level) / s->cfg.growth_max;
        s->fence_amp = 0.0;
        s->probe_barred = false;
        s->fence_moves++;
    }
}

/* Rule 7: the give-back still to come decays with time and grows with
 * every advance (the travel since the interval before). */
static void track_creep(ag_state_t *s, double moved, double time_s)
{
    if (s->hist_n > 0u) {
        const double before = s->pending_um;
        s->pending_um *= exp(-(time_s - s->time_s) / s->cfg.relax_tau_s);
        s->followed_um += before - s->pending_um;
    }
    s->pending_um += (moved > 0.0) ? s->cfg.relax_frac * moved : 0.0;
    s->time_s = time_s;
}

/* Rule 7: the give-back that comes within creep_horizon_s. The guard looks
 * again every interval, so what comes later is judged when it is nearer. */
static double creep_soon_um(const ag_state_t *s)
{
    return s->pending_um * (1.0 - exp(-s->cfg.creep_horizon_s / s->cfg.relax_tau_s));
}

/* Rule 7: a unit that will pass its ceiling (or amp_stop) by climb_free_frac once
 * the give-back of the horizon has come, predicted with its growth. */
static bool creep_ahead(const ag_state_t *s, const ag_snapshot_t *now)
{
    const double rise = 1.0 + s->cfg.climb_free_frac; /* a prediction: the wider margin */
    const double soon = creep_soon_um(s);
    for (uint8_t i = 0u; i < s->n_ceil; ++i) {
        const double a = unit_amp(now, s->ceil[i].id);
        const double g = fmax(s->ceil[i].growth, s->cfg.growth_stop);
        if (a > 0.0 && a * exp(g * soon) >= rise * s->ceil[i].amp) {
            return true;
        }
    }
    return largest_amp(now) * exp(s->cfg.growth_stop * soon) >= rise * s->cfg.amp_stop;
}

/* Rule 7: the retraction that keeps the geometry of a ceiling's moment: the
 * tip follows the give-back come since it was set (0: none due). Following
 * it as it comes, not all of it at once, keeps the distance the ceiling
 * chose, no more: all at once held a tip beside a neuron 25 µm off the track
 * ~12 µm further away for minutes. */
static double given_back_um(const ag_state_t *s, const ag_snapshot_t *now)
{
    double back = 0.0;
    for (uint8_t i = 0u; i < s->n_ceil; ++i) {
        const ag_ceiling_t *c = &s->ceil[i];
        const double allowed = c->depth_um - fmax(c->pending_um - s->pending_um, 0.0);
        if (unit_amp(now, c->id) > 0.0 && now->depth_um - allowed > 0.1 * s->cfg.still_um) { /* not rounding */
            back = fmax(back, now->depth_um - allowed);
        }
    }
    return back;
}

/* Rules 3, 6 and 7: a retraction, when a unit came closer or will; the tip
 * may not go back past where it retracted to. */
static bool retract(ag_state_t *s, const ag_snapshot_t *now, bool still, double *step)
{
    const bool up = climbed(s, now, still); /* always: it keeps the standstill's reference */
    const bool creeping = creep_ahead(s, now);
    const double over = given_back_um(s, now);
    if (!up && !creeping && !(over > 0.0)) {
        return false;
    }
    if (up || creeping) { /* following the give-back keeps the geometry, and the standstill */
        s->still_ref.n = 0u;
    }
    s->retractions++;
    s->creep_retractions += (!up) ? 1u : 0u;
    *step = fmin(*step, (up || creeping) ? -s->cfg.retract_um : -over);
    put_fence(s, now->depth_um + *step);
    return true;
}

/* Rule 5: a unit at amp_slow whose growth on the latest advance was not
 * measured or reached growth_slow: the tip may be closing in on it. Returns
 * the loudest such unit's amplitude (rule 10 scales the advance by it), 0 if
 * none. */
static double loud_and_closing(const ag_state_t *s, const ag_snapshot_t *now)
{
    double loudest = 0.0;
    for (uint8_t k = 0u; k < now->n; ++k) {
        double g = 0.0;
        if (now->unit[k].amp >= s->cfg.amp_slow &&
            (!advance_growth(s, now->unit[k].id, &g) || g >= s->cfg.growth_slow)) {
            loudest = fmax(loudest, now->unit[k].amp);
        }
    }
    return loudest;
}

/* Rule 6: a probe of probe_um past the fence, when the tip stands at it,
 * its level is known, no probe is pending or barred, and the tissue has
 * nearly settled (the give-back due soon would add to the growth). */
static bool try_probe(ag_state_t *s, const ag_snapshot_t *now)
{
    if (isinf(s->fence_um) != 0 || fabs(now->depth_um - s->fence_um) >= s->cfg.still_um || !(s->fence_amp > 0.0) ||
        s->probing || s->probe_barred || creep_soon_um(s) >= s->cfg.still_um) {
        return false;
    }
    s->probe_from_um = s->fence_um;
    s->probe_level = s->fence_amp;
    s->fence_um += s->cfg.probe_um;
    s->fence_amp = 0.0;
    s->probing = true;
    s->probes++;
    return true;
}

/* Rule 6: the step the fence allows; back to it after a steep probe. */
static double fence_step(ag_state_t *s, const ag_snapshot_t *now, double step, ag_action_t *action)
{
    double to_fence = s->fence_um - now->depth_um;
    if (to_fence <= -s->cfg.still_um) {
        *action = AG_RETRACT;
        s->retractions++;
        return fmin(step, to_fence);
    }
    to_fence = fmax(to_fence, 0.0);
    if (step > to_fence && try_probe(s, now)) {
        to_fence = fmax(s->fence_um - now->depth_um, 0.0);
    }
    if (step > to_fence) {
        *action = AG_BLOCKED;
        return to_fence;
    }
    return step;
}

/* Rule 8: in active tissue an advance may leave at most pace_um of give-back
 * to come (each µm of advance adds relax_frac µm of it). A remainder shorter
 * than a standstill is no step. */
static double pace_step(const ag_state_t *s, const ag_snapshot_t *now, double step, ag_action_t *action)
{
    const ag_config_t *c = &s->cfg;
    if (!(c->pace_um > 0.0) || !(step > 0.0) || largest_amp(now) < c->amp_floor) {
        return step;
    }
    const double room = fmax((c->pace_um - s->pending_um) / c->relax_frac, 0.0);
    if (step <= room) {
        return step;
    }
    *action = (*action == AG_PASS) ? AG_SLOWED : *action;
    return (room >= c->still_um) ? room : 0.0;
}

/* Rule 9: a tip the SFSM lets stand in loud tissue follows the give-back:
 * it keeps a target that moves back by the give-back as it comes, and goes
 * there once it is still_um or more away (the servo stops within its
 * tolerance, so the target, not the last step, is what is followed). Any
 * other move, or quiet tissue, ends the following. */
static double follow_step(ag_state_t *s, const ag_snapshot_t *now, bool lone, double step, ag_action_t *action)
{
    const ag_config_t *c = &s->cfg;
    const double came = s->followed_um;
    s->followed_um = 0.0;
    if (!c->follow || lone || fabs(step) >= c->still_um || largest_amp(now) < c->amp_slow) {
        s->following = false;
        return step;
    }
    if (!s->following) {
        s->following = true;
        s->follow_target_um = now->depth_um;
        return step;
    }
    s->follow_target_um -= came;
    if (now->depth_um - s->follow_target_um < c->still_um) {
        return step;
    }
    s->follows++;
    s->follow_moved = true;
    *action = AG_RETRACT;
    return s->follow_target_um - now->depth_um;
}

/* Rules 3 to 10: the step. */
static double limit_step(ag_state_t *s, const ag_snapshot_t *now, const ag_input_t *in, bool still, ag_action_t *action)
{
    const ag_config_t *c = &s->cfg;
    double step = in->move_um;
    *action = AG_PASS;
    if (retract(s, now, still, &step)) {
        *action = AG_RETRACT;
        return step;
    }
    const double loud = loud_and_closing(s, now);
    const double near = (c->near_scale && loud > 0.0) ? c->move_near_um * fmin(1.0, c->amp_slow / loud)
                                                      : c->move_near_um;
    if (loud > 0.0 && step > near) {
        step = near;
        *action = AG_SLOWED;
    }
    const double room = fmax(ceiling_room_um(s, now) - creep_soon_um(s), 0.0);
    if (step > room) {
        step = room;
        *action = AG_BLOCKED;
        put_fence(s, now->depth_um + room);
    }
    return follow_step(s, now, in->lone, pace_step(s, now, fence_step(s, now, step, action), action), action);
}

static bool input_valid(const ag_state_t *s, const ag_input_t *in)
{
    if (!isfinite(in->depth_um) || !isfinite(in->move_um) || !isfinite(in->time_s) ||
        (s->hist_n > 0u && in->time_s < s->time_s) || in->n_units > AG_UNITS_MAX ||
        (in->unit == NULL && in->n_units > 0u)) {
        return false;
    }
    for (size_t k = 0u; k < in->n_units; ++k) {
        if (!isfinite(in->unit[k].amp) || in->unit[k].amp < 0.0) {
            return false;
        }
    }
    return true;
}

/* The interval's units that were seen (amplitude > 0). */
static void snapshot(const ag_input_t *in, ag_snapshot_t *now)
{
    memset(now, 0, sizeof *now);
    now->depth_um = in->depth_um;
    for (size_t k = 0u; k < in->n_units; ++k) {
        if (in->unit[k].amp > 0.0) {
            now->unit[now->n] = in->unit[k];
            now->n++;
        }
    }
}

md_status_t ag_apply(ag_state_t *s, const ag_input_t *in, ag_output_t *out)
{
    if (s == NULL || in == NULL || out == NULL) {
        return MD_E_ARG;
    }
    memset(out, 0, sizeof *out);
    s->cycles++;
    out->fence_um = s->fence_um;
    out->pending_um = s->pending_um;
    if (!input_valid(s, in)) {
        s->bad_inputs++;
        out->action = AG_BAD_INPUT;
        out->n_ceilings = s->n_ceil;
        return MD_E_ARG;
    }
    ag_snapshot_t now;
    snapshot(in, &now);
    const double moved = (s->hist_n > 0u) ? now.depth_um - history_back(s, 0u)->depth_um : 0.0;
    /* a retraction that followed the give-back keeps the standstill (rule 3) */
    const bool still = s->hist_n > 0u && (fabs(moved) < s->cfg.still_um || s->follow_moved);
    s->follow_moved = false;
    track_creep(s, moved, in->time_s);
    age_ceilings(s, &now);
    if (moved >= s->cfg.still_um) {
        mark_steep(s, &now, out); /* judged on arrival after an advance only */
    }
    tend_fence(s, &now);
    out->move_um = limit_step(s, &now, in, still, &out->action);
    push_history(s, &now);
    s->last_growth = out->growth;
    s->limited += (out->action != AG_PASS) ? 1u : 0u;
    out->n_ceilings = s->n_ceil;
    out->fence_um = s->fence_um;
    out->pending_um = s->pending_um;
    return MD_OK;
}

bool ag_settled(const ag_state_t *s)
{
    return (s != NULL) && (s->pending_um <= s->cfg.settle_um);
}
