/// Unit tests of the parameter table (md_params): table invariants, defaults,
/// and every rule of a set. Bus-level parameter access is tested in test_node.c.
#include <math.h>
#include <string.h>

#include "md_params.h"
#include "unity.h"

static md_params_t P;

void setUp(void)
{
    TEST_ASSERT_EQUAL_INT(MD_OK, md_params_init(&P));
}
void tearDown(void) {}

static uint16_t index_of(md_param_id_t id)
{
    return md_params_def((size_t)id)->index;
}

static void test_table_is_consistent(void)
{
    TEST_ASSERT_EQUAL_INT(MD_OK, md_params_table_check());
    TEST_ASSERT_EQUAL_size_t((size_t)MD_P_COUNT, md_params_count());
    TEST_ASSERT_NULL(md_params_def(md_params_count()));
    for (size_t i = 0u; i < md_params_count(); ++i) {
        const md_param_def_t *d = md_params_def(i);
        TEST_ASSERT_NOT_NULL(d);
        TEST_ASSERT_EQUAL_INT((int)i, md_params_find(d->index));
        TEST_ASSERT_TRUE(strlen(d->name) > 0u);
        for (size_t j = 0u; j < i; ++j) {
            TEST_ASSERT_TRUE_MESSAGE(strcmp(md_params_def(j)->name, d->name) != 0, "names are unique");
        }
        if ((d->flags & MD_PARAM_F_LIVE) != 0u) {
            TEST_ASSERT_TRUE((d->flags & MD_PARAM_F_READ_ONLY) != 0u);
        }
    }
    TEST_ASSERT_EQUAL_INT(-1, md_params_find(0x0000u));
    TEST_ASSERT_EQUAL_INT(-1, md_params_find(0xFFFFu));
}

static void test_required_rows_exist_with_defaults(void)
{
    TEST_ASSERT_EQUAL_INT(MD_P_HEARTBEAT_PERIOD_MS, md_params_find(0x1017u));
    TEST_ASSERT_EQUAL_INT(MD_P_HEARTBEAT_TIMEOUT_MS, md_params_find(0x1016u));
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 100.0, md_params_get(&P, MD_P_HEARTBEAT_PERIOD_MS));
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 500.0, md_params_get(&P, MD_P_HEARTBEAT_TIMEOUT_MS));
    TEST_ASSERT_EQUAL_UINT32(1u, md_params_get_u32(&P, MD_P_MONITOR_ACT));
    TEST_ASSERT_EQUAL_UINT32(1u, md_params_get_u32(&P, MD_P_MONITOR_HALL));
    TEST_ASSERT_EQUAL_UINT32(1u, md_params_get_u32(&P, MD_P_MONITOR_FE));
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 10.0, md_params_get(&P, MD_P_INTERVAL_S));
    TEST_ASSERT_TRUE(md_params_get(&P, MD_P_DEPTH_MIN_UM) < md_params_get(&P, MD_P_DEPTH_MAX_UM));
    /* diagnostics are read-only rows */
    const md_param_id_t diag[] = {MD_P_RX_FRAMES,       MD_P_RX_MALFORMED, MD_P_RX_UNKNOWN_ID, MD_P_RX_BAD_LENGTH,
                                  MD_P_RX_BAD_SEQUENCE, MD_P_EMCY_SENT,    MD_P_TX_FAILURES};
    for (size_t i = 0u; i < sizeof diag / sizeof diag[0]; ++i) {
        TEST_ASSERT_TRUE((md_params_def((size_t)diag[i])->flags & MD_PARAM_F_READ_ONLY) != 0u);
    }
}

static void test_set_in_range_applies(void)
{
    TEST_ASSERT_EQUAL_INT(MD_PARAM_OK, md_params_set(&P, index_of(MD_P_HEARTBEAT_PERIOD_MS), 250.0));
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 250.0, md_params_get(&P, MD_P_HEARTBEAT_PERIOD_MS));
    const md_param_def_t *d = md_params_def((size_t)MD_P_HEARTBEAT_PERIOD_MS);
    TEST_ASSERT_EQUAL_INT(MD_PARAM_OK, md_params_set(&P, d->index, d->min)); /* bounds are inclusive */
    TEST_ASSERT_EQUAL_INT(MD_PARAM_OK, md_params_set(&P, d->index, d->max));
    TEST_ASSERT_DOUBLE_WITHIN(0.0, d->max, md_params_get(&P, MD_P_HEARTBEAT_PERIOD_MS));
}

static void test_set_out_of_range_changes_nothing(void)
{
    const md_param_def_t *d = md_params_def((size_t)MD_P_HEARTBEAT_PERIOD_MS);
    TEST_ASSERT_EQUAL_INT(MD_PARAM_OUT_OF_RANGE, md_params_set(&P, d->index, d->min - 1.0));
    TEST_ASSERT_EQUAL_INT(MD_PARAM_OUT_OF_RANGE, md_params_set(&P, d->index, d->max + 1.0));
    TEST_ASSERT_EQUAL_INT(MD_PARAM_OUT_OF_RANGE, md_params_set(&P, d->index, 150.5)); /* integer row */
    TEST_ASSERT_DOUBLE_WITHIN(0.0, d->def, md_params_get(&P, MD_P_HEARTBEAT_PERIOD_MS));
}

static void test_nan_and_inf_are_rejected(void)
{
    const uint16_t idx = index_of(MD_P_MOVE_MAX_UM);
    TEST_ASSERT_EQUAL_INT(MD_PARAM_OUT_OF_RANGE, md_params_set(&P, idx, (double)NAN));
    TEST_ASSERT_EQUAL_INT(MD_PARAM_OUT_OF_RANGE, md_params_set(&P, idx, (double)INFINITY));
    TEST_ASSERT_EQUAL_INT(MD_PARAM_OUT_OF_RANGE, md_params_set(&P, idx, -(double)INFINITY));
    TEST_ASSERT_DOUBLE_WITHIN(0.0, md_params_def((size_t)MD_P_MOVE_MAX_UM)->def, md_params_get(&P, MD_P_MOVE_MAX_UM));
}

static void test_read_only_and_unknown(void)
{
    TEST_ASSERT_EQUAL_INT(MD_PARAM_READ_ONLY, md_params_set(&P, index_of(MD_P_RX_FRAMES), 0.0));
    TEST_ASSERT_EQUAL_INT(MD_PARAM_READ_ONLY, md_params_set(&P, index_of(MD_P_UPTIME_S), 1.0));
    TEST_ASSERT_EQUAL_INT(MD_PARAM_UNKNOWN_INDEX, md_params_set(&P, 0x7777u, 1.0));
    TEST_ASSERT_EQUAL_INT(MD_PARAM_UNKNOWN_INDEX, md_params_set(NULL, index_of(MD_P_INTERVAL_S), 1.0));
}

static void test_depth_window_stays_ordered(void)
{
    const uint16_t lo = index_of(MD_P_DEPTH_MIN_UM);
    const uint16_t hi = index_of(MD_P_DEPTH_MAX_UM);
    TEST_ASSERT_EQUAL_INT(MD_PARAM_OK, md_params_set(&P, hi, 3000.0));
    TEST_ASSERT_EQUAL_INT(MD_PARAM_OUT_OF_RANGE, md_params_set(&P, lo, 3000.0));
    TEST_ASSERT_EQUAL_INT(MD_PARAM_OK, md_params_set(&P, lo, 2999.0));
    TEST_ASSERT_EQUAL_INT(MD_PARAM_OUT_OF_RANGE, md_params_set(&P, hi, 2000.0));
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 3000.0, md_params_get(&P, MD_P_DEPTH_MAX_UM));
}

static void test_init_restores_defaults_and_rejects_null(void)
{
    TEST_ASSERT_EQUAL_INT(MD_PARAM_OK, md_params_set(&P, index_of(MD_P_INTERVAL_S), 20.0));
    TEST_ASSERT_EQUAL_INT(MD_OK, md_params_init(&P));
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 10.0, md_params_get(&P, MD_P_INTERVAL_S));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, md_params_init(NULL));
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.0, md_params_get(&P, MD_P_COUNT));
}

static void test_get_u32_saturates(void)
{
    P.value[MD_P_INTERVAL_S] = -5.0;
    TEST_ASSERT_EQUAL_UINT32(0u, md_params_get_u32(&P, MD_P_INTERVAL_S));
    P.value[MD_P_INTERVAL_S] = 1e12;
    TEST_ASSERT_EQUAL_UINT32(UINT32_MAX, md_params_get_u32(&P, MD_P_INTERVAL_S));
    P.value[MD_P_INTERVAL_S] = (double)NAN;
    TEST_ASSERT_EQUAL_UINT32(0u, md_params_get_u32(&P, MD_P_INTERVAL_S));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_table_is_consistent);
    RUN_TEST(test_required_rows_exist_with_defaults);
    RUN_TEST(test_set_in_range_applies);
    RUN_TEST(test_set_out_of_range_changes_nothing);
    RUN_TEST(test_nan_and_inf_are_rejected);
    RUN_TEST(test_read_only_and_unknown);
    RUN_TEST(test_depth_window_stays_ordered);
    RUN_TEST(test_init_restores_defaults_and_rejects_null);
    RUN_TEST(test_get_u32_saturates);
    return UNITY_END();
}
