/// @file signal.h
/// Parameters and building blocks of the recorded signal (band-limited
/// background noise, distant multi-unit activity, artifacts, the ADC).
///
/// Background = thermal white noise through a 1st-order high-pass at
/// band_low_hz and a 2nd-order Butterworth low-pass at band_high_hz (bilinear
/// transform), scaled so its RMS is exactly noise_uv; plus distant multi-unit
/// activity (MUA): Poisson events at mua_rate_hz, each a generic small spike
/// of ptp uniform in [0.5, 1.5] * mua_amp_uv. Artifacts: after every actuator
/// motion a decaying ringing A e^{-t/tau} sin(2 pi f t) (motion_artifact_*),
/// and rare large fast bipolar transients at large_artifact_rate_hz (ptp
/// uniform in [0.6, 1.4] * large_artifact_uv) that a spike detector will take
/// for spikes (ground truth marks them neuron_id -1). The ADC is 16-bit,
/// adc_gain_uv per LSB, rounding, saturating.
#ifndef SIM_SIGNAL_H
#define SIM_SIGNAL_H

#include <stdint.h>

#include "md_status.h"
#include "model/sim_rng.h"

#define SIM_SHORT_WAVE_MAX 96u  ///< MUA / artifact template samples, at most

typedef struct {
    double sample_rate_hz;          ///< default 30000 (20000..50000)
    double adc_gain_uv;             ///< uV per LSB, default 0.195 (16-bit, +-6.4 mV)
    double noise_uv;                ///< band-limited thermal RMS, default 6 uV
    double band_low_hz;             ///< default 300 Hz
    double band_high_hz;            ///< default 6000 Hz
    double mua_rate_hz;             ///< distant-unit events, default 400 Hz
    double mua_amp_uv;              ///< their mean ptp, default 15 uV
    double motion_artifact_uv;      ///< ringing amplitude after motion, default 150 uV
    double motion_artifact_tau_s;   ///< its decay, default 0.05 s
    double motion_artifact_hz;      ///< its frequency, default 700 Hz
    double large_artifact_rate_hz;  ///< default 0.02 Hz
    double large_artifact_uv;       ///< default 800 uV ptp
} signal_params_t;

/// Band-limiting filter state (HP1 then biquad LP).
typedef struct {
    double hp_a, hp_x1, hp_y1;
    double b0, b1, b2, a1, a2, z1, z2;
    double in_scale;  ///< white sigma that yields noise_uv at the output
} sim_noise_filter_t;

void signal_default_params(signal_params_t *p);
md_status_t signal_params_check(const signal_params_t *p);
/// Designs the filter and its input scale. O(fs) once (impulse-response energy).
void sim_noise_filter_init(sim_noise_filter_t *f, const signal_params_t *p);
/// One filtered sample from one white N(0,1) input.
static inline double sim_noise_filter_step(sim_noise_filter_t *f, double white)
{
    const double x = white * f->in_scale;
    const double hp = f->hp_a * (f->hp_y1 + x - f->hp_x1);
    f->hp_x1 = x;
    f->hp_y1 = hp;
    const double y = f->b0 * hp + f->z1; /* transposed direct form II */
    f->z1 = f->b1 * hp - f->a1 * y + f->z2;
    f->z2 = f->b2 * hp - f->a2 * y;
    return y;
}
/// Unit-ptp MUA template; returns its length. Also sum of squares in *energy.
uint32_t sim_mua_template(double fs, double *out, double *energy);
/// Unit-ptp large-artifact template; returns its length.
uint32_t sim_artifact_template(double fs, double *out);
/// RMS of the whole background (thermal + MUA), analytic (shot-noise variance).
double sim_background_rms_uv(const signal_params_t *p);

#endif
