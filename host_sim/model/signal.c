#include "model/signal.h"

#include <math.h>
#include <stdbool.h>
#include <string.h>

#define PI 3.141592653589793

void signal_default_params(signal_params_t *p)
{
    p->sample_rate_hz = 30000.0;
    p->adc_gain_uv = 0.195;
    p->noise_uv = 6.0;
    p->band_low_hz = 300.0;
    p->band_high_hz = 6000.0;
    p->mua_rate_hz = 400.0;
    p->mua_amp_uv = 15.0;
    p->motion_artifact_uv = 150.0;
    p->motion_artifact_tau_s = 0.05;
    p->motion_artifact_hz = 700.0;
    p->large_artifact_rate_hz = 0.02;
    p->large_artifact_uv = 800.0;
}

md_status_t signal_params_check(const signal_params_t *p)
{
    const bool ok = p->sample_rate_hz >= 20000.0 && p->sample_rate_hz <= 50000.0 && p->adc_gain_uv > 0.0 &&
                    p->noise_uv >= 0.0 && p->band_low_hz > 0.0 && p->band_high_hz > p->band_low_hz &&
                    p->band_high_hz < 0.45 * p->sample_rate_hz && p->mua_rate_hz >= 0.0 && p->mua_amp_uv >= 0.0 &&
                    p->motion_artifact_uv >= 0.0 && p->motion_artifact_tau_s > 0.0 && p->motion_artifact_hz > 0.0 &&
                    p->large_artifact_rate_hz >= 0.0 && p->large_artifact_uv >= 0.0;
    return ok ? MD_OK : MD_E_ARG;
}

void sim_noise_filter_init(sim_noise_filter_t *f, const signal_params_t *p)
{
    memset(f, 0, sizeof *f);
    const double fs = p->sample_rate_hz;
    /* 1st-order high-pass, bilinear: y = a (y1 + x - x1) */
    const double rc = 1.0 / (2.0 * PI * p->band_low_hz);
    f->hp_a = rc / (rc + 1.0 / fs);
    /* 2nd-order Butterworth low-pass, bilinear with pre-warping */
    const double k = tan(PI * p->band_high_hz / fs);
    const double q = 1.0 / sqrt(2.0);
    const double norm = 1.0 / (1.0 + k / q + k * k);
    f->b0 = k * k * norm;
    f->b1 = 2.0 * f->b0;
    f->b2 = f->b0;
    f->a1 = 2.0 * (k * k - 1.0) * norm;
    f->a2 = (1.0 - k / q + k * k) * norm;
    /* output variance for unit white input = energy of the impulse response */
    f->in_scale = 1.0;
    double e = 0.0;
    const uint32_t n = (uint32_t)fs;
    for (uint32_t i = 0u; i < n; ++i) {
        const double y = sim_noise_filter_step(f, (i == 0u) ? 1.0 : 0.0);
        e += y * y;
    }
    f->hp_x1 = f->hp_y1 = f->z1 = f->z2 = 0.0;
    f->in_scale = (e > 0.0) ? p->noise_uv / sqrt(e) : 0.0;
}

uint32_t sim_mua_template(double fs, double *out, double *energy)
{
    /* a generic distant spike: trough sigma 0.12 ms, repolarisation 0.3 ms,
     * lobes of equal area (0.4 * 0.3 = 0.12) as after the front-end's
     * high-pass, so that MUA adds no DC */
    const uint32_t len = (uint32_t)floor(1.6e-3 * fs);
    const uint32_t pre = len / 4u;
    double lo = 0.0, hi = 0.0;
    for (uint32_t i = 0u; i < len && i < SIM_SHORT_WAVE_MAX; ++i) {
        const double u = ((double)i - (double)pre) * 1000.0 / fs;
        out[i] = -exp(-0.5 * (u / 0.12) * (u / 0.12)) + 0.4 * exp(-0.5 * ((u - 0.45) / 0.3) * ((u - 0.45) / 0.3));
        lo = fmin(lo, out[i]);
        hi = fmax(hi, out[i]);
    }
    double e = 0.0;
    for (uint32_t i = 0u; i < len && i < SIM_SHORT_WAVE_MAX; ++i) {
        out[i] /= (hi - lo);
        e += out[i] * out[i];
    }
    *energy = e;
    return (len < SIM_SHORT_WAVE_MAX) ? len : SIM_SHORT_WAVE_MAX;
}

uint32_t sim_artifact_template(double fs, double *out)
{
    const uint32_t len = (uint32_t)floor(0.8e-3 * fs);
    const uint32_t pre = len / 4u;
    double lo = 0.0, hi = 0.0;
    for (uint32_t i = 0u; i < len && i < SIM_SHORT_WAVE_MAX; ++i) {
        const double u = ((double)i - (double)pre) * 1000.0 / fs;
        out[i] = exp(-0.5 * (u / 0.05) * (u / 0.05)) - 0.9 * exp(-0.5 * ((u - 0.12) / 0.05) * ((u - 0.12) / 0.05));
        lo = fmin(lo, out[i]);
        hi = fmax(hi, out[i]);
    }
    for (uint32_t i = 0u; i < len && i < SIM_SHORT_WAVE_MAX; ++i) {
        out[i] /= (hi - lo);
    }
    return (len < SIM_SHORT_WAVE_MAX) ? len : SIM_SHORT_WAVE_MAX;
}

double sim_background_rms_uv(const signal_params_t *p)
{
    double tmpl[SIM_SHORT_WAVE_MAX];
    double energy = 0.0;
    (void)sim_mua_template(p->sample_rate_hz, tmpl, &energy);
    /* Campbell's theorem: var = (rate / fs) * E[a^2] * sum h^2, a ~ U[0.5,1.5] * mua_amp */
    const double ea2 = p->mua_amp_uv * p->mua_amp_uv * (13.0 / 12.0);
    const double mua_var = p->mua_rate_hz / p->sample_rate_hz * ea2 * energy;
    return sqrt(p->noise_uv * p->noise_uv + mua_var);
}
