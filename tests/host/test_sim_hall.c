/* Host unit: Hall sensor model — non-linear characteristic, sub-micron noise,
 * quantisation, thermal drift, and the calibration handed to the controller. */
#include <math.h>

#include "model/hall_sensor.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static hall_sensor_t h;

static void test_characteristic_is_nonlinear_and_monotonic(void)
{
    hall_params_t p;
    hall_default_params(&p);
    const double slope_mid = hall_ideal_code(&p, 2801.0) - hall_ideal_code(&p, 2800.0);
    const double slope_end = hall_ideal_code(&p, 5600.0) - hall_ideal_code(&p, 5599.0);
    TEST_ASSERT_TRUE(slope_end > 0.0);
    TEST_ASSERT_TRUE(slope_end < 0.6 * slope_mid); /* clearly non-linear */
    for (double z = 0.0; z < 5600.0; z += 7.0) {
        TEST_ASSERT_TRUE(hall_ideal_code(&p, z + 7.0) > hall_ideal_code(&p, z));
    }
}

static void test_calibration_fit_error_is_small(void)
{
    hall_params_t p;
    hall_default_params(&p);
    TEST_ASSERT_EQUAL_INT(MD_OK, hall_init(&h, &p, 5600.0, 1u, 0u));
    TEST_ASSERT_TRUE(h.cal.max_fit_error_um < 0.5);
    TEST_ASSERT_EQUAL_UINT32(9u, h.cal.degree);
}

/* Calibrated depth of averaged raw readings within 1 um over the travel. */
static void test_calibrated_depth_within_tolerance(void)
{
    hall_params_t p;
    hall_default_params(&p);
    TEST_ASSERT_EQUAL_INT(MD_OK, hall_init(&h, &p, 5600.0, 2u, 0u));
    for (double z = 50.0; z <= 5550.0; z += 250.0) {
        double acc = 0.0;
        for (int i = 0; i < 64; ++i) {
            acc += hall_cal_depth_um(&h.cal, (double)hall_read(&h, z, 0.0));
        }
        TEST_ASSERT_DOUBLE_WITHIN(1.0, z, acc / 64.0);
    }
}

/* Noise of single readings, in depth, is sub-micron (sd < 1 um) but present. */
static void test_noise_is_sub_micron(void)
{
    hall_params_t p;
    hall_default_params(&p);
    TEST_ASSERT_EQUAL_INT(MD_OK, hall_init(&h, &p, 5600.0, 3u, 0u));
    const double zs[3] = {100.0, 2800.0, 5500.0};
    for (int k = 0; k < 3; ++k) {
        double s = 0.0, s2 = 0.0;
        const int n = 4000;
        for (int i = 0; i < n; ++i) {
            const double d = hall_cal_depth_um(&h.cal, (double)hall_read(&h, zs[k], 0.0));
            s += d;
            s2 += d * d;
        }
        const double sd = sqrt(s2 / n - (s / n) * (s / n));
        TEST_ASSERT_TRUE(sd < 1.0);
        TEST_ASSERT_TRUE(sd > 0.05);
    }
}

static void test_quantisation_without_noise(void)
{
    hall_params_t p;
    hall_default_params(&p);
    p.noise_codes = 0.0;
    p.drift_codes_per_hour = 0.0;
    p.drift_amp_codes = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_OK, hall_init(&h, &p, 5600.0, 4u, 0u));
    const double z = 1234.567;
    const uint32_t c = hall_read(&h, z, 0.0);
    TEST_ASSERT_EQUAL_UINT32((uint32_t)floor(hall_ideal_code(&p, z) + 0.5), c);
    TEST_ASSERT_EQUAL_UINT32(c, hall_read(&h, z, 100.0));
    /* one code step is worth ~0.1 um in the middle of the travel */
    TEST_ASSERT_TRUE(fabs(hall_cal_depth_um(&h.cal, (double)c) - z) < 0.3);
}

/* Slow thermal drift: after an hour the reading has moved by the configured
 * creep (+ the sinusoid, which is back to zero after two periods). */
static void test_thermal_drift(void)
{
    hall_params_t p;
    hall_default_params(&p);
    p.noise_codes = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_OK, hall_init(&h, &p, 5600.0, 5u, 0u));
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 2.0, hall_drift_codes(&p, 3600.0));
    const int c0 = (int)hall_read(&h, 2800.0, 0.0);
    const int c1 = (int)hall_read(&h, 2800.0, 3600.0);
    TEST_ASSERT_EQUAL_INT(2, c1 - c0);
    const int cq = (int)hall_read(&h, 2800.0, 450.0); /* a quarter period: + amplitude */
    TEST_ASSERT_EQUAL_INT(3, cq - c0);
}

static void test_saturating_parameters_are_rejected(void)
{
    hall_params_t p;
    hall_default_params(&p);
    p.amplitude_codes = 60000.0;
    TEST_ASSERT_EQUAL_INT(MD_E_NUMERIC, hall_init(&h, &p, 5600.0, 1u, 0u));
    hall_default_params(&p);
    p.cal_degree = 0u;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, hall_init(&h, &p, 5600.0, 1u, 0u));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_characteristic_is_nonlinear_and_monotonic);
    RUN_TEST(test_calibration_fit_error_is_small);
    RUN_TEST(test_calibrated_depth_within_tolerance);
    RUN_TEST(test_noise_is_sub_micron);
    RUN_TEST(test_quantisation_without_noise);
    RUN_TEST(test_thermal_drift);
    RUN_TEST(test_saturating_parameters_are_rejected);
    return UNITY_END();
}
