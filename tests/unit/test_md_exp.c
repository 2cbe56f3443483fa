/* Unit: md_exp — against the C library's exp across the whole range, at the
 * table nodes and the boundaries of the documented range. */
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "numeric/md_exp.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

/* Distance in units in the last place between two positive finite doubles. */
static double ulps(double a, double b)
{
    uint64_t ia = 0u;
    uint64_t ib = 0u;
    memcpy(&ia, &a, sizeof ia);
    memcpy(&ib, &b, sizeof ib);
    return (ia > ib) ? (double)(ia - ib) : (double)(ib - ia);
}

static uint64_t g_state = 0x243F6A8885A308D3ull;
static double uniform(double lo, double hi)
{
    g_state = g_state * 6364136223846793005ull + 1442695040888963407ull;
    return lo + (hi - lo) * ((double)(g_state >> 11) / 9007199254740992.0);
}

static void test_matches_libm_within_one_ulp(void)
{
    double worst = 0.0;
    for (unsigned i = 0u; i < 200000u; ++i) {
        /* the E-step's range [-60, 0] densely, the rest of the normal range too */
        const double x = (i % 4u == 0u) ? uniform(MD_EXP_X_MIN, MD_EXP_X_MAX) : uniform(-60.0, 0.0);
        worst = fmax(worst, ulps(md_exp(x), exp(x)));
    }
    TEST_ASSERT_TRUE(worst <= 1.0);
}

static void test_exact_at_table_nodes(void)
{
    /* x = k·ln2 exactly representable multiples give powers of two to rounding */
    for (int k = -1000; k <= 1000; k += 7) {
        const double x = (double)k * 0.693147180559945309417;
        TEST_ASSERT_TRUE(ulps(md_exp(x), exp(x)) <= 1.0);
    }
    TEST_ASSERT_TRUE(ulps(md_exp(0.0), 1.0) <= 0.0);
    TEST_ASSERT_TRUE(ulps(md_exp(-0.0), 1.0) <= 0.0);
}

static void test_range_ends_and_nan(void)
{
    TEST_ASSERT_TRUE(md_exp(MD_EXP_X_MIN) >= DBL_MIN);
    TEST_ASSERT_TRUE(ulps(md_exp(MD_EXP_X_MIN), exp(MD_EXP_X_MIN)) <= 1.0);
    TEST_ASSERT_TRUE(ulps(md_exp(-708.4), 0.0) <= 0.0);
    TEST_ASSERT_TRUE(ulps(md_exp(-1e300), 0.0) <= 0.0);
    TEST_ASSERT_TRUE(ulps(md_exp(-HUGE_VAL), 0.0) <= 0.0);
    TEST_ASSERT_TRUE(ulps(md_exp(MD_EXP_X_MAX), exp(MD_EXP_X_MAX)) <= 1.0);
    TEST_ASSERT_TRUE(isinf(md_exp(709.78)));
    TEST_ASSERT_TRUE(isinf(md_exp(710.0)));
    TEST_ASSERT_TRUE(isinf(md_exp(HUGE_VAL)));
    TEST_ASSERT_TRUE(isnan(md_exp(NAN)));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_matches_libm_within_one_ulp);
    RUN_TEST(test_exact_at_table_nodes);
    RUN_TEST(test_range_ends_and_nan);
    return UNITY_END();
}
