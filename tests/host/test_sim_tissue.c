/* Host unit: tissue motion — slow drift, decompression after insertion and
 * after movements (exponential), advance/retract hysteresis, micro-motion. */
#include <math.h>

#include "model/tissue.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static tissue_t t;

static tissue_params_t quiet(void)
{
    tissue_params_t p;
    tissue_default_params(&p);
    p.drift_um_per_min = 0.0;
    p.insert_relax_um = 0.0;
    return p;
}

static void test_slow_drift_um_per_min(void)
{
    tissue_params_t p = quiet();
    p.drift_um_per_min = 0.5;
    p.drift_start_s = 60.0;
    TEST_ASSERT_EQUAL_INT(MD_OK, tissue_init(&t, &p));
    tissue_advance_to(&t, 60.0, 0.0);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 0.0, tissue_displacement_um(&t));
    tissue_advance_to(&t, 660.0, 0.0);
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 5.0, tissue_displacement_um(&t)); /* 10 min * 0.5 um/min */
}

static void test_decompression_after_insertion(void)
{
    tissue_params_t p = quiet();
    p.insert_relax_um = 40.0;
    p.insert_tau_s = 1800.0;
    TEST_ASSERT_EQUAL_INT(MD_OK, tissue_init(&t, &p));
    tissue_advance_to(&t, 1800.0, 0.0);
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, -40.0 * (1.0 - exp(-1.0)), tissue_displacement_um(&t));
    tissue_advance_to(&t, 30000.0, 0.0);
    TEST_ASSERT_DOUBLE_WITHIN(0.01, -40.0, tissue_displacement_um(&t));
}

/* A 100 um advance drags the tissue 30 um; 80 % of it relaxes with tau. */
static void test_relaxation_after_movement(void)
{
    tissue_params_t p = quiet();
    TEST_ASSERT_EQUAL_INT(MD_OK, tissue_init(&t, &p));
    tissue_advance_to(&t, 10.0, 100.0);
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 30.0, tissue_displacement_um(&t));
    tissue_advance_to(&t, 10.0 + p.move_tau_s, 0.0);
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 6.0 + 24.0 * exp(-1.0), tissue_displacement_um(&t));
    tissue_advance_to(&t, 10.0 + 20.0 * p.move_tau_s, 0.0);
    TEST_ASSERT_DOUBLE_WITHIN(1e-6, 6.0, tissue_displacement_um(&t));
}

/* Advance then retract by the same distance: the tissue does not come back
 * to where it was (different drag in the two directions). */
static void test_hysteresis_between_advance_and_retract(void)
{
    tissue_params_t p = quiet();
    TEST_ASSERT_EQUAL_INT(MD_OK, tissue_init(&t, &p));
    tissue_advance_to(&t, 1.0, 50.0);
    tissue_advance_to(&t, 2.0, -50.0);
    tissue_advance_to(&t, 5000.0, 0.0);
    const double residual = tissue_displacement_um(&t);
    TEST_ASSERT_DOUBLE_WITHIN(1e-6, 0.2 * (0.30 - 0.15) * 50.0, residual);
    TEST_ASSERT_TRUE(residual > 1.0);
}

static void test_relaxing_part_is_bounded(void)
{
    tissue_params_t p = quiet();
    TEST_ASSERT_EQUAL_INT(MD_OK, tissue_init(&t, &p));
    tissue_advance_to(&t, 1.0, 1000.0);
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 60.0, t.relax_um);
}

static void test_breathing_and_heartbeat(void)
{
    tissue_params_t p = quiet();
    p.breathing_um = 2.0;
    p.breathing_hz = 0.25;
    p.heartbeat_um = 0.5;
    p.heartbeat_hz = 1.0;
    TEST_ASSERT_EQUAL_INT(MD_OK, tissue_init(&t, &p));
    tissue_advance_to(&t, 1.0, 0.0); /* breathing at its crest, heartbeat at a zero */
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 2.0, tissue_displacement_um(&t));
    tissue_advance_to(&t, 1.25, 0.0);
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 2.0 * sin(2.0 * 3.141592653589793 * 0.3125) + 0.5, tissue_displacement_um(&t));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_slow_drift_um_per_min);
    RUN_TEST(test_decompression_after_insertion);
    RUN_TEST(test_relaxation_after_movement);
    RUN_TEST(test_hysteresis_between_advance_and_retract);
    RUN_TEST(test_relaxing_part_is_bounded);
    RUN_TEST(test_breathing_and_heartbeat);
    return UNITY_END();
}
