#include "model/hall_sensor.h"

#include <math.h>
#include <stdbool.h>
#include <string.h>

void hall_default_params(hall_params_t *p)
{
    p->center_um = 2800.0;
    p->length_um = 3000.0;
    p->offset_codes = 32768.0;
    p->amplitude_codes = 30000.0;
    p->adc_bits = 16u;
    p->noise_codes = 2.0;
    p->drift_codes_per_hour = 2.0;
    p->drift_amp_codes = 3.0;
    p->drift_period_s = 1800.0;
    p->report_rate_hz = 100.0;
    p->cal_degree = 9u;
}

md_status_t hall_params_check(const hall_params_t *p)
{
    const bool ok = isfinite(p->center_um) && p->length_um > 0.0 && p->amplitude_codes > 0.0 && p->adc_bits >= 8u &&
                    p->adc_bits <= 24u && p->noise_codes >= 0.0 && isfinite(p->drift_codes_per_hour) &&
                    p->drift_amp_codes >= 0.0 && p->drift_period_s > 0.0 && p->report_rate_hz > 0.0 &&
                    p->cal_degree >= 1u && p->cal_degree <= HALL_CAL_MAX_DEGREE;
    return ok ? MD_OK : MD_E_ARG;
}

double hall_ideal_code(const hall_params_t *p, double depth_um)
{
    return p->offset_codes + p->amplitude_codes * tanh((depth_um - p->center_um) / p->length_um);
}

double hall_drift_codes(const hall_params_t *p, double t_s)
{
    return p->drift_codes_per_hour * t_s / 3600.0 +
           p->drift_amp_codes * sin(6.283185307179586 * t_s / p->drift_period_s);
}

uint32_t hall_read(hall_sensor_t *h, double depth_um, double t_s)
{
    const double full = ldexp(1.0, (int)h->p.adc_bits) - 1.0;
    const double v = hall_ideal_code(&h->p, depth_um) + hall_drift_codes(&h->p, t_s) +
                     h->p.noise_codes * sim_rng_normal(&h->rng);
    const double q = floor(v + 0.5);
    return (uint32_t)fmin(fmax(q, 0.0), full);
}

double hall_cal_depth_um(const hall_calibration_t *cal, double code)
{
    const double x = (code - cal->code_mid) / cal->code_half;
    double y = 0.0;
    for (uint32_t k = cal->degree + 1u; k-- > 0u;) {
        y = y * x + cal->coef[k];
    }
    return y;
}

/* Least squares by modified Gram-Schmidt on the Vandermonde matrix: better
 * conditioned than normal equations at degree 9-11. */
static md_status_t hall_fit(hall_calibration_t *cal, const double *x, const double *y, uint32_t n, uint32_t deg)
{
    static double q[HALL_CAL_MAX_DEGREE + 1u][HALL_CAL_POINTS];
    double r[HALL_CAL_MAX_DEGREE + 1u][HALL_CAL_MAX_DEGREE + 1u];
    const uint32_t m = deg + 1u;
    memset(r, 0, sizeof r);
    for (uint32_t j = 0u; j < m; ++j) {
        for (uint32_t i = 0u; i < n; ++i) {
            q[j][i] = pow(x[i], (double)j);
        }
        for (uint32_t k = 0u; k < j; ++k) {
            double d = 0.0;
            for (uint32_t i = 0u; i < n; ++i) {
                d += q[k][i] * q[j][i];
            }
            r[k][j] = d;
            for (uint32_t i = 0u; i < n; ++i) {
                q[j][i] -= d * q[k][i];
            }
        }
        double nn = 0.0;
        for (uint32_t i = 0u; i < n; ++i) {
            nn += q[j][i] * q[j][i];
        }
        r[j][j] = sqrt(nn);
        if (!(r[j][j] > 1e-12)) {
            return MD_E_NUMERIC;
        }
        for (uint32_t i = 0u; i < n; ++i) {
            q[j][i] /= r[j][j];
        }
    }
    double qty[HALL_CAL_MAX_DEGREE + 1u];
    for (uint32_t j = 0u; j < m; ++j) {
        qty[j] = 0.0;
        for (uint32_t i = 0u; i < n; ++i) {
            qty[j] += q[j][i] * y[i];
        }
    }
    for (uint32_t j = m; j-- > 0u;) {
        double s = qty[j];
        for (uint32_t k = j + 1u; k < m; ++k) {
            s -= r[j][k] * cal->coef[k];
        }
        cal->coef[j] = s / r[j][j];
    }
    return MD_OK;
}

md_status_t hall_init(hall_sensor_t *h, const hall_params_t *p, double travel_um, uint64_t seed, uint32_t electrode)
{
    if (h == NULL || p == NULL || hall_params_check(p) != MD_OK || !(travel_um > 0.0)) {
        return MD_E_ARG;
    }
    memset(h, 0, sizeof *h);
    h->p = *p;
    h->travel_um = travel_um;
    sim_rng_init(&h->rng, seed, SIM_RNG_HALL, electrode, 0u);
    const double full = ldexp(1.0, (int)p->adc_bits) - 1.0;
    const double c0 = hall_ideal_code(p, 0.0), c1 = hall_ideal_code(p, travel_um);
    if (c0 < 0.0 || c1 > full || !(c1 - c0 > 1.0)) {
        return MD_E_NUMERIC; /* saturates over the travel: no unique inverse */
    }
    hall_calibration_t *cal = &h->cal;
    cal->degree = p->cal_degree;
    cal->code_mid = 0.5 * (c0 + c1);
    cal->code_half = 0.5 * (c1 - c0);
    double xs[HALL_CAL_POINTS], ys[HALL_CAL_POINTS];
    for (uint32_t i = 0u; i < HALL_CAL_POINTS; ++i) {
        ys[i] = travel_um * (double)i / (double)(HALL_CAL_POINTS - 1u);
        xs[i] = (hall_ideal_code(p, ys[i]) - cal->code_mid) / cal->code_half;
    }
    const md_status_t st = hall_fit(cal, xs, ys, HALL_CAL_POINTS, cal->degree);
    if (st != MD_OK) {
        return st;
    }
    for (uint32_t i = 0u; i < HALL_CAL_POINTS; ++i) {
        const double e = fabs(hall_cal_depth_um(cal, hall_ideal_code(p, ys[i])) - ys[i]);
        cal->max_fit_error_um = fmax(cal->max_fit_error_um, e);
    }
    return MD_OK;
}
