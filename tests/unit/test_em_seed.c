/* Unit: em_seed — the three seeding cases of thesis §3.3.4 and the
 * middle-90 % rule of footnote 10. */
#include <math.h>
#include <string.h>

#include "cluster/em_seed.h"
#include "numeric/md_rng.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static double pts[400u * 2u];
static uint8_t lab[400u];
static uint8_t truth[400u];
static em_seed_work_t ws;

/* n points per centre, sd 0.5. */
static size_t blobs(const double (*c)[2], size_t k, size_t n, uint64_t s)
{
    md_rng_t rng;
    md_rng_seed(&rng, s);
    size_t m = 0u;
    for (size_t j = 0u; j < k; ++j) {
        for (size_t i = 0u; i < n; ++i, ++m) {
            pts[2u * m] = c[j][0] + 0.5 * md_rng_gauss(&rng);
            pts[2u * m + 1u] = c[j][1] + 0.5 * md_rng_gauss(&rng);
            truth[m] = (uint8_t)j;
        }
    }
    return m;
}

static void target(em_target_t *t, double x, double y)
{
    memset(t, 0, sizeof *t);
    t->mean[0] = x;
    t->mean[1] = y;
    t->s_cov[0] = t->s_cov[3] = 1.0;
    t->cluster_cov[0] = t->cluster_cov[3] = 0.25;
    t->p_detect = 0.9;
}

/* Seed groups equal the truth up to a renaming given by map[truth]. */
static void assert_partition(size_t n, const uint8_t *map)
{
    for (size_t i = 0u; i < n; ++i) {
        TEST_ASSERT_EQUAL_UINT(map[truth[i]], lab[i]);
    }
}

static const double c3[3][2] = {{-4.0, 0.0}, {4.0, 0.0}, {0.0, 6.0}};

static void test_equal_count_nearest_prior_cluster(void)
{
    const size_t n = blobs(c3, 3u, 30u, 1u);
    em_target_t tg[3];
    target(&tg[0], 0.2, 5.8); /* order differs from the data */
    target(&tg[1], -3.9, 0.1);
    target(&tg[2], 4.1, -0.2);
    const em_data_t d = {pts, n, 2u};
    TEST_ASSERT_EQUAL_INT(MD_OK, em_seed_from_targets(&d, tg, 3u, 3u, &ws, lab));
    const uint8_t map[3] = {1u, 2u, 0u};
    assert_partition(n, map);
}

static void test_fewer_keeps_best_subset(void)
{
    const double c2[2][2] = {{-4.0, 0.0}, {0.0, 6.0}};
    const size_t n = blobs(c2, 2u, 40u, 2u);
    em_target_t tg[3];
    target(&tg[0], -4.0, 0.0);
    target(&tg[1], 4.0, 0.0); /* went silent: no data near it */
    target(&tg[2], 0.0, 6.0);
    const em_data_t d = {pts, n, 2u};
    TEST_ASSERT_EQUAL_INT(MD_OK, em_seed_from_targets(&d, tg, 3u, 2u, &ws, lab));
    const uint8_t map[2] = {0u, 1u}; /* subset {0, 2}, ranks 0 and 1 */
    assert_partition(n, map);
    /* G = 1 of 3: the single best prior cluster takes everything */
    TEST_ASSERT_EQUAL_INT(MD_OK, em_seed_from_targets(&d, tg, 3u, 1u, &ws, lab));
    for (size_t i = 0u; i < n; ++i) {
        TEST_ASSERT_EQUAL_UINT(0u, lab[i]);
    }
}

static void test_more_splits_widest_at_largest_gap(void)
{
    /* one prior cluster; the data are two blobs along a diagonal (its
     * principal axis), plus a far outlier on the same line whose gap is the
     * largest but lies outside the middle 90 % */
    const double c2[2][2] = {{-3.0, -3.0}, {3.0, 3.0}};
    size_t n = blobs(c2, 2u, 40u, 3u);
    pts[2u * n] = 40.0;
    pts[2u * n + 1u] = 40.0;
    truth[n] = 1u;
    n++;
    em_target_t tg[1];
    target(&tg[0], 0.0, 0.0);
    tg[0].cluster_cov[0] = tg[0].cluster_cov[3] = 10.0;
    const em_data_t d = {pts, n, 2u};
    TEST_ASSERT_EQUAL_INT(MD_OK, em_seed_from_targets(&d, tg, 1u, 2u, &ws, lab));
    const uint8_t map[2] = {0u, 1u};
    assert_partition(n, map);
    /* no targets at all (first interval): the same split from one group */
    TEST_ASSERT_EQUAL_INT(MD_OK, em_seed_from_targets(&d, NULL, 0u, 2u, &ws, lab));
    assert_partition(n, map);
}

static void test_more_splits_the_widest_group(void)
{
    /* two prior clusters; the data of the second hold two blobs: the second
     * group is the widest and is the one split */
    const double c3b[3][2] = {{-6.0, 0.0}, {3.0, 0.0}, {7.0, 0.0}};
    const size_t n = blobs(c3b, 3u, 30u, 4u);
    em_target_t tg[2];
    target(&tg[0], -6.0, 0.0);
    target(&tg[1], 5.0, 0.0);
    tg[1].cluster_cov[0] = 5.0;
    const em_data_t d = {pts, n, 2u};
    TEST_ASSERT_EQUAL_INT(MD_OK, em_seed_from_targets(&d, tg, 2u, 3u, &ws, lab));
    uint8_t map[3];
    map[0] = 0u;
    map[1] = lab[30];
    map[2] = lab[60];
    TEST_ASSERT_TRUE((map[1] == 1u && map[2] == 2u) || (map[1] == 2u && map[2] == 1u));
    assert_partition(n, map);
}

static void test_degenerate_seeds(void)
{
    for (size_t i = 0u; i < 10u; ++i) {
        pts[2u * i] = 1.0;
        pts[2u * i + 1u] = 1.0;
    }
    const em_data_t d = {pts, 10u, 2u};
    TEST_ASSERT_EQUAL_INT(MD_E_DEGENERATE, em_seed_from_targets(&d, NULL, 0u, 2u, &ws, lab));
    const em_data_t tiny = {pts, 1u, 2u};
    TEST_ASSERT_EQUAL_INT(MD_E_DEGENERATE, em_seed_from_targets(&tiny, NULL, 0u, 2u, &ws, lab));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, em_seed_from_targets(&d, NULL, 0u, EM_G_MAX + 1u, &ws, lab));
    em_target_t bad;
    target(&bad, 0.0, 0.0);
    bad.cluster_cov[0] = -1.0;
    TEST_ASSERT_EQUAL_INT(MD_E_NUMERIC, em_seed_from_targets(&d, &bad, 1u, 1u, &ws, lab));
}

/* A point with no distance to the prior clusters is reported, not assigned to
 * the first of them; both the subset search (g < J) and the assignment. */
static void test_nonfinite_point_is_reported(void)
{
    const size_t n = blobs(c3, 3u, 10u, 3u);
    em_target_t tg[3];
    target(&tg[0], -4.0, 0.0);
    target(&tg[1], 4.0, 0.0);
    target(&tg[2], 0.0, 6.0);
    pts[2u * 7u + 1u] = NAN;
    const em_data_t d = {pts, n, 2u};
    TEST_ASSERT_EQUAL_INT(MD_E_NUMERIC, em_seed_from_targets(&d, tg, 3u, 3u, &ws, lab));
    TEST_ASSERT_EQUAL_INT(MD_E_NUMERIC, em_seed_from_targets(&d, tg, 3u, 2u, &ws, lab));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_equal_count_nearest_prior_cluster);
    RUN_TEST(test_fewer_keeps_best_subset);
    RUN_TEST(test_more_splits_widest_at_largest_gap);
    RUN_TEST(test_more_splits_the_widest_group);
    RUN_TEST(test_degenerate_seeds);
    RUN_TEST(test_nonfinite_point_is_reported);
    return UNITY_END();
}
