/* Target-only, a test of the fault path: an integer division by zero must
 * trap (CCR.DIV_0_TRP), be reported by the UsageFault handler and end QEMU
 * with MD_M7_FAULT_EXIT_STATUS. ctest checks status and report
 * (`run-qemu.sh --expect-exit 254 --expect-output ...`). */
#include <stdint.h>

#include "md_m7_startup.h"
#include "unity.h"

_Static_assert(MD_M7_FAULT_EXIT_STATUS == 254, "ctest expects exit status 254");

void setUp(void) {}
void tearDown(void) {}

static void test_division_by_zero_faults(void)
{
    volatile uint32_t num = 7u;
    volatile uint32_t den = 0u;
    volatile uint32_t q = num / den; /* never completes */
    (void)q;
    TEST_FAIL_MESSAGE("division by zero did not trap");
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_division_by_zero_faults);
    return UNITY_END();
}
