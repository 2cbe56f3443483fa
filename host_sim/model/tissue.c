#include "model/tissue.h"

#include <math.h>
#include <stdbool.h>
#include <string.h>

void tissue_default_params(tissue_params_t *p)
{
    p->drift_um_per_min = 0.3;
    p->drift_start_s = 0.0;
    p->insert_relax_um = 40.0;
    p->insert_tau_s = 1800.0;
    p->drag_advance = 0.30;
    p->drag_retract = 0.15;
    p->permanent_fraction = 0.2;
    p->move_tau_s = 120.0;
    p->max_relax_um = 60.0;
    p->breathing_um = 0.0;
    p->breathing_hz = 0.3;
    p->heartbeat_um = 0.0;
    p->heartbeat_hz = 1.5;
}

md_status_t tissue_params_check(const tissue_params_t *p)
{
    const bool ok = isfinite(p->drift_um_per_min) && p->drift_start_s >= 0.0 && isfinite(p->insert_relax_um) &&
                    p->insert_tau_s > 0.0 && p->drag_advance >= 0.0 && p->drag_advance <= 1.0 &&
                    p->drag_retract >= 0.0 && p->drag_retract <= 1.0 && p->permanent_fraction >= 0.0 &&
                    p->permanent_fraction <= 1.0 && p->move_tau_s > 0.0 && p->max_relax_um >= 0.0 &&
                    p->breathing_um >= 0.0 && p->breathing_hz > 0.0 && p->heartbeat_um >= 0.0 && p->heartbeat_hz > 0.0;
    return ok ? MD_OK : MD_E_ARG;
}

md_status_t tissue_init(tissue_t *t, const tissue_params_t *p)
{
    if (t == NULL || p == NULL || tissue_params_check(p) != MD_OK) {
        return MD_E_ARG;
    }
    memset(t, 0, sizeof *t);
    t->p = *p;
    return MD_OK;
}

void tissue_advance_to(tissue_t *t, double t_s, double electrode_move_um)
{
    if (t_s > t->t_s) {
        t->relax_um *= exp(-(t_s - t->t_s) / t->p.move_tau_s);
        t->t_s = t_s;
    }
    if (electrode_move_um > 0.0 || electrode_move_um < 0.0) {
        const double drag = (electrode_move_um > 0.0 ? t->p.drag_advance : t->p.drag_retract) * electrode_move_um;
        t->perm_um += drag * t->p.permanent_fraction;
        t->relax_um += drag * (1.0 - t->p.permanent_fraction);
        t->relax_um = fmin(fmax(t->relax_um, -t->p.max_relax_um), t->p.max_relax_um);
    }
}

double tissue_displacement_um(const tissue_t *t)
{
    const tissue_params_t *p = &t->p;
    const double two_pi = 6.283185307179586;
    double s = -p->insert_relax_um * (1.0 - exp(-t->t_s / p->insert_tau_s));
    if (t->t_s > p->drift_start_s) {
        s += p->drift_um_per_min * (t->t_s - p->drift_start_s) / 60.0;
    }
    s += t->perm_um + t->relax_um;
    s += p->breathing_um * sin(two_pi * p->breathing_hz * t->t_s);
    s += p->heartbeat_um * sin(two_pi * p->heartbeat_hz * t->t_s);
    return s;
}
