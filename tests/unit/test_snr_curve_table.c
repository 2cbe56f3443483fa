/* Unit: per-track SNR-curve table (beyond the thesis, its §6.2): one curve per
 * MHTC track ID, SC_TABLE_SLOTS per electrode, least-recently-observed
 * eviction, reset of one track's curve, error counting. */
#include <math.h>
#include <string.h>

#include "control/snr_curve.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static sc_config_t cfg;
static sc_table_t table;

static void fresh(void)
{
    sc_config_default(&cfg);
    (void)memset(&table, 0xA5, sizeof table); /* init must not rely on zeroed storage */
    sc_table_init(&table);
}

static void observe(uint32_t id, double u, double r)
{
    TEST_ASSERT_EQUAL_INT(MD_OK, sc_table_observe(&table, &cfg, id, u, r, NULL));
}

static void test_init_is_empty(void)
{
    fresh();
    TEST_ASSERT_NULL(sc_table_find(&table, 0u));
    TEST_ASSERT_NULL(sc_table_find(&table, 7u));
    TEST_ASSERT_EQUAL_UINT32(0u, table.evictions);
    TEST_ASSERT_EQUAL_UINT32(0u, table.errors);
    TEST_ASSERT_EQUAL_UINT32(0u, table.clock);
}

/* Observations of different tracks land in different curves and never mix. */
static void test_curves_are_kept_per_track(void)
{
    fresh();
    for (size_t i = 0u; i < 6u; ++i) {
        const double u = 10.0 * (double)i;
        observe(11u, u, 2.0 + 0.1 * u); /* rising */
        observe(42u, u, 8.0 - 0.1 * u); /* falling */
    }
    sc_curve_t *a = sc_table_find(&table, 11u);
    sc_curve_t *b = sc_table_find(&table, 42u);
    TEST_ASSERT_NOT_NULL(a);
    TEST_ASSERT_NOT_NULL(b);
    TEST_ASSERT_TRUE(a != b);
    TEST_ASSERT_EQUAL_UINT(6u, a->count);
    TEST_ASSERT_EQUAL_UINT(6u, b->count);
    sc_suggestion_t sa;
    sc_suggestion_t sb;
    TEST_ASSERT_EQUAL_INT(MD_OK, sc_curve_suggest(a, &cfg, 50.0, 1, &sa));
    TEST_ASSERT_EQUAL_INT(MD_OK, sc_curve_suggest(b, &cfg, 50.0, 1, &sb));
    TEST_ASSERT_GREATER_THAN_DOUBLE(0.0, sa.move_um);
    TEST_ASSERT_LESS_THAN_DOUBLE(0.0, sb.move_um);
    sc_curve_t *out = NULL;
    TEST_ASSERT_EQUAL_INT(MD_OK, sc_table_observe(&table, &cfg, 11u, 60.0, 8.0, &out));
    TEST_ASSERT_TRUE(out == a);
    TEST_ASSERT_EQUAL_UINT(7u, a->count);
}

/* A full table evicts the track observed least recently — not the oldest
 * created, not the one with fewest points. */
static void test_eviction_is_least_recently_observed(void)
{
    fresh();
    for (uint32_t id = 1u; id <= SC_TABLE_SLOTS; ++id) {
        observe(id, 0.0, 1.0);
    }
    /* refresh every track but #2, #1 last of all */
    for (uint32_t id = SC_TABLE_SLOTS; id >= 3u; --id) {
        observe(id, 10.0, 2.0);
    }
    observe(1u, 10.0, 2.0);
    TEST_ASSERT_EQUAL_UINT32(0u, table.evictions);
    observe(100u, 20.0, 3.0);
    TEST_ASSERT_EQUAL_UINT32(1u, table.evictions);
    TEST_ASSERT_NULL(sc_table_find(&table, 2u));
    sc_curve_t *c = sc_table_find(&table, 100u);
    TEST_ASSERT_NOT_NULL(c);
    TEST_ASSERT_EQUAL_UINT(1u, c->count); /* the reused slot starts empty */
    TEST_ASSERT_FALSE(c->posterior_valid);
    for (uint32_t id = 1u; id <= SC_TABLE_SLOTS; ++id) {
        if (id != 2u) {
            TEST_ASSERT_NOT_NULL(sc_table_find(&table, id));
        }
    }
    /* next victim: the least recently observed among the rest (#SC_TABLE_SLOTS
     * was refreshed first above) */
    observe(101u, 20.0, 3.0);
    TEST_ASSERT_EQUAL_UINT32(2u, table.evictions);
    TEST_ASSERT_NULL(sc_table_find(&table, SC_TABLE_SLOTS));
    TEST_ASSERT_NOT_NULL(sc_table_find(&table, 1u));
    TEST_ASSERT_NOT_NULL(sc_table_find(&table, 100u));
    /* an evicted track that comes back starts a fresh curve */
    observe(2u, 30.0, 4.0);
    c = sc_table_find(&table, 2u);
    TEST_ASSERT_NOT_NULL(c);
    TEST_ASSERT_EQUAL_UINT(1u, c->count);
}

static void test_reset_track_restarts_only_that_curve(void)
{
    fresh();
    for (size_t i = 0u; i < 5u; ++i) {
        observe(5u, 10.0 * (double)i, 3.0 + (double)i);
        observe(6u, 10.0 * (double)i, 3.0);
    }
    TEST_ASSERT_EQUAL_INT(MD_OK, sc_table_reset_track(&table, 5u));
    TEST_ASSERT_EQUAL_UINT(0u, sc_table_find(&table, 5u)->count);
    TEST_ASSERT_FALSE(sc_table_find(&table, 5u)->posterior_valid);
    TEST_ASSERT_DOUBLE_WITHIN(1e-15, 1.0 / (double)SC_M_MAX, sc_table_find(&table, 5u)->post[0]);
    TEST_ASSERT_EQUAL_UINT(5u, sc_table_find(&table, 6u)->count);
    TEST_ASSERT_EQUAL_INT(MD_E_STATE, sc_table_reset_track(&table, 99u));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, sc_table_reset_track(NULL, 5u));
}

static void test_bad_observations_are_counted_and_change_nothing(void)
{
    fresh();
    observe(3u, 0.0, 1.0);
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, sc_table_observe(&table, &cfg, 3u, NAN, 1.0, NULL));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, sc_table_observe(&table, &cfg, 4u, 1.0, -INFINITY, NULL));
    sc_config_t bad = cfg;
    bad.k0 = 0u;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, sc_table_observe(&table, &bad, 3u, 1.0, 1.0, NULL));
    TEST_ASSERT_EQUAL_UINT32(3u, table.errors);
    TEST_ASSERT_EQUAL_UINT(1u, sc_table_find(&table, 3u)->count);
    TEST_ASSERT_NULL(sc_table_find(&table, 4u));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, sc_table_observe(NULL, &cfg, 3u, 1.0, 1.0, NULL));
    TEST_ASSERT_NULL(sc_table_find(NULL, 3u));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_init_is_empty);
    RUN_TEST(test_curves_are_kept_per_track);
    RUN_TEST(test_eviction_is_least_recently_observed);
    RUN_TEST(test_reset_track_restarts_only_that_curve);
    RUN_TEST(test_bad_observations_are_counted_and_change_nothing);
    return UNITY_END();
}
