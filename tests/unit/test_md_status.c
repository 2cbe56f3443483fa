/* Unit: md_status — every code has a distinct, stable name. */
#include "md_status.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static void test_names_are_distinct_and_known(void)
{
    const md_status_t codes[] = {MD_OK,           MD_E_ARG,   MD_E_CAPACITY, MD_E_NUMERIC, MD_E_DEGENERATE,
                                 MD_E_NOCONVERGE, MD_E_STATE, MD_E_FRAME,    MD_E_TIMEOUT, MD_E_IO};
    const unsigned n = (unsigned)(sizeof codes / sizeof codes[0]);
    for (unsigned i = 0u; i < n; ++i) {
        TEST_ASSERT_TRUE(md_status_name(codes[i])[0] == 'M');
        for (unsigned j = i + 1u; j < n; ++j) {
            TEST_ASSERT_TRUE(md_status_name(codes[i]) != md_status_name(codes[j]));
        }
    }
    TEST_ASSERT_EQUAL_STRING("MD_E_UNKNOWN", md_status_name((md_status_t)-100));
}

static void test_success_is_zero_and_failures_negative(void)
{
    TEST_ASSERT_EQUAL_INT(0, MD_OK);
    TEST_ASSERT_LESS_THAN(0, MD_E_ARG);
    TEST_ASSERT_LESS_THAN(0, MD_E_IO);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_names_are_distinct_and_known);
    RUN_TEST(test_success_is_zero_and_failures_negative);
    return UNITY_END();
}
