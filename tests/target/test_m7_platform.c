/* Target-only: the Cortex-M7 start-up left the machine in the state the
 * firmware relies on (double FPU on, .data/.bss initialised, no heap, traps
 * armed) and newlib's libm gives correct double results on it. */
#include <math.h>
#include <stdint.h>

#include "md_m7_startup.h"
#include "unity.h"

#define REG32(addr) (*(volatile const uint32_t *)(addr))
#define CPACR 0xE000ED88u
#define MVFR0 0xE000EF40u
#define SCB_CCR 0xE000ED14u

extern uint32_t __heap_start[], __heap_end[];

static uint32_t initialised_word = 0x12345678u;
static uint32_t zeroed_words[64];

void setUp(void) {}
void tearDown(void) {}

static void test_fpu_is_enabled_and_double_precision(void)
{
    /* CP10/CP11 full access, set by Reset_Handler. */
    TEST_ASSERT_EQUAL_HEX32(0x00F00000u, REG32(CPACR) & 0x00F00000u);
    const uint32_t mvfr0 = REG32(MVFR0);
    TEST_ASSERT_EQUAL_UINT32(1u, mvfr0 & 0xFu);         /* 16 x 64-bit registers (D16) */
    TEST_ASSERT_EQUAL_UINT32(2u, (mvfr0 >> 4) & 0xFu);  /* single precision */
    TEST_ASSERT_EQUAL_UINT32(2u, (mvfr0 >> 8) & 0xFu);  /* double precision */
    TEST_ASSERT_EQUAL_UINT32(1u, (mvfr0 >> 20) & 0xFu); /* hardware square root */
}

static void test_double_arithmetic_is_ieee_double(void)
{
    volatile double one = 1.0;
    volatile double tiny = 0x1p-52; /* 1 ulp of 1.0 in double, lost in float */
    TEST_ASSERT_TRUE((one + tiny) > one);
    volatile double third = 1.0 / 3.0;
    TEST_ASSERT_DOUBLE_WITHIN(1e-16, 0.3333333333333333, third);
}

static void test_libm_double_functions(void)
{
    volatile double two = 2.0;
    TEST_ASSERT_DOUBLE_WITHIN(1e-15, 1.4142135623730951, sqrt(two));
    TEST_ASSERT_DOUBLE_WITHIN(1e-15, 0.6931471805599453, log(two));
    TEST_ASSERT_DOUBLE_WITHIN(1e-14, 7.38905609893065, exp(two));
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 2.0, fabs(-two));
    TEST_ASSERT_TRUE(isnan(sqrt(-two)));
}

static void test_data_and_bss_are_initialised(void)
{
    TEST_ASSERT_EQUAL_HEX32(0x12345678u, initialised_word);
    for (unsigned i = 0u; i < 64u; ++i) {
        TEST_ASSERT_EQUAL_UINT32(0u, zeroed_words[i]);
    }
}

static void test_no_heap_and_a_sane_stack(void)
{
    TEST_ASSERT_EQUAL_UINT((uintptr_t)__heap_start, (uintptr_t)__heap_end);
    const uint32_t used = md_m7_stack_used_bytes();
    TEST_ASSERT_GREATER_THAN_UINT(0u, used);
    TEST_ASSERT_LESS_THAN_UINT(md_m7_stack_size_bytes(), used);
}

static void test_integer_division_by_zero_traps(void)
{
    TEST_ASSERT_EQUAL_HEX32(1u << 4, REG32(SCB_CCR) & (1u << 4)); /* DIV_0_TRP */
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_fpu_is_enabled_and_double_precision);
    RUN_TEST(test_double_arithmetic_is_ieee_double);
    RUN_TEST(test_libm_double_functions);
    RUN_TEST(test_data_and_bss_are_initialised);
    RUN_TEST(test_no_heap_and_a_sane_stack);
    RUN_TEST(test_integer_division_by_zero_traps);
    return UNITY_END();
}
