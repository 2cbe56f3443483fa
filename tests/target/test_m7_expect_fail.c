/* Target-only, a test of the test harness: this program FAILS on purpose
 * (one failing and one passing test). ctest runs it with
 * `run-qemu.sh --expect-exit 1`, so it is green only if a failed assertion on
 * the target really turns into a non-zero QEMU exit status, i.e. if a broken
 * unit test can make `ctest --preset cortex-m7` red. */
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static void test_deliberately_failing(void)
{
    TEST_FAIL_MESSAGE("deliberate failure (harness check)");
}

static void test_passing(void)
{
    TEST_ASSERT_EQUAL_INT(4, 2 + 2);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_deliberately_failing);
    RUN_TEST(test_passing);
    return UNITY_END();
}
