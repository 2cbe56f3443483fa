/// @file tissue.h
/// Axial tissue motion along one electrode's track (thesis §2.3.2: electrode
/// drift, decompression after dura penetration and after movements).
///
/// s(t) is the displacement of the tissue along the depth axis (um, positive =
/// deeper); a neuron whose tissue depth is z appears at z + s(t). Terms:
///  - insertion decompression: -insert_relax_um * (1 - exp(-t / insert_tau_s))
///    (the tissue pushed down by the insertion rises back);
///  - slow drift: drift_um_per_min * (t - drift_start_s) / 60 after drift_start_s;
///  - drag by electrode movements: a move of d um drags the tissue by
///    drag * d, drag = drag_advance or drag_retract (the two differ:
///    hysteresis between advancing and retracting). A fraction
///    permanent_fraction of it stays; the rest relaxes back exponentially with
///    move_tau_s (decompression after movements), |relaxing part| <= max_relax_um;
///  - breathing and heartbeat micro-motion: sinusoids (off by default).
#ifndef SIM_TISSUE_H
#define SIM_TISSUE_H

#include "md_status.h"

typedef struct {
    double drift_um_per_min;    ///< default 0.3 um/min
    double drift_start_s;       ///< default 0 s
    double insert_relax_um;     ///< default 40 um
    double insert_tau_s;        ///< default 1800 s
    double drag_advance;        ///< default 0.30 (fraction of an advance)
    double drag_retract;        ///< default 0.15 (fraction of a retraction)
    double permanent_fraction;  ///< default 0.2
    double move_tau_s;          ///< default 120 s
    double max_relax_um;        ///< default 60 um
    double breathing_um;        ///< default 0 (off); typical 2 um
    double breathing_hz;        ///< default 0.3 Hz
    double heartbeat_um;        ///< default 0 (off); typical 0.5 um
    double heartbeat_hz;        ///< default 1.5 Hz
} tissue_params_t;

typedef struct {
    tissue_params_t p;
    double t_s;       ///< model time
    double relax_um;  ///< relaxing part of the movement drag
    double perm_um;   ///< permanent part of the movement drag
} tissue_t;

void tissue_default_params(tissue_params_t *p);
md_status_t tissue_params_check(const tissue_params_t *p);
md_status_t tissue_init(tissue_t *t, const tissue_params_t *p);
/// Moves the model time to `t_s` (relaxing the drag) and then applies an
/// electrode displacement `electrode_move_um` that happened in that span.
void tissue_advance_to(tissue_t *t, double t_s, double electrode_move_um);
/// s(t) at the model time (um, positive = tissue deeper).
double tissue_displacement_um(const tissue_t *t);

#endif
