/// @file unity.h
/// STAND-IN for ThrowTheSwitch Unity: a small, independently written subset of
/// Unity's public test API, used only when the build is not given a real Unity
/// checkout (-DUNITY_ROOT=<dir with src/unity.c>). Tests written against this
/// header compile unchanged against real Unity.
///
/// Output goes through unity_standin_putchar(), which the host build maps to
/// putchar() and the Cortex-M build to semihosting, so no printf (and no heap)
/// is needed on the target.
#ifndef UNITY_STANDIN_H
#define UNITY_STANDIN_H

#include <stddef.h>
#include <stdint.h>

#define UNITY_STANDIN 1

typedef void (*UnityTestFunction)(void);

void setUp(void);
void tearDown(void);

void UnityBegin(const char *file);
int UnityEnd(void);
void UnityDefaultTestRun(UnityTestFunction func, const char *name, int line);
/* Failing never returns (it longjmps to the test runner), as in real Unity;
 * saying so lets the compiler see that code after an assertion is reached
 * only when the assertion held (no false -Wnull-dereference). */
_Noreturn void UnityFail(const char *msg, int line);
_Noreturn void UnityFailAssert(const char *expr, const char *msg, int line);
_Noreturn void UnityIgnore(const char *msg, int line);
void UnityMessage(const char *msg, int line);
void UnityAssertEqualInt(int64_t expected, int64_t actual, const char *msg, int line);
void UnityAssertEqualUInt(uint64_t expected, uint64_t actual, const char *msg, int line);
void UnityAssertCompareInt(int64_t threshold, int64_t actual, int relation, const char *msg, int line);
void UnityAssertCompareDouble(double threshold, double actual, int relation, const char *msg, int line);
void UnityAssertDoubleWithin(double delta, double expected, double actual, const char *msg, int line);
void UnityAssertEqualString(const char *expected, const char *actual, const char *msg, int line);
void UnityAssertEqualMemory(const void *expected, const void *actual, size_t len, const char *msg, int line);

/// Character sink; defined by the platform glue (host: putchar).
void unity_standin_putchar(int c);

#define UNITY_REL_GT 1
#define UNITY_REL_LT 2
#define UNITY_REL_GE 3
#define UNITY_REL_LE 4

#define UNITY_BEGIN() UnityBegin(__FILE__)
#define UNITY_END() UnityEnd()
#define RUN_TEST(func) UnityDefaultTestRun(func, #func, __LINE__)

#define TEST_FAIL_MESSAGE(msg) UnityFail((msg), __LINE__)
#define TEST_FAIL() UnityFail(NULL, __LINE__)
#define TEST_IGNORE_MESSAGE(msg) UnityIgnore((msg), __LINE__)
#define TEST_IGNORE() UnityIgnore(NULL, __LINE__)
#define TEST_MESSAGE(msg) UnityMessage((msg), __LINE__)
#define TEST_PASS() ((void)0)

#define UNITY_STANDIN_CHECK(c, expr, msg) \
    do { \
        if (!(c)) { \
            UnityFailAssert((expr), (msg), __LINE__); \
        } \
    } while (0)
#define TEST_ASSERT_MESSAGE(c, msg) UNITY_STANDIN_CHECK(c, #c, msg)
#define TEST_ASSERT(c) UNITY_STANDIN_CHECK(c, #c, NULL)
#define TEST_ASSERT_TRUE(c) TEST_ASSERT(c)
#define TEST_ASSERT_TRUE_MESSAGE(c, msg) TEST_ASSERT_MESSAGE(c, msg)
#define TEST_ASSERT_FALSE(c) UNITY_STANDIN_CHECK(!(c), "!(" #c ")", NULL)
#define TEST_ASSERT_FALSE_MESSAGE(c, msg) UNITY_STANDIN_CHECK(!(c), "!(" #c ")", msg)
#define TEST_ASSERT_NULL(p) UNITY_STANDIN_CHECK((p) == NULL, #p " == NULL", NULL)
#define TEST_ASSERT_NOT_NULL(p) UNITY_STANDIN_CHECK((p) != NULL, #p " != NULL", NULL)

#define TEST_ASSERT_EQUAL_INT_MESSAGE(e, a, msg) UnityAssertEqualInt((int64_t)(e), (int64_t)(a), (msg), __LINE__)
#define TEST_ASSERT_EQUAL_INT(e, a) TEST_ASSERT_EQUAL_INT_MESSAGE(e, a, NULL)
#define TEST_ASSERT_EQUAL(e, a) TEST_ASSERT_EQUAL_INT(e, a)
#define TEST_ASSERT_EQUAL_MESSAGE(e, a, msg) TEST_ASSERT_EQUAL_INT_MESSAGE(e, a, msg)
#define TEST_ASSERT_EQUAL_INT8(e, a) TEST_ASSERT_EQUAL_INT(e, a)
#define TEST_ASSERT_EQUAL_INT16(e, a) TEST_ASSERT_EQUAL_INT(e, a)
#define TEST_ASSERT_EQUAL_INT32(e, a) TEST_ASSERT_EQUAL_INT(e, a)
#define TEST_ASSERT_EQUAL_INT64(e, a) TEST_ASSERT_EQUAL_INT(e, a)
#define TEST_ASSERT_EQUAL_UINT_MESSAGE(e, a, msg) UnityAssertEqualUInt((uint64_t)(e), (uint64_t)(a), (msg), __LINE__)
#define TEST_ASSERT_EQUAL_UINT(e, a) TEST_ASSERT_EQUAL_UINT_MESSAGE(e, a, NULL)
#define TEST_ASSERT_EQUAL_UINT8(e, a) TEST_ASSERT_EQUAL_UINT(e, a)
#define TEST_ASSERT_EQUAL_UINT16(e, a) TEST_ASSERT_EQUAL_UINT(e, a)
#define TEST_ASSERT_EQUAL_UINT32(e, a) TEST_ASSERT_EQUAL_UINT(e, a)
#define TEST_ASSERT_EQUAL_UINT64(e, a) TEST_ASSERT_EQUAL_UINT(e, a)
#define TEST_ASSERT_EQUAL_HEX8(e, a) TEST_ASSERT_EQUAL_UINT(e, a)
#define TEST_ASSERT_EQUAL_HEX16(e, a) TEST_ASSERT_EQUAL_UINT(e, a)
#define TEST_ASSERT_EQUAL_HEX32(e, a) TEST_ASSERT_EQUAL_UINT(e, a)
#define TEST_ASSERT_EQUAL_size_t(e, a) TEST_ASSERT_EQUAL_UINT(e, a)

#define TEST_ASSERT_GREATER_THAN(t, a) UnityAssertCompareInt((int64_t)(t), (int64_t)(a), UNITY_REL_GT, NULL, __LINE__)
#define TEST_ASSERT_LESS_THAN(t, a) UnityAssertCompareInt((int64_t)(t), (int64_t)(a), UNITY_REL_LT, NULL, __LINE__)
#define TEST_ASSERT_GREATER_OR_EQUAL(t, a) UnityAssertCompareInt((int64_t)(t), (int64_t)(a), UNITY_REL_GE, NULL, __LINE__)
#define TEST_ASSERT_LESS_OR_EQUAL(t, a) UnityAssertCompareInt((int64_t)(t), (int64_t)(a), UNITY_REL_LE, NULL, __LINE__)
#define TEST_ASSERT_GREATER_THAN_INT(t, a) TEST_ASSERT_GREATER_THAN(t, a)
#define TEST_ASSERT_LESS_THAN_INT(t, a) TEST_ASSERT_LESS_THAN(t, a)
#define TEST_ASSERT_GREATER_OR_EQUAL_INT(t, a) TEST_ASSERT_GREATER_OR_EQUAL(t, a)
#define TEST_ASSERT_LESS_OR_EQUAL_INT(t, a) TEST_ASSERT_LESS_OR_EQUAL(t, a)
#define TEST_ASSERT_GREATER_THAN_UINT(t, a) TEST_ASSERT_GREATER_THAN(t, a)
#define TEST_ASSERT_LESS_THAN_UINT(t, a) TEST_ASSERT_LESS_THAN(t, a)
#define TEST_ASSERT_GREATER_OR_EQUAL_UINT(t, a) TEST_ASSERT_GREATER_OR_EQUAL(t, a)
#define TEST_ASSERT_LESS_OR_EQUAL_UINT(t, a) TEST_ASSERT_LESS_OR_EQUAL(t, a)

#define TEST_ASSERT_GREATER_THAN_DOUBLE(t, a) UnityAssertCompareDouble((double)(t), (double)(a), UNITY_REL_GT, NULL, __LINE__)
#define TEST_ASSERT_LESS_THAN_DOUBLE(t, a) UnityAssertCompareDouble((double)(t), (double)(a), UNITY_REL_LT, NULL, __LINE__)
#define TEST_ASSERT_GREATER_OR_EQUAL_DOUBLE(t, a) UnityAssertCompareDouble((double)(t), (double)(a), UNITY_REL_GE, NULL, __LINE__)
#define TEST_ASSERT_LESS_OR_EQUAL_DOUBLE(t, a) UnityAssertCompareDouble((double)(t), (double)(a), UNITY_REL_LE, NULL, __LINE__)
#define TEST_ASSERT_GREATER_THAN_FLOAT(t, a) TEST_ASSERT_GREATER_THAN_DOUBLE(t, a)
#define TEST_ASSERT_LESS_THAN_FLOAT(t, a) TEST_ASSERT_LESS_THAN_DOUBLE(t, a)

#define TEST_ASSERT_DOUBLE_WITHIN_MESSAGE(d, e, a, msg) UnityAssertDoubleWithin((double)(d), (double)(e), (double)(a), (msg), __LINE__)
#define TEST_ASSERT_DOUBLE_WITHIN(d, e, a) TEST_ASSERT_DOUBLE_WITHIN_MESSAGE(d, e, a, NULL)
#define TEST_ASSERT_FLOAT_WITHIN(d, e, a) TEST_ASSERT_DOUBLE_WITHIN(d, e, a)
#define TEST_ASSERT_FLOAT_WITHIN_MESSAGE(d, e, a, msg) TEST_ASSERT_DOUBLE_WITHIN_MESSAGE(d, e, a, msg)

/* Integer closeness: |actual - expected| <= delta, compared in 64 bits. */
void UnityAssertIntWithin(int64_t delta, int64_t expected, int64_t actual, const char *msg, int line);
#define TEST_ASSERT_INT_WITHIN(d, e, a) UnityAssertIntWithin((int64_t)(d), (int64_t)(e), (int64_t)(a), NULL, __LINE__)
#define TEST_ASSERT_INT32_WITHIN(d, e, a) TEST_ASSERT_INT_WITHIN(d, e, a)
#define TEST_ASSERT_UINT_WITHIN(d, e, a) TEST_ASSERT_INT_WITHIN(d, e, a)
#define TEST_ASSERT_UINT32_WITHIN(d, e, a) TEST_ASSERT_INT_WITHIN(d, e, a)

#define TEST_ASSERT_EQUAL_STRING(e, a) UnityAssertEqualString((e), (a), NULL, __LINE__)
#define TEST_ASSERT_EQUAL_STRING_MESSAGE(e, a, msg) UnityAssertEqualString((e), (a), (msg), __LINE__)
#define TEST_ASSERT_EQUAL_MEMORY(e, a, len) UnityAssertEqualMemory((e), (a), (len), NULL, __LINE__)

#endif
