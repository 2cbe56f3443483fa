/* STAND-IN for ThrowTheSwitch Unity (see unity.h). Written from scratch for
 * this project; only the subset our tests use. A failed assertion longjmps out
 * of the running test, as Unity does, so later statements of that test are
 * skipped and the next test runs. */
#include "unity.h"

#include <setjmp.h>

static struct {
    const char *file;
    const char *test_name;
    unsigned tests, failures, ignored;
    int current_failed;
    jmp_buf abort_frame;
} unity_state;

static void out_str(const char *s)
{
    if (s == NULL) {
        return;
    }
    for (unsigned i = 0u; s[i] != '\0' && i < 4096u; ++i) {
        unity_standin_putchar((unsigned char)s[i]);
    }
}

static void out_uint(uint64_t v)
{
    char buf[24];
    unsigned n = 0u;
    do {
        buf[n++] = (char)('0' + (int)(v % 10u));
        v /= 10u;
    } while (v != 0u && n < sizeof buf);
    while (n > 0u) {
        unity_standin_putchar(buf[--n]);
    }
}

static void out_int(int64_t v)
{
    if (v < 0) {
        unity_standin_putchar('-');
        out_uint((uint64_t)(-(v + 1)) + 1u);
    } else {
        out_uint((uint64_t)v);
    }
}

/* Enough precision to read a failure, not a faithful %g. */
static void out_double(double v)
{
    if (!(v >= 0.0) && !(v < 0.0)) { /* NaN */
        out_str("nan");
        return;
    }
    if (v < 0.0) {
        unity_standin_putchar('-');
        v = -v;
    }
    if (v > 1e15) {
        out_str("inf-or-huge");
        return;
    }
    uint64_t whole = (uint64_t)v;
    double frac = v - (double)whole;
    out_uint(whole);
    unity_standin_putchar('.');
    for (int i = 0; i < 6; ++i) {
        frac *= 10.0;
        int digit = (int)frac;
        unity_standin_putchar('0' + digit);
        frac -= (double)digit;
    }
}

static void report_location(int line)
{
    out_str(unity_state.file);
    unity_standin_putchar(':');
    out_int(line);
    unity_standin_putchar(':');
    out_str(unity_state.test_name);
    unity_standin_putchar(':');
}

_Noreturn static void fail_now(int line, const char *what, const char *msg)
{
    report_location(line);
    out_str("FAIL: ");
    out_str(what);
    if (msg != NULL) {
        out_str(" (");
        out_str(msg);
        unity_standin_putchar(')');
    }
    unity_standin_putchar('\n');
    unity_state.current_failed = 1;
    longjmp(unity_state.abort_frame, 1);
}

void UnityBegin(const char *file)
{
    unity_state.file = file;
    unity_state.tests = 0u;
    unity_state.failures = 0u;
    unity_state.ignored = 0u;
}

int UnityEnd(void)
{
    out_str("\n-----------------------\n");
    out_uint(unity_state.tests);
    out_str(" Tests ");
    out_uint(unity_state.failures);
    out_str(" Failures ");
    out_uint(unity_state.ignored);
    out_str(" Ignored\n");
    out_str(unity_state.failures == 0u ? "OK\n" : "FAIL\n");
    return (int)unity_state.failures;
}

void UnityDefaultTestRun(UnityTestFunction func, const char *name, int line)
{
    unity_state.test_name = name;
    unity_state.current_failed = 0;
    unity_state.tests++;
    if (setjmp(unity_state.abort_frame) == 0) {
        setUp();
        func();
    }
    if (setjmp(unity_state.abort_frame) == 0) {
        tearDown();
    }
    if (unity_state.current_failed == 1) {
        unity_state.failures++;
    } else if (unity_state.current_failed == 0) {
        report_location(line);
        out_str("PASS\n");
    }
}

_Noreturn void UnityFail(const char *msg, int line)
{
    fail_now(line, "TEST_FAIL", msg);
}

_Noreturn void UnityIgnore(const char *msg, int line)
{
    report_location(line);
    out_str("IGNORE");
    if (msg != NULL) {
        out_str(": ");
        out_str(msg);
    }
    unity_standin_putchar('\n');
    unity_state.current_failed = 2;
    unity_state.ignored++;
    longjmp(unity_state.abort_frame, 1);
}

void UnityMessage(const char *msg, int line)
{
    report_location(line);
    out_str("INFO: ");
    out_str(msg);
    unity_standin_putchar('\n');
}

_Noreturn void UnityFailAssert(const char *expr, const char *msg, int line)
{
    fail_now(line, expr, msg);
}

void UnityAssertEqualInt(int64_t expected, int64_t actual, const char *msg, int line)
{
    if (expected != actual) {
        report_location(line);
        out_str("Expected ");
        out_int(expected);
        out_str(" Was ");
        out_int(actual);
        unity_standin_putchar('\n');
        fail_now(line, "integers differ", msg);
    }
}

void UnityAssertEqualUInt(uint64_t expected, uint64_t actual, const char *msg, int line)
{
    if (expected != actual) {
        report_location(line);
        out_str("Expected ");
        out_uint(expected);
        out_str(" Was ");
        out_uint(actual);
        unity_standin_putchar('\n');
        fail_now(line, "unsigned integers differ", msg);
    }
}

static int relation_holds_int(int64_t t, int64_t a, int rel)
{
    switch (rel) {
    case UNITY_REL_GT: return a > t;
    case UNITY_REL_LT: return a < t;
    case UNITY_REL_GE: return a >= t;
    default: return a <= t;
    }
}

static int relation_holds_double(double t, double a, int rel)
{
    switch (rel) {
    case UNITY_REL_GT: return a > t;
    case UNITY_REL_LT: return a < t;
    case UNITY_REL_GE: return a >= t;
    default: return a <= t;
    }
}

static const char *relation_name(int rel)
{
    switch (rel) {
    case UNITY_REL_GT: return " > ";
    case UNITY_REL_LT: return " < ";
    case UNITY_REL_GE: return " >= ";
    default: return " <= ";
    }
}

void UnityAssertCompareInt(int64_t threshold, int64_t actual, int relation, const char *msg, int line)
{
    if (!relation_holds_int(threshold, actual, relation)) {
        report_location(line);
        out_str("Expected actual ");
        out_int(actual);
        out_str(relation_name(relation));
        out_int(threshold);
        unity_standin_putchar('\n');
        fail_now(line, "comparison failed", msg);
    }
}

void UnityAssertCompareDouble(double threshold, double actual, int relation, const char *msg, int line)
{
    if (!relation_holds_double(threshold, actual, relation)) {
        report_location(line);
        out_str("Expected actual ");
        out_double(actual);
        out_str(relation_name(relation));
        out_double(threshold);
        unity_standin_putchar('\n');
        fail_now(line, "comparison failed", msg);
    }
}

void UnityAssertDoubleWithin(double delta, double expected, double actual, const char *msg, int line)
{
    double diff = actual - expected;
    if (diff < 0.0) {
        diff = -diff;
    }
    /* NaN fails: the comparison below is false for NaN. */
    if (!(diff <= delta)) {
        report_location(line);
        out_str("Expected ");
        out_double(expected);
        out_str(" +/- ");
        out_double(delta);
        out_str(" Was ");
        out_double(actual);
        unity_standin_putchar('\n');
        fail_now(line, "values not within delta", msg);
    }
}

void UnityAssertIntWithin(int64_t delta, int64_t expected, int64_t actual, const char *msg, int line)
{
    const int64_t diff = (actual > expected) ? (actual - expected) : (expected - actual);
    if (diff > delta) {
        report_location(line);
        out_str("Expected ");
        out_int(expected);
        out_str(" +/- ");
        out_int(delta);
        out_str(" Was ");
        out_int(actual);
        unity_standin_putchar('\n');
        fail_now(line, "integers not within delta", msg);
    }
}

void UnityAssertEqualString(const char *expected, const char *actual, const char *msg, int line)
{
    if (expected == NULL || actual == NULL) {
        if (expected != actual) {
            fail_now(line, "one string is NULL", msg);
        }
        return;
    }
    for (size_t i = 0u; i < 65536u; ++i) {
        if (expected[i] != actual[i]) {
            report_location(line);
            out_str("Expected '");
            out_str(expected);
            out_str("' Was '");
            out_str(actual);
            out_str("'\n");
            fail_now(line, "strings differ", msg);
        }
        if (expected[i] == '\0') {
            return;
        }
    }
}

void UnityAssertEqualMemory(const void *expected, const void *actual, size_t len, const char *msg, int line)
{
    const unsigned char *e = expected;
    const unsigned char *a = actual;
    for (size_t i = 0u; i < len; ++i) {
        if (e[i] != a[i]) {
            report_location(line);
            out_str("Memory differs at byte ");
            out_uint(i);
            unity_standin_putchar('\n');
            fail_now(line, "memory differs", msg);
        }
    }
}
