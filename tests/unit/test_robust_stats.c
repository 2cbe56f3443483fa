/* Unit: robust_stats — histogram order statistics equal sorting. */

#include "numeric/md_rng.h"
#include "signal/robust_stats.h"
#include "unity.h"

#define N 2001u

static int16_t g_x[N];
static uint32_t g_sorted[N];
static rs_hist_t g_h;

void setUp(void) {}
void tearDown(void) {}

/* insertion sort of |x - off| (test oracle; N is small) */
static void sort_abs(size_t n, int32_t off)
{
    for (size_t i = 0u; i < n; ++i) {
        const int32_t d = (int32_t)g_x[i] - off;
        const uint32_t v = (uint32_t)((d < 0) ? -d : d);
        size_t j = i;
        while ((j > 0u) && (g_sorted[j - 1u] > v)) {
            g_sorted[j] = g_sorted[j - 1u];
            --j;
        }
        g_sorted[j] = v;
    }
}

static void test_kth_equals_sorted_over_full_int16_range(void)
{
    md_rng_t rng;
    md_rng_seed(&rng, 3u);
    for (size_t i = 0u; i < N; ++i) { /* wide values incl. the extremes */
        g_x[i] = (int16_t)((int32_t)md_rng_below(&rng, 65536u) - 32768);
    }
    g_x[0] = -32768;
    g_x[1] = 32767;
    const int32_t offsets[3] = {0, 32767, -32768};
    for (size_t o = 0u; o < 3u; ++o) {
        sort_abs(N, offsets[o]);
        const size_t ks[5] = {0u, 1u, N / 2u, N - 2u, N - 1u};
        for (size_t k = 0u; k < 5u; ++k) {
            TEST_ASSERT_EQUAL_UINT32(g_sorted[ks[k]], rs_abs_kth_i16(g_x, N, offsets[o], ks[k], &g_h));
        }
    }
}

static void test_median_even_and_odd(void)
{
    const int16_t x[6] = {-5, 3, 1, -1, 10, 2}; /* |x| sorted: 1 1 2 3 5 10 */
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 2.5, rs_abs_median_i16(x, 6u, 0, &g_h));
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 3.0, rs_abs_median_i16(x, 5u, 0, &g_h)); /* 1 1 3 5 10 */
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.0, rs_abs_median_i16(x, 0u, 0, &g_h));
}

static void test_histogram_rank_value(void)
{
    const uint32_t h[4] = {0, 4, 0, 2}; /* width 0.5: 4 values in [0.5,1), 2 in [1.5,2) */
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 0.5 + 0.5 * 0.5 / 4.0, rs_hist_rank_value(h, 4u, 0.5, 6u, 0u));
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 1.5 + 0.5 * 1.5 / 2.0, rs_hist_rank_value(h, 4u, 0.5, 6u, 5u));
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.0, rs_hist_rank_value(h, 4u, 0.5, 6u, 6u));
}

static void test_rng_is_deterministic_and_uniform(void)
{
    md_rng_t a, b;
    md_rng_seed(&a, 42u);
    md_rng_seed(&b, 42u);
    unsigned counts[10] = {0};
    double sum = 0.0, sum2 = 0.0;
    for (unsigned i = 0u; i < 100u; ++i) {
        TEST_ASSERT_TRUE(md_rng_next_u64(&a) == md_rng_next_u64(&b));
    }
    for (unsigned i = 0u; i < 20000u; ++i) {
        counts[md_rng_below(&a, 10u)]++;
        const double g = md_rng_gauss(&a);
        sum += g;
        sum2 += g * g;
    }
    for (unsigned k = 0u; k < 10u; ++k) { /* expected 2000, sd ~42 */
        TEST_ASSERT_DOUBLE_WITHIN(200.0, 2000.0, (double)counts[k]);
    }
    TEST_ASSERT_DOUBLE_WITHIN(0.05, 0.0, sum / 20000.0);
    TEST_ASSERT_DOUBLE_WITHIN(0.05, 1.0, sum2 / 20000.0);
    TEST_ASSERT_EQUAL_UINT32(0u, md_rng_below(&a, 0u));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_kth_equals_sorted_over_full_int16_range);
    RUN_TEST(test_median_even_and_odd);
    RUN_TEST(test_histogram_rank_value);
    RUN_TEST(test_rng_is_deterministic_and_uniform);
    return UNITY_END();
}
