/// @file approach_guard.h
/// Approach guard: a tracker-independent limit on electrode motion that keeps
/// the tip away from the neurons it approaches (ours; the thesis leaves
/// damage avoidance to Ω3, IQM >= γ3, which needs the tracker to see the
/// neuron). It runs after the SFSM in every state and with every tracker,
/// and may only shorten or cancel the SFSM's step, or retract.
///
/// What it reads, once per recording interval: the depth at which the
/// interval was recorded and the amplitude of every *unit* it can tell apart:
/// the interval's *robust amplitude* — the k-th largest peak-to-peak of all
/// detected windows, outliers included, over the noise RMS — which needs no
/// tracker and follows the loudest unit, and the SNR of each track the
/// tracker reports (any tracker), which follows quieter units that the
/// loudest one would mask. A unit is known by an id across intervals
/// (AG_UNIT_RAW for the robust amplitude, the track id otherwise).
///
/// Why growth: a neuron's amplitude follows A(d) = A0 / (1 + d^2 / d0^2)
/// (d tip–soma distance). Along the track, with r the neuron's lateral
/// distance and x the axial distance still to go, ln A grows per µm of
/// approach by 2x / (d0^2 + r^2 + x^2): at most 1/sqrt(d0^2 + r^2). A neuron
/// on the path (r = 0) grows up to 1/d0; one the tip passes safely (r well
/// above the damage radius) grows less. Amplitude alone cannot tell them
/// apart (A0 is unknown), growth per µm can. The limits, with their defaults
/// justified from measurements, are in docs/sfsm.md ("Approach guard").
///
/// Rules, every interval (a *ceiling* is an amplitude a unit may not be
/// driven past):
///  1. on arrival after an advance, per unit, growth g = ln(a / a_j) /
///     (z - z_j) against the newest earlier interval j recorded at least
///     baseline_min_um shallower that saw the unit; a unit (a >= amp_floor)
///     whose growth reached growth_stop on two advances in a row — or on one,
///     once it is at amp_slow — is steep like a neuron on the path: its
///     present amplitude becomes its ceiling. A unit first seen less than
///     baseline_min_um back (a new track, often a neuron that was masked) is
///     measured against the newest interval at least baseline_new_um
///     shallower, and is steep from growth_max on (that reading is noisier,
///     and a neuron beside the track can read growth_stop when its track is
///     born); rule 5 still counts its growth unmeasured;
///  2. amp_stop is a ceiling for every unit, whatever its growth;
///  3. a unit's level (mean of its last AG_STILL_INTERVALS amplitudes, all
///     at this depth; >= amp_slow) that climbed while the electrode stood
///     still — the unit came closer: tissue relaxation, drift — retracts by
///     retract_um: a climb to (1 + climb_frac) times its ceiling, or, for a
///     unit without one, to (1 + climb_free_frac) times its lowest level at
///     this standstill (a slow creep adds up);
///  4. an advance stops where the unit would reach its ceiling, predicted
///     with its growth (at least growth_stop): no advance at the ceiling,
///     and the electrode follows a unit that moves away. A ceiling whose
///     unit was not seen for AG_HISTORY intervals lapses (it left, or an
///     artefact burst ended), so a transient never freezes the search;
///  5. advances are at most move_near_um while a unit at amp_slow may be
///     ahead: its growth on the latest advance reached growth_slow, or was
///     not measured (the first interval, a new track). A loud unit the tip
///     stands beside grows little and does not slow the search; one ahead
///     on the path grows about 2 / x at axial distance x, so growth_slow
///     catches it from a few hundred µm. Retractions are never shortened;
///  6. a depth *fence*: where the guard retracted (the depth it retracted
///     to) or a ceiling cut an advance (the depth the advance was cut to),
///     the tip may not go deeper, even when the unit's ceiling later lapses
///     (a sparse unit unseen for a while, a track that changed its id). On
///     arrival at the fence the guard takes the level of the robust
///     amplitude there; once that level has fallen by fence_drop_frac the
///     unit moved away by at least ln(level then / level now) / growth_max
///     (no unit's ln amplitude grows faster than growth_max per µm of
///     approach), and the fence moves deeper by that much. A unit that
///     stays put (a neuron beside the track, which may have set a ceiling:
///     growth alone cannot tell it from one on the path) is *probed*: once
///     the tissue has settled and the level at the fence is known, the
///     fence moves probe_um deeper; the level there, against the level
///     before, gives the growth over the probe, and a steep one puts the
///     fence, and the tip, back and bars probes until the level falls.
///     A fence lapses
///     after fence_lapse intervals in a row in which no unit reached
///     amp_floor (nothing near: the search may go on);
///  7. tissue *creep*: an advance drags the tissue along, and a fraction
///     relax_frac of it springs back towards the tip over the following
///     minutes (time constant relax_tau_s), carrying the neurons below with
///     it. The part due within creep_horizon_s shortens every ceiling's
///     room, and when a ceiling unit (or the loudest unit against amp_stop)
///     would rise to (1 + climb_free_frac) times its ceiling once it has come,
///     the guard retracts now rather than wait for rule 3 to see the climb.
///     The horizon spans a few intervals, not the whole give-back: the guard
///     looks again every interval, and what comes later is judged nearer.
///     And a ceiling keeps the geometry of the moment it was set: the tip
///     follows the give-back due then as it comes, retracting by what came
///     since (near the soma the amplitude hardly grows, and the give-back
///     after a descent is more than the room a ceiling leaves). Following
///     the give-back keeps the standstill of rule 3;
///  8. *pace*: while a unit reaches amp_floor (active tissue, where a neuron
///     louder ones mask may lie ahead unseen), no advance lifts the give-back
///     still to come above pace_um: what the tissue brings back after the tip
///     stops is then at most pace_um, whatever lies below. 0 turns it off.
///     The tissue counts as *settled* (ag_settled) once that give-back is at
///     most settle_um: what the SFSM's settled approach waits for;
///  9. *follow*: while the SFSM lets the tip stand with a unit at amp_slow,
///     the tip retracts by the give-back that came since it stopped (once it
///     adds up to still_um): the tissue's geometry around the tip stays as it
///     was when the tip stopped, so no neuron, seen or masked, is carried
///     closer by the give-back. Such a retraction keeps the standstill of
///     rule 3, which then sees what the model does not (drift). It stands
///     down while the caller holds a lone, well-isolated neuron
///     (ag_input_t.lone). Off when follow is false;
/// 10. *near scale*: with near_scale, rule 5's longest advance is
///     move_near_um × amp_slow / the loudest unit that may be ahead.
/// Invalid input (non-finite, or time running backwards) holds the electrode
/// and is counted.
///
/// Memory: ag_state_t, fixed size, caller-owned. No I/O, no heap.
#ifndef APPROACH_GUARD_H
#define APPROACH_GUARD_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "md_status.h"
#include "md_config.h"

#define AG_HISTORY 8u                       ///< intervals kept for the growth and standstill rules
#define AG_TOP_K_MAX 16u                    ///< largest k of the robust amplitude
#define AG_UNITS_MAX (MD_MAX_TARGETS + 1u)  ///< units per interval: every track and the robust amplitude
#define AG_UNIT_RAW UINT32_MAX              ///< unit id of the robust amplitude
#define AG_STILL_INTERVALS 6u               ///< a unit's level at a standstill: mean of this many intervals

_Static_assert(AG_STILL_INTERVALS >= 2u && AG_STILL_INTERVALS <= AG_HISTORY,
               "a standstill level needs that many intervals of history");

/// One unit's amplitude in one interval (noise RMS units).
typedef struct {
    uint32_t id;
    double amp;
} ag_unit_t;

/// What one interval saw.
typedef struct {
    double depth_um;
    uint8_t n;
    ag_unit_t unit[AG_UNITS_MAX];
} ag_snapshot_t;

/// What the guard did to the SFSM's step.
typedef enum {
    AG_PASS = 0,  ///< step unchanged
    AG_SLOWED,    ///< advance shortened to move_near_um (loud unit ahead)
    AG_BLOCKED,   ///< advance shortened or cancelled by a ceiling
    AG_RETRACT,   ///< retraction ordered: the unit climbed while standing still
    AG_BAD_INPUT  ///< non-finite input: hold
} ag_action_t;

typedef struct {
    double growth_stop;      ///< 1/µm: ln-amplitude growth per µm of advance that marks a unit steep
    double growth_slow;      ///< 1/µm: growth below which a loud unit does not slow the advance (rule 5)
    double baseline_min_um;  ///< shortest travel over which growth is measured
    double baseline_new_um;  ///< the same for a unit not seen baseline_min_um back (a new track)
    double amp_floor;        ///< below this robust amplitude (noise RMS units) growth is not judged
    double amp_slow;         ///< from this amplitude advances are at most move_near_um
    double amp_stop;         ///< a ceiling for every unit
    double move_near_um;     ///< longest advance at or above amp_slow
    double climb_frac;       ///< rise over a unit's ceiling that retracts (rule 3)
    double climb_free_frac;  ///< rise over its lowest level at a standstill that retracts a unit without a ceiling
    double retract_um;       ///< retraction step
    double still_um;         ///< moves shorter than this count as standing still
    double growth_max;       ///< 1/µm: steepest ln-amplitude growth per µm of approach (1 / d0 of the law)
    double fence_drop_frac;  ///< fall of the level at the fence that moves the fence deeper (rule 6)
    double relax_frac;       ///< share of an advance the tissue gives back towards the tip (rule 7)
    double relax_tau_s;      ///< time constant of that give-back
    double creep_horizon_s;  ///< rule 7 counts the give-back due within this time
    double probe_um;         ///< a probe past the fence (rule 6)
    double pace_um;          ///< rule 8: most give-back an advance in active tissue may leave to come (0: off)
    double settle_um;        ///< give-back still to come at or below which the tissue counts as settled
    bool follow;             ///< rule 9: a standing tip follows the give-back
    bool near_scale;         ///< rule 5: move_near_um shrinks as amp_slow / amplitude
    uint16_t fence_lapse;    ///< quiet intervals (no unit at amp_floor) after which a fence lapses
    uint8_t top_k;           ///< robust amplitude = k-th largest window amplitude (1..AG_TOP_K_MAX)
} ag_config_t;

/// A unit's growth measured on an advance.
typedef struct {
    uint32_t id;
    double growth;  ///< 1/µm: ln-amplitude growth per µm of advance
} ag_growth_t;

/// A unit's ceiling.
typedef struct {
    uint32_t id;
    double amp;         ///< its ceiling
    double growth;      ///< its growth when it was set (>= growth_stop)
    double depth_um;    ///< where the tip was when it was set
    double pending_um;  ///< the tissue's give-back still to come then (rule 7)
    uint8_t unseen;     ///< intervals since the unit was last seen
} ag_ceiling_t;

typedef struct {
    ag_config_t cfg;
    ag_snapshot_t hist[AG_HISTORY];
    uint8_t hist_n;
    uint8_t hist_head;  ///< slot of the next entry
    ag_ceiling_t ceil[AG_UNITS_MAX];
    uint8_t n_ceil;
    ag_growth_t grown[AG_UNITS_MAX];  ///< each unit's growth on the latest advance: rules 1 and 5
    uint8_t n_grown;
    ag_snapshot_t still_ref;  ///< per unit, its lowest level at the current standstill (rule 3)
    double last_growth;       ///< largest unit growth of the latest interval (0 if none measured)
    double fence_um;          ///< rule 6: deepest depth allowed (HUGE_VAL: no fence)
    double fence_amp;         ///< level of the robust amplitude at the fence (0: not yet taken)
    uint16_t fence_quiet;     ///< intervals in a row with no unit at amp_floor
    bool probing;             ///< the fence was moved probe_um by a probe not judged yet
    bool probe_barred;        ///< a probe from this fence was steep: none until its level falls
    double probe_from_um;     ///< the fence before the probe
    double probe_level;       ///< the level there
    double pending_um;        ///< rule 7: tissue give-back still to come
    double followed_um;       ///< rule 9: give-back come over the latest interval
    bool following;           ///< rule 9: the tip stands and follows the give-back
    bool follow_moved;        ///< rule 9: the latest step was a following retraction
    double follow_target_um;  ///< rule 9: where the tip stands in the tissue's frame
    double time_s;            ///< the latest interval's time
    uint32_t cycles, ceilings_set, retractions, lapses, limited, bad_inputs;
    uint32_t fences_set, fence_moves, fence_lapses, creep_retractions, probes, probes_steep, follows;
} ag_state_t;

typedef struct {
    const ag_unit_t *unit;  ///< the interval's units (ids distinct; amp >= 0, 0: not seen)
    size_t n_units;         ///< 0..AG_UNITS_MAX
    double depth_um;        ///< depth at which the interval was recorded
    double time_s;          ///< when it was recorded (s; finite, never less than the interval before)
    double move_um;         ///< the SFSM's step (signed, + advances)
    bool lone;              ///< the SFSM holds one well-isolated neuron (IQM >= γ3): rule 9 stands down
} ag_input_t;

typedef struct {
    double move_um;  ///< the step to execute
    ag_action_t action;
    double growth;         ///< largest unit growth of this interval (0 if none measured)
    uint32_t growth_unit;  ///< its unit id
    uint8_t n_ceilings;    ///< ceilings in force after this interval
    double fence_um;       ///< the fence after this interval (HUGE_VAL: none)
    double pending_um;     ///< tissue give-back still expected (rule 7)
} ag_output_t;

/// Defaults (docs/sfsm.md, "Approach guard").
void ag_config_default(ag_config_t *cfg);

/// MD_OK if every field is in range (positive limits, amp_floor <= amp_slow
/// < amp_stop, climb_frac <= climb_free_frac, growth_slow <= growth_stop
/// <= growth_max,
/// fence_drop_frac and relax_frac in (0, 1), fence_lapse >= 1, probe_um,
/// relax_tau_s and creep_horizon_s > 0, pace_um and settle_um >= 0,
/// 1 <= top_k <= AG_TOP_K_MAX), else MD_E_ARG.
md_status_t ag_config_check(const ag_config_t *cfg);

/// Starts with no history and no ceiling. MD_E_ARG on NULL or a bad config.
md_status_t ag_init(ag_state_t *s, const ag_config_t *cfg);

/// Robust amplitude of an interval: the k-th largest peak-to-peak amplitude
/// over `n` int16 windows of `d_w` samples (row stride `stride`), times
/// `gain` (µV per count) over `noise_rms_uv`. Fewer than k windows give 0
/// (too little to judge). MD_E_ARG on NULL (with n > 0), d_w < 2,
/// d_w > stride, k outside 1..AG_TOP_K_MAX, or a non-positive gain or noise.
/// O(n · (d_w + k)).
md_status_t ag_robust_amplitude_i16(const int16_t *wave, size_t n, size_t stride, size_t d_w, double gain,
                                    double noise_rms_uv, uint8_t k, double *amp);

/// One interval: updates the history and the ceilings, limits in->move_um.
/// MD_E_ARG on NULL (nothing written) or invalid input — non-finite depth,
/// time or step, a time before the previous interval's, a non-finite or
/// negative amplitude, more than AG_UNITS_MAX units or
/// a NULL unit array with n_units > 0 (out: step 0, AG_BAD_INPUT, counted).
/// O(AG_HISTORY · AG_UNITS_MAX²).
md_status_t ag_apply(ag_state_t *s, const ag_input_t *in, ag_output_t *out);

/// True when the give-back still to come (rule 7, as of the latest interval)
/// is at most cfg.settle_um; false on NULL.
bool ag_settled(const ag_state_t *s);

#endif
