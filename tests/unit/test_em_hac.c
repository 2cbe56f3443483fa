/* Unit: em_hac — Ward's linkage by nearest-neighbour chain equals the greedy
 * (textbook) Ward agglomeration; a hand-computed 1-D example. */
#include <math.h>
#include <string.h>

#include "cluster/em_hac.h"
#include "numeric/md_rng.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static em_hac_work_t ws;
static double pts[64u * 2u];
static uint8_t lab[64u];

static void test_hand_example_1d(void)
{
    const double y[5] = {0.0, 1.0, 10.0, 11.0, 30.0};
    const em_data_t d = {y, 5u, 1u};
    TEST_ASSERT_EQUAL_INT(MD_OK, em_hac_ward(&d, &ws));
    /* Ward costs: {0,1} 0.5, {10,11} 0.5, {0,1}+{10,11} 100, + {30} 480 */
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 0.5, ws.merge_cost[0]);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 100.0, ws.merge_cost[2]);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 480.2, ws.merge_cost[3]);
    TEST_ASSERT_EQUAL_INT(MD_OK, em_hac_cut(&ws, 2u, lab));
    const uint8_t two[5] = {0u, 0u, 0u, 0u, 1u};
    TEST_ASSERT_EQUAL_MEMORY(two, lab, 5u);
    TEST_ASSERT_EQUAL_INT(MD_OK, em_hac_cut(&ws, 3u, lab));
    const uint8_t three[5] = {0u, 0u, 1u, 1u, 2u};
    TEST_ASSERT_EQUAL_MEMORY(three, lab, 5u);
    TEST_ASSERT_EQUAL_INT(MD_OK, em_hac_cut(&ws, 1u, lab));
    TEST_ASSERT_EQUAL_UINT(0u, lab[4]);
}

/* Greedy Ward: merge the cheapest pair each round (O(n^3), test only). */
static void greedy_ward(size_t n, size_t g, uint8_t *out)
{
    double c[64][2];
    double sz[64];
    size_t owner[64];
    for (size_t i = 0u; i < n; ++i) {
        c[i][0] = pts[2u * i];
        c[i][1] = pts[2u * i + 1u];
        sz[i] = 1.0;
        owner[i] = i;
    }
    for (size_t left = n; left > g; --left) {
        size_t ba = 0u;
        size_t bb = 0u;
        double best = INFINITY;
        for (size_t a = 0u; a < n; ++a) {
            for (size_t b = a + 1u; (sz[a] > 0.0) && (b < n); ++b) {
                if (sz[b] > 0.0) {
                    const double dx = c[a][0] - c[b][0];
                    const double dy = c[a][1] - c[b][1];
                    const double k = sz[a] * sz[b] / (sz[a] + sz[b]) * (dx * dx + dy * dy);
                    if (k < best) {
                        best = k;
                        ba = a;
                        bb = b;
                    }
                }
            }
        }
        for (size_t j = 0u; j < 2u; ++j) {
            c[ba][j] = (sz[ba] * c[ba][j] + sz[bb] * c[bb][j]) / (sz[ba] + sz[bb]);
        }
        sz[ba] += sz[bb];
        sz[bb] = 0.0;
        for (size_t i = 0u; i < n; ++i) {
            owner[i] = (owner[i] == bb) ? ba : owner[i];
        }
    }
    size_t roots[EM_G_MAX];
    size_t found = 0u;
    for (size_t i = 0u; i < n; ++i) {
        size_t k = 0u;
        while ((k < found) && (roots[k] != owner[i])) {
            k++;
        }
        if (k == found) {
            roots[found++] = owner[i];
        }
        out[i] = (uint8_t)k;
    }
}

static void test_matches_greedy_ward(void)
{
    md_rng_t rng;
    md_rng_seed(&rng, 7u);
    for (size_t trial = 0u; trial < 5u; ++trial) {
        const size_t n = 40u + 5u * trial;
        for (size_t i = 0u; i < 2u * n; ++i) {
            pts[i] = 3.0 * md_rng_gauss(&rng) + ((i % 6u) < 2u ? 8.0 : 0.0);
        }
        const em_data_t d = {pts, n, 2u};
        TEST_ASSERT_EQUAL_INT(MD_OK, em_hac_ward(&d, &ws));
        for (size_t g = 1u; g <= EM_G_MAX; ++g) {
            uint8_t ref[64];
            greedy_ward(n, g, ref);
            TEST_ASSERT_EQUAL_INT(MD_OK, em_hac_cut(&ws, g, lab));
            TEST_ASSERT_EQUAL_MEMORY(ref, lab, n);
        }
    }
}

static void test_bad_inputs(void)
{
    const double y[2] = {0.0, NAN};
    const em_data_t d = {y, 2u, 1u};
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, em_hac_ward(&d, &ws));
    const double one[1] = {1.0};
    const em_data_t d1 = {one, 1u, 1u};
    TEST_ASSERT_EQUAL_INT(MD_OK, em_hac_ward(&d1, &ws));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, em_hac_cut(&ws, 2u, lab));
    TEST_ASSERT_EQUAL_INT(MD_OK, em_hac_cut(&ws, 1u, lab));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_hand_example_1d);
    RUN_TEST(test_matches_greedy_ward);
    RUN_TEST(test_bad_inputs);
    return UNITY_END();
}
