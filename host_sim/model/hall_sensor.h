/// @file hall_sensor.h
/// Hall-effect depth sensor, one per electrode (thesis ch. 5: Hall sensors on
/// the drive's board read electrode depth to about 1 um).
///
/// Chain: carrier depth z -> magnetic field -> ADC code. The field of the
/// magnet riding on the carrier, as seen by the fixed sensor, is modelled as
///   code(z) = offset_codes + amplitude_codes * tanh((z - center_um) / length_um)
///             + drift(t) + noise,  then rounded and clamped to the ADC range,
/// a monotonic but clearly non-linear characteristic (slope at the ends of
/// the travel ~half of that in the middle). drift(t) is a slow thermal term:
/// a linear creep plus a slow sinusoid. Noise is white Gaussian in codes.
///
/// Calibration: what a factory calibration would give the controller — a
/// polynomial depth_um = sum_k coef[k] * x^k in the normalised code
/// x = (code - code_mid) / code_half, least-squares fitted over the travel on
/// the noise-free, drift-free characteristic at time 0. See docs/simulator.md.
#ifndef SIM_HALL_SENSOR_H
#define SIM_HALL_SENSOR_H

#include <stdint.h>

#include "md_status.h"
#include "model/sim_rng.h"

#define HALL_CAL_MAX_DEGREE 11u
#define HALL_CAL_POINTS 257u  ///< fit points over the travel

typedef struct {
    double center_um;             ///< depth of the characteristic's inflection (default 2800)
    double length_um;             ///< tanh length scale (default 3000)
    double offset_codes;          ///< code at the inflection (default 32768)
    double amplitude_codes;       ///< tanh amplitude (default 30000)
    uint32_t adc_bits;            ///< ADC resolution (default 16; 8..24)
    double noise_codes;           ///< white noise sigma in codes (default 2.0: ~0.2-0.45 um)
    double drift_codes_per_hour;  ///< linear thermal creep (default 2.0)
    double drift_amp_codes;       ///< slow sinusoidal thermal term amplitude (default 3.0)
    double drift_period_s;        ///< its period (default 1800 s)
    double report_rate_hz;        ///< how often the sensor node reports (default 100 Hz)
    uint32_t cal_degree;          ///< calibration polynomial degree (default 9; 1..11)
} hall_params_t;

/// Calibration handed to the controller: code -> depth.
typedef struct {
    uint32_t degree;
    double code_mid, code_half;             ///< x = (code - code_mid) / code_half
    double coef[HALL_CAL_MAX_DEGREE + 1u];  ///< depth_um = sum coef[k] x^k
    double max_fit_error_um;                ///< worst residual over the fit points
} hall_calibration_t;

typedef struct {
    hall_params_t p;
    sim_rng_t rng;
    double travel_um;
    hall_calibration_t cal;
} hall_sensor_t;

void hall_default_params(hall_params_t *p);
md_status_t hall_params_check(const hall_params_t *p);
/// Initialises the sensor and computes its calibration. O(points * degree^2).
/// MD_E_NUMERIC if the characteristic is not monotonic over the travel
/// (the parameters make the code saturate) or the fit fails.
md_status_t hall_init(hall_sensor_t *h, const hall_params_t *p, double travel_um, uint64_t seed, uint32_t electrode);
/// Noise-free, drift-free, unquantised code at depth z (the characteristic).
double hall_ideal_code(const hall_params_t *p, double depth_um);
/// One raw reading at true depth `depth_um` and time `t_s` (draws noise).
uint32_t hall_read(hall_sensor_t *h, double depth_um, double t_s);
/// The thermal drift term (codes) at time t_s.
double hall_drift_codes(const hall_params_t *p, double t_s);
/// Evaluates a calibration: code -> depth (um). Horner, O(degree).
double hall_cal_depth_um(const hall_calibration_t *cal, double code);

#endif
