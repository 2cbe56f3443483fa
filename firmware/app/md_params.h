/// @file md_params.h
/// The controller's parameter table: every tunable value and every diagnostic
/// counter an operator can read over the bus (PARAM_REQ_CTRL / PARAM_RESP_CTRL).
///
/// The table (md_params_def) is const data, one row per parameter, sorted by
/// bus index; the values live in a caller-owned md_params_t. Values are doubles
/// inside the firmware and float32 on the wire. Diagnostic counters are rows
/// flagged MD_PARAM_F_LIVE: read-only, their value is supplied by the node
/// (md_node) when a request reads them, so the table stays the one list of
/// everything readable. docs/protocol.md prints this table (checked by a test).
///
/// To add a parameter: add an id before MD_PARAM_COUNT and a row in
/// md_params.c at the position of that id (a static assertion checks the count,
/// md_params_table_check() the order and the defaults).
#ifndef MD_PARAMS_H
#define MD_PARAMS_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "md_status.h"
#include "md_protocol.h"

/// Row flags.
#define MD_PARAM_F_READ_ONLY 0x01u  ///< sets are answered MD_PARAM_READ_ONLY
#define MD_PARAM_F_INTEGER 0x02u    ///< the value must be a whole number
#define MD_PARAM_F_MOTION 0x04u     ///< a set could move an electrode: refused while the e-stop is latched
#define MD_PARAM_F_CONFIG 0x08u     ///< changes the cycle's set-up: refused while operational
#define MD_PARAM_F_LIVE 0x10u       ///< diagnostic, value supplied by the node when read (implies read-only)

/// Dense ids: position of a row in the table. The bus uses md_param_def_t.index.
typedef enum {
    /* communication (CANopen-like indices 0x1xxx) */
    MD_P_EMCY_INHIBIT_MS = 0,   ///< min gap between two protocol-error EMCYs, 0x1015
    MD_P_HEARTBEAT_TIMEOUT_MS,  ///< consumer timeout, 0x1016
    MD_P_HEARTBEAT_PERIOD_MS,   ///< producer period, 0x1017
    MD_P_MONITOR_ACT,           ///< supervise the actuator driver's heartbeat
    MD_P_MONITOR_HALL,          ///< supervise the position sensor's heartbeat
    MD_P_MONITOR_FE,            ///< supervise the front-end's heartbeat
    MD_P_AUTO_START,            ///< go operational by itself after boot (CANopen 0x1F80)
    /* closed loop placeholders (0x2xxx), used by the electrode cycle */
    MD_P_INTERVAL_S,             ///< recording interval length
    MD_P_MOVE_MAX_UM,            ///< Delta_max, cap of one step (thesis §2.2.3, after eq. 2.1)
    MD_P_MOVE_SEARCH_UM,         ///< Delta_search
    MD_P_MOVE_SAMPLE_UM,         ///< Delta_sample
    MD_P_MOVE_RESAMPLE_UM,       ///< Delta_resample (retracting)
    MD_P_DEPTH_MIN_UM,           ///< depth window, shallow end
    MD_P_DEPTH_MAX_UM,           ///< depth window, deep end
    MD_P_SETTLE_MS,              ///< wait after a move before the next recording
    MD_P_MIN_RATE_HZ,            ///< firing rate that counts as "spikes seen" (SFSM)
    MD_P_SERVO_TOL_UM,           ///< servo: converged within this distance of the target
    MD_P_SERVO_MAX_ITER,         ///< servo: step commands per move at most
    MD_P_SERVO_AVG_N,            ///< servo: Hall readings averaged per measurement
    MD_P_SERVO_STEP_NM,          ///< servo: initial estimate of one piezo step
    MD_P_SERVO_RATE_HZ,          ///< servo: ACT_CMD step rate
    MD_P_SFSM_GAMMA1,            ///< SFSM γ1: IQM to follow the gradient
    MD_P_SFSM_GAMMA2,            ///< SFSM γ2: IQM to declare isolation at the peak
    MD_P_SFSM_GAMMA3,            ///< SFSM γ3: IQM to declare isolation at once
    MD_P_SFSM_WAIT_R,            ///< SFSM R of WAIT transitions
    MD_P_SFSM_LOST_CYCLES,       ///< SFSM cycles without a dominant track before Spike Search
    MD_P_SFSM_SNR_DROP,          ///< SFSM fraction of the isolation SNR that ends Neuron Isolated
    MD_P_SC_TOL_UM,              ///< SNR-curve optimiser ε (eq. 2.1 converged)
    MD_P_SFSM_SNR_MIN,           ///< SFSM noise floor: tracks below this SNR are never dominant
    MD_P_SFSM_SEARCH_SPAN_UM,    ///< SFSM search leash around the last dominant track
    MD_P_SFSM_SNR_ISOLATE,       ///< SFSM: dominant SNR that declares isolation at once, whatever the IQM
    MD_P_SFSM_APPROACH_UM,       ///< SFSM: settled approach step in Neuron Isolated (0: hold)
    MD_P_SFSM_APPROACH_GAIN,     ///< SFSM: SNR rise over one approach step that earns the next
    MD_P_MHTC_Q_UV,              ///< MHTC process noise std per waveform sample and interval
    MD_P_TRACKER,                ///< tracker: 0 MHTC, 1 MAP-NN, 2 ML-NN, 3 GNN (mhtc_tracker_t)
    MD_P_MHTC_UNIMODAL_RATIO,    ///< clustering: a model with two clusters forming one mode is dropped
    MD_P_MHTC_COUNT_SIGMA,       ///< tracking: ln-count spread of the spike-count term of a continuation
    MD_P_MHTC_LAMBDA_FIRST,      ///< tracking: λν of the first interval (neurons present at the start)
    MD_P_GUARD_ENABLE,           ///< approach guard limits motion (0: computed and reported only)
    MD_P_GUARD_GROWTH_STOP,      ///< approach guard: ln-amplitude growth per µm that blocks advancing
    MD_P_GUARD_AMP_SLOW,         ///< approach guard: amplitude from which advances are shortened
    MD_P_GUARD_AMP_STOP,         ///< approach guard: amplitude that blocks advancing
    MD_P_GUARD_MOVE_NEAR_UM,     ///< approach guard: longest advance at or above guard_amp_slow
    MD_P_GUARD_RETRACT_UM,       ///< approach guard: retraction when the unit climbs at a barrier
    MD_P_GUARD_CLIMB_FRAC,       ///< approach guard: climb over the lowest standstill level that retracts
    MD_P_GUARD_GROWTH_SLOW,      ///< approach guard: growth from which a loud unit shortens advances
    MD_P_GUARD_GROWTH_MAX,       ///< approach guard: steepest growth of any unit (1 / d0)
    MD_P_GUARD_FENCE_DROP,       ///< approach guard: fall of the level at the fence that moves it deeper
    MD_P_GUARD_FENCE_LAPSE,      ///< approach guard: quiet intervals after which a fence lapses
    MD_P_GUARD_RELAX_FRAC,       ///< approach guard: share of an advance the tissue gives back
    MD_P_GUARD_RELAX_TAU_S,      ///< approach guard: time constant of that give-back
    MD_P_GUARD_PROBE_UM,         ///< approach guard: a probe past the depth fence
    MD_P_GUARD_CREEP_HORIZON_S,  ///< approach guard: give-back counted within this time
    MD_P_GUARD_CEILING_CLIMB,    ///< approach guard: climb over a unit's ceiling that retracts
    MD_P_GUARD_BASELINE_UM,      ///< approach guard: shortest advance over which growth is measured
    MD_P_GUARD_BASELINE_NEW_UM,  ///< approach guard: the same for a unit first seen less far back
    MD_P_GUARD_PACE_UM,          ///< approach guard: most give-back an advance in active tissue may leave
    MD_P_GUARD_SETTLE_UM,        ///< approach guard: give-back to come at which the tissue counts as settled
    MD_P_GUARD_FOLLOW,           ///< approach guard: a standing tip follows the tissue's give-back
    MD_P_GUARD_NEAR_SCALE,       ///< approach guard: near a loud unit, steps shrink as it gets louder
    /* diagnostics (0x3xxx), read-only */
    MD_P_NODE_STATE,
    MD_P_ESTOP_LATCHED,
    MD_P_UPTIME_S,
    MD_P_RX_FRAMES,
    MD_P_RX_MALFORMED,
    MD_P_RX_UNKNOWN_ID,
    MD_P_RX_BAD_LENGTH,
    MD_P_RX_BAD_RANGE,
    MD_P_RX_BAD_SEQUENCE,
    MD_P_RX_ID_CONFLICT,
    MD_P_TX_FRAMES,
    MD_P_TX_FAILURES,
    MD_P_EMCY_SENT,
    MD_P_HEARTBEAT_LOST,
    MD_P_NODE_BACK,
    MD_P_ESTOP_EVENTS,
    MD_P_NMT_REFUSED,
    MD_P_CYCLES_DONE,
    MD_P_CYCLES_SKIPPED,
    MD_P_RECORDINGS_FAILED,
    MD_P_MOVES_FAILED,
    MD_P_COUNT
} md_param_id_t;

/// One row of the table.
typedef struct {
    uint16_t index;    ///< bus index (PARAM_REQ_CTRL Index)
    const char *name;  ///< snake_case, unique
    const char *unit;  ///< "" when dimensionless
    double min, max;   ///< inclusive bounds of a set
    double def;        ///< value after init and after NMT reset-node
    uint8_t flags;     ///< MD_PARAM_F_*
    const char *doc;   ///< one line for docs/protocol.md
} md_param_def_t;

/// Current values of every row (live rows unused: the node owns them).
typedef struct {
    double value[MD_P_COUNT];
} md_params_t;

/// Number of rows. O(1).
size_t md_params_count(void);

/// Row of dense id `id`, or NULL when id >= md_params_count(). O(1).
const md_param_def_t *md_params_def(size_t id);

/// Dense id of bus index `index`, or -1 if no row has it. O(n), n = MD_P_COUNT (small).
int md_params_find(uint16_t index);

/// Checks the const table: indices strictly increasing, names present, min <= def <= max,
/// live rows read-only. MD_OK or MD_E_STATE. Run by md_params_init; O(n).
md_status_t md_params_table_check(void);

/// Sets every value to its default. MD_E_ARG if p is NULL, MD_E_STATE if the table is inconsistent.
md_status_t md_params_init(md_params_t *p);

/// Current value of dense id `id` (not meaningful for counters). 0.0 if out of range.
double md_params_get(const md_params_t *p, md_param_id_t id);

/// Current value as a whole number, saturated to [0, UINT32_MAX]; for integer rows.
uint32_t md_params_get_u32(const md_params_t *p, md_param_id_t id);

/// Validates and applies a set of bus index `index` to `value`, in this order:
/// unknown index, read-only (live rows included), finite (NaN/inf → out of range),
/// [min, max], integrality, and cross-row rules (depth_min_um < depth_max_um).
/// The caller checks MD_PARAM_REFUSED (state rules) before calling. Nothing is
/// changed unless MD_PARAM_OK is returned. O(n).
md_param_status_t md_params_set(md_params_t *p, uint16_t index, double value);

#endif
