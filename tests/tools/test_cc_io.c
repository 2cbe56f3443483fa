/* Host unit: cluster-consistency's ground_truth.csv reader (cc_io.h): the
 * exporter's format is read, anything else is refused with PATH:LINE. */
#define _POSIX_C_SOURCE 200809L
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cc_io.h"
#include "unity.h"

static char g_dir[64];
static char g_path[128];
static char g_err[4400];
static cc_truth_t g_t;

void setUp(void)
{
    (void)snprintf(g_dir, sizeof g_dir, "/tmp/test_cc_io.XXXXXX");
    TEST_ASSERT_NOT_NULL(mkdtemp(g_dir));
    (void)snprintf(g_path, sizeof g_path, "%s/ground_truth.csv", g_dir);
}

void tearDown(void)
{
    cc_truth_free(&g_t);
    (void)unlink(g_path);
    (void)rmdir(g_dir);
}

static md_status_t read_csv(const char *text, uint32_t ch)
{
    FILE *f = fopen(g_path, "wb");
    TEST_ASSERT_NOT_NULL(f);
    (void)fputs(text, f);
    (void)fclose(f);
    return cc_read_truth(g_dir, ch, &g_t, g_err, sizeof g_err);
}

static void test_exporter_format(void)
{
    TEST_ASSERT_EQUAL_INT(MD_OK, read_csv("sample_index,channel,neuron_id\n12,0,3\n40,1,-1\n41,0,-1\n99,0,2\n", 0u));
    TEST_ASSERT_EQUAL_size_t(2u, g_t.n);
    TEST_ASSERT_EQUAL_UINT64(12u, g_t.sample[0]);
    TEST_ASSERT_EQUAL_INT32(2, g_t.neuron[1]);
    TEST_ASSERT_EQUAL_INT32(3, g_t.max_neuron);
    TEST_ASSERT_EQUAL_size_t(1u, cc_truth_lower_bound(&g_t, 13u));
}

static void test_crlf_and_limits(void)
{
    TEST_ASSERT_EQUAL_INT(MD_OK, read_csv("sample_index,channel,neuron_id\r\n\r\n18446744073709551615,4294967295,"
                                          "2147483647\r\n",
                                          4294967295u));
    TEST_ASSERT_EQUAL_size_t(1u, g_t.n);
    TEST_ASSERT_EQUAL_UINT64(UINT64_MAX, g_t.sample[0]);
}

/* What sscanf("%llu,%u,%d") took before: a negative sample or channel
 * (wrapped), trailing text, a value beyond its type, a second header. */
static void test_not_records_refused(void)
{
    static const char *const bad[] = {
        "-1,0,3\n",
        "5,-1,3\n",
        "5,0,3abc\n",
        " 5,0,3\n",
        "+5,0,3\n",
        "5,0,2147483648\n",
        "5,4294967296,1\n",
        "18446744073709551616,0,1\n",
        "5,0\n",
        "1,0,1\nsample_index,channel,neuron_id\n",
        "5,0,3,\n",
    };
    for (size_t k = 0u; k < sizeof bad / sizeof bad[0]; ++k) {
        TEST_ASSERT_EQUAL_INT_MESSAGE(MD_E_FRAME, read_csv(bad[k], 0u), bad[k]);
        TEST_ASSERT_TRUE_MESSAGE(strncmp(g_err, g_path, strlen(g_path)) == 0, g_err);
        TEST_ASSERT_EQUAL_size_t(0u, g_t.n);
    }
    TEST_ASSERT_EQUAL_INT(MD_E_FRAME, read_csv("1,0,1\n9,0,1\n8,0,1\n", 0u));
    TEST_ASSERT_NOT_NULL(strstr(g_err, "ground_truth.csv:3: samples of the channel not ascending"));
}

static void test_missing_file_is_empty(void)
{
    TEST_ASSERT_EQUAL_INT(MD_OK, cc_read_truth(g_dir, 0u, &g_t, g_err, sizeof g_err));
    TEST_ASSERT_EQUAL_size_t(0u, g_t.n);
    TEST_ASSERT_EQUAL_INT32(-1, g_t.max_neuron);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_exporter_format);
    RUN_TEST(test_crlf_and_limits);
    RUN_TEST(test_not_records_refused);
    RUN_TEST(test_missing_file_is_empty);
    return UNITY_END();
}
