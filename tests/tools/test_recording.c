/* Host unit: the recording reader of the host tools (tools/recording). Valid
 * sidecars give the documented fields and samples (int16 and float32,
 * little-endian, interleaved; float32 rounding, clipping and non-finite
 * values counted); every kind of bad sidecar or binary gives its status and a
 * one-line "PATH: reason" naming the file and the field or byte offset. */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "recording.h"
#include "unity.h"

static char g_dir[64];
static char g_json[128];
static char g_bin[128];
static rec_recording_t g_rec;
static char g_err[REC_ERR_MAX];

void setUp(void)
{
    memset(g_err, 0, sizeof g_err);
}

void tearDown(void)
{
    const char *names[] = {"recording.json", "recording.bin", "other.bin"};
    for (size_t i = 0u; i < sizeof names / sizeof names[0]; ++i) {
        char p[160];
        (void)snprintf(p, sizeof p, "%s/%s", g_dir, names[i]);
        (void)remove(p);
    }
}

/* ---------------------------------------------------------------- files */

static void write_bytes(const char *name, const uint8_t *b, size_t n)
{
    char p[160];
    (void)snprintf(p, sizeof p, "%s/%s", g_dir, name);
    FILE *f = fopen(p, "wb");
    TEST_ASSERT_NOT_NULL(f);
    TEST_ASSERT_EQUAL_size_t(n, fwrite(b, 1u, n, f));
    TEST_ASSERT_EQUAL_INT(0, fclose(f));
}

static void write_json(const char *text)
{
    write_bytes("recording.json", (const uint8_t *)text, strlen(text));
}

static void write_zeros(const char *name, size_t n)
{
    uint8_t *b = calloc(n + 1u, 1u);
    TEST_ASSERT_NOT_NULL(b);
    write_bytes(name, b, n);
    free(b);
}

/* int16 samples, little-endian (frames of interleaved channels) */
static void write_i16(const char *name, const int16_t *v, size_t n)
{
    uint8_t *b = malloc(2u * n + 1u);
    TEST_ASSERT_NOT_NULL(b);
    for (size_t i = 0u; i < n; ++i) {
        const uint16_t u = (uint16_t)v[i];
        b[2u * i] = (uint8_t)(u & 0xffu);
        b[2u * i + 1u] = (uint8_t)(u >> 8u);
    }
    write_bytes(name, b, 2u * n);
    free(b);
}

/* float32 samples, little-endian */
static void write_f32(const char *name, const float *v, size_t n)
{
    uint8_t *b = malloc(4u * n + 1u);
    TEST_ASSERT_NOT_NULL(b);
    for (size_t i = 0u; i < n; ++i) {
        uint32_t u;
        memcpy(&u, &v[i], sizeof u);
        for (size_t j = 0u; j < 4u; ++j) {
            b[4u * i + j] = (uint8_t)((u >> (8u * j)) & 0xffu);
        }
    }
    write_bytes(name, b, 4u * n);
    free(b);
}

static md_status_t open_rec(double interval_s, uint32_t channel)
{
    const rec_options_t opt = {interval_s, channel};
    return rec_read_sidecar(g_json, &opt, &g_rec, g_err, sizeof g_err);
}

/* The status, and one line "<dir>/<file>: ...<reason>...". */
static void check_error(md_status_t want, md_status_t got, const char *file, const char *reason, int line)
{
    char prefix[200];
    char msg[REC_ERR_MAX + 400];
    (void)snprintf(prefix, sizeof prefix, "%s/%s: ", g_dir, file);
    (void)snprintf(msg, sizeof msg, "line %d: status %s, message [%s]", line, md_status_name(got), g_err);
    TEST_ASSERT_EQUAL_INT_MESSAGE(want, got, msg);
    TEST_ASSERT_TRUE_MESSAGE(strncmp(g_err, prefix, strlen(prefix)) == 0, msg);
    TEST_ASSERT_TRUE_MESSAGE(strstr(g_err, reason) != NULL, msg);
    TEST_ASSERT_TRUE_MESSAGE(strchr(g_err, '\n') == NULL, msg);
}

#define EXPECT_OPEN_ERROR(want, file, reason, json)           \
    do {                                                      \
        write_json(json);                                     \
        const md_status_t st_ = open_rec(10.0, 0u);           \
        check_error((want), st_, (file), (reason), __LINE__); \
    } while (0)

/* ---------------------------------------------------------------- valid */

static void test_int16_minimal_sidecar_is_cut_into_intervals(void)
{
    /* 2 channels x 3500 frames at 1 kHz: 1 s intervals, the half-second rest kept */
    enum { N = 3500 };
    static int16_t v[2 * N];
    for (int i = 0; i < N; ++i) {
        v[2 * i] = (int16_t)(i - 1000);
        v[2 * i + 1] = (int16_t)((i % 2 == 0) ? INT16_MIN + i : INT16_MAX - i);
    }
    write_i16("recording.bin", v, 2u * N);
    write_json("{\"sampling_frequency\": 1000, \"num_channels\": 2, \"dtype\": \"int16\"}");
    TEST_ASSERT_EQUAL_INT(MD_OK, open_rec(1.0, 1u));
    TEST_ASSERT_EQUAL_STRING(g_bin, g_rec.bin_path);
    TEST_ASSERT_EQUAL_UINT(2u, g_rec.n_channels);
    TEST_ASSERT_EQUAL_INT(REC_DTYPE_INT16, g_rec.dtype);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 1.0, g_rec.gain_uv);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 1.0, g_rec.count_uv);
    TEST_ASSERT_EQUAL_UINT64(N, g_rec.total_samples);
    TEST_ASSERT_EQUAL_INT(0, g_rec.interval_list);
    TEST_ASSERT_EQUAL_STRING("?", g_rec.scenario);
    TEST_ASSERT_EQUAL_UINT(4u, g_rec.n_intervals);
    TEST_ASSERT_EQUAL_UINT64(3000u, g_rec.iv[3].start_sample);
    TEST_ASSERT_EQUAL_UINT64(500u, g_rec.iv[3].num_samples);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 0.5, g_rec.iv[3].duration_s);
    TEST_ASSERT_TRUE(isnan(g_rec.iv[0].depth_um));
    static int16_t x[N];
    rec_conversion_t conv = {0u, 0u};
    for (uint32_t ch = 0u; ch < 2u; ++ch) {
        for (uint32_t k = 0u; k < g_rec.n_intervals; ++k) {
            TEST_ASSERT_EQUAL_INT(MD_OK, rec_read_interval(&g_rec, k, ch, x, N, &conv, g_err, sizeof g_err));
            for (uint64_t i = 0u; i < g_rec.iv[k].num_samples; ++i) {
                TEST_ASSERT_EQUAL_INT(v[2u * (g_rec.iv[k].start_sample + i) + ch], x[i]);
            }
        }
    }
    TEST_ASSERT_EQUAL_UINT64(0u, conv.clipped + conv.non_finite);
    /* a last partial interval is kept when at least half as long, else dropped */
    TEST_ASSERT_EQUAL_INT(MD_OK, open_rec(2.0, 0u));
    TEST_ASSERT_EQUAL_UINT(2u, g_rec.n_intervals);
    TEST_ASSERT_EQUAL_UINT64(1500u, g_rec.iv[1].num_samples);
    TEST_ASSERT_EQUAL_INT(MD_OK, open_rec(3.0, 0u));
    TEST_ASSERT_EQUAL_UINT(1u, g_rec.n_intervals);
    TEST_ASSERT_EQUAL_UINT64(3000u, g_rec.iv[0].num_samples);
}

static void test_export_sidecar_with_interval_list(void)
{
    write_zeros("recording.bin", 2u * 3u * 2000u);
    write_json("{\n  \"sampling_frequency\": 30000.000,\n  \"num_channels\": 3,\n  \"num_samples\": 2000,\n"
               "  \"dtype\": \"int16\",\n  \"gain_uV\": 0.195000,\n  \"offset_uV\": 0.0,\n"
               "  \"byte_order\": \"little\",\n  \"layout\": \"interleaved\",\n  \"seed\": 42,\n"
               "  \"scenario\": \"drift_away\",\n  \"intervals\": [\n"
               "    {\"index\": 0, \"start_sample\": 0, \"num_samples\": 1000, \"start_s\": 0.0, \"duration_s\": 0.04,"
               " \"depth_um\": [100.5, 200.5, 300.5]},\n"
               "    {\"index\": 1, \"start_sample\": 1000, \"num_samples\": 1000, \"depth_um\": [101, null, 301]}\n"
               "  ]\n}\n");
    TEST_ASSERT_EQUAL_INT(MD_OK, open_rec(0.0, 1u));
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 30000.0, g_rec.fs_hz);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.195, g_rec.gain_uv);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.195, g_rec.count_uv);
    TEST_ASSERT_EQUAL_STRING("drift_away", g_rec.scenario);
    TEST_ASSERT_EQUAL_UINT64(42u, g_rec.seed);
    TEST_ASSERT_EQUAL_INT(1, g_rec.interval_list);
    TEST_ASSERT_EQUAL_UINT(2u, g_rec.n_intervals);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.04, g_rec.iv[0].duration_s);
    TEST_ASSERT_DOUBLE_WITHIN(1e-15, 1000.0 / 30000.0, g_rec.iv[1].duration_s);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 200.5, g_rec.iv[0].depth_um);
    TEST_ASSERT_TRUE(isnan(g_rec.iv[1].depth_um));
    TEST_ASSERT_EQUAL_INT(MD_OK, open_rec(0.0, 2u));
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 301.0, g_rec.iv[1].depth_um);
}

/* microdrive-session's sidecar: one channel, depth and Hall code as numbers or
 * null, fields the reader does not use (source, electrode, cycle, complete). */
static void test_session_sidecar_with_hall_codes(void)
{
    write_zeros("recording.bin", 2u * 3000u);
    write_json("{\"sampling_frequency\": 30000, \"num_channels\": 1, \"num_samples\": 3000, \"dtype\": \"int16\",\n"
               " \"gain_uV\": 0.195, \"file\": \"recording.bin\", \"scenario\": \"single_neuron\", \"seed\": 1,\n"
               " \"source\": \"microdrive-session\", \"electrode\": 0, \"intervals\": [\n"
               "  {\"index\": 0, \"start_sample\": 0, \"num_samples\": 1000, \"start_s\": 0.0, \"interval_id\": 1,"
               " \"cycle\": 0, \"depth_um\": 1000.194, \"hall_code\": 16656, \"complete\": true},\n"
               "  {\"index\": 1, \"start_sample\": 1000, \"num_samples\": 2000, \"start_s\": 1.3, \"interval_id\": 2,"
               " \"cycle\": null, \"depth_um\": null, \"hall_code\": null, \"complete\": false}]}\n");
    TEST_ASSERT_EQUAL_INT(MD_OK, open_rec(0.0, 0u));
    TEST_ASSERT_EQUAL_UINT(2u, g_rec.n_intervals);
    TEST_ASSERT_EQUAL_UINT64(1000u, g_rec.iv[1].start_sample);
    TEST_ASSERT_EQUAL_UINT64(2000u, g_rec.iv[1].num_samples);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 1000.194, g_rec.iv[0].depth_um);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 16656.0, g_rec.iv[0].hall_code);
    TEST_ASSERT_TRUE(isnan(g_rec.iv[1].depth_um));
    TEST_ASSERT_TRUE(isnan(g_rec.iv[1].hall_code));
    /* a cut recording (no list) knows no Hall code either */
    write_json("{\"sampling_frequency\": 30000, \"num_channels\": 1, \"dtype\": \"int16\"}\n");
    TEST_ASSERT_EQUAL_INT(MD_OK, open_rec(0.05, 0u));
    TEST_ASSERT_TRUE(isnan(g_rec.iv[0].hall_code));
}

static void test_file_field_relative_and_absolute(void)
{
    const int16_t v[4] = {1, -2, 3, -4};
    write_i16("other.bin", v, 4u);
    write_json("{\"sampling_frequency\": 1000, \"num_channels\": 1, \"dtype\": \"int16\", \"file\": \"other.bin\"}");
    TEST_ASSERT_EQUAL_INT(MD_OK, open_rec(0.004, 0u));
    char want[200];
    (void)snprintf(want, sizeof want, "%s/other.bin", g_dir);
    TEST_ASSERT_EQUAL_STRING(want, g_rec.bin_path);
    char json[400];
    (void)snprintf(json, sizeof json,
                   "{\"sampling_frequency\": 1000, \"num_channels\": 1, \"dtype\": \"int16\", \"file\": \"%s\"}", want);
    write_json(json);
    TEST_ASSERT_EQUAL_INT(MD_OK, open_rec(0.004, 0u));
    TEST_ASSERT_EQUAL_STRING(want, g_rec.bin_path);
    TEST_ASSERT_EQUAL_UINT64(4u, g_rec.total_samples);
    int16_t x[4];
    rec_conversion_t conv = {0u, 0u};
    TEST_ASSERT_EQUAL_INT(MD_OK, rec_read_interval(&g_rec, 0u, 0u, x, 4u, &conv, g_err, sizeof g_err));
    TEST_ASSERT_EQUAL_INT16(-4, x[3]);
}

/* float32 in µV (no gain_uV): counts of 1 µV, nearest with halves away from zero, clipped and non-finite counted */
static void test_float32_microvolts_rounding_clipping(void)
{
    const float v[] = {0.0f,     0.49f,    0.5f,      -0.5f,     1.5f,    2.5f, -2.5f,    12.34f,    32767.4f,
                       32767.5f, 40000.0f, -32768.4f, -32768.5f, -1.0e9f, NAN,  INFINITY, -INFINITY, 3.0f};
    const int16_t want[] = {0, 0, 1, -1, 2, 3, -3, 12, 32767, 32767, 32767, -32768, -32768, -32768, 0, 0, 0, 3};
    const size_t n = sizeof v / sizeof v[0];
    write_f32("recording.bin", v, n);
    write_json("{\"sampling_frequency\": 1000, \"num_channels\": 1, \"dtype\": \"float32\"}");
    TEST_ASSERT_EQUAL_INT(MD_OK, open_rec(0.018, 0u));
    TEST_ASSERT_EQUAL_INT(REC_DTYPE_FLOAT32, g_rec.dtype);
    TEST_ASSERT_EQUAL_STRING("float32", rec_dtype_name(g_rec.dtype));
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 1.0, g_rec.count_uv);
    TEST_ASSERT_EQUAL_UINT64(n, g_rec.total_samples);
    int16_t x[sizeof v / sizeof v[0]];
    rec_conversion_t conv = {5u, 7u}; /* counts are added */
    TEST_ASSERT_EQUAL_INT(MD_OK, rec_read_interval(&g_rec, 0u, 0u, x, n, &conv, g_err, sizeof g_err));
    for (size_t i = 0u; i < n; ++i) {
        char m[64];
        (void)snprintf(m, sizeof m, "sample %zu", i);
        TEST_ASSERT_EQUAL_INT_MESSAGE(want[i], x[i], m);
    }
    TEST_ASSERT_EQUAL_UINT64(5u + 4u, conv.clipped);    /* 32767.5, 40000, -32768.5, -1e9 */
    TEST_ASSERT_EQUAL_UINT64(7u + 3u, conv.non_finite); /* NaN, +inf, -inf */
}

/* float32 in units of gain_uV: at or below 1 µV the unit is the count; coarser units are converted to 1 µV counts */
static void test_float32_gain(void)
{
    const float counts[6] = {12.0f, -7.0f, 100.4f, 100.6f, 5.0f, -5.0f}; /* 2 channels */
    write_f32("recording.bin", counts, 6u);
    write_json("{\"sampling_frequency\": 1000, \"num_channels\": 2, \"dtype\": \"float32\", \"gain_uV\": 0.195}");
    TEST_ASSERT_EQUAL_INT(MD_OK, open_rec(0.003, 0u));
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.195, g_rec.count_uv);
    int16_t x[3];
    rec_conversion_t conv = {0u, 0u};
    TEST_ASSERT_EQUAL_INT(MD_OK, rec_read_interval(&g_rec, 0u, 1u, x, 3u, &conv, g_err, sizeof g_err));
    TEST_ASSERT_EQUAL_INT(-7, x[0]);
    TEST_ASSERT_EQUAL_INT(101, x[1]);
    TEST_ASSERT_EQUAL_INT(-5, x[2]);
    /* volts: 1 unit = 1e6 µV, delivered as 1 µV counts */
    const float volts[3] = {1.2e-5f, -3.0e-4f, 0.04f};
    write_f32("recording.bin", volts, 3u);
    write_json("{\"sampling_frequency\": 1000, \"num_channels\": 1, \"dtype\": \"float32\", \"gain_uV\": 1e6}");
    TEST_ASSERT_EQUAL_INT(MD_OK, open_rec(0.003, 0u));
    TEST_ASSERT_DOUBLE_WITHIN(0.0, REC_F32_MAX_COUNT_UV, g_rec.count_uv);
    TEST_ASSERT_EQUAL_INT(MD_OK, rec_read_interval(&g_rec, 0u, 0u, x, 3u, &conv, g_err, sizeof g_err));
    TEST_ASSERT_EQUAL_INT(12, x[0]);
    TEST_ASSERT_EQUAL_INT(-300, x[1]);
    TEST_ASSERT_EQUAL_INT(32767, x[2]); /* 40 mV */
    TEST_ASSERT_EQUAL_UINT64(1u, conv.clipped);
}

/* ---------------------------------------------------------------- not JSON */

static void test_not_json(void)
{
    write_zeros("recording.bin", 4000u);
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json",
                      "not a JSON object: invalid JSON at byte offset 23 (line 1, column 24), in "
                      "\"sampling_frequency\": NaN is not a JSON number",
                      "{\"sampling_frequency\": NaN, \"num_channels\": 1, \"dtype\": \"int16\"}");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json",
                      "at byte offset 31 (line 1, column 32), in \"gain_uV\": Infinity is not a JSON number",
                      "{\"num_channels\": 1, \"gain_uV\": -Infinity}");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json",
                      "at byte offset 16 (line 2, column 4), in \"a\": unexpected end of file", "{\"a\": [1, 2,\n   ");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json",
                      "at byte offset 8 (line 1, column 9): unexpected character ',', expected a key in double quotes",
                      "{\"a\": 1,, \"b\": 2}");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json", "at byte offset 9 (line 2, column 1): text after the JSON value",
                      "{\"a\": 1}\n{\"b\": 2}");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json", "empty file", "");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json", "not a JSON object: the top level is a string", "\"int16\"");
    write_bytes("recording.json", (const uint8_t *)"{\"a\": 1}\0{}", 11u);
    check_error(MD_E_FRAME, open_rec(10.0, 0u), "recording.json", "NUL byte at byte offset 8", __LINE__);
    /* a byte that is not printable ASCII is shown escaped */
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json",
                      "at byte offset 6 (line 1, column 7), in \"a\": unexpected character '\\x7f', expected a value",
                      "{\"a\": \x7f}");
    /* what cJSON alone would take: not JSON */
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json",
                      "at byte offset 6 (line 1, column 7), in \"a\": unexpected character '+', expected a value",
                      "{\"a\": +1}");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json",
                      "at byte offset 6 (line 1, column 7), in \"a\": a number cannot start with 0 followed by digits",
                      "{\"a\": 0030000}");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json", "at byte offset 8 (line 1, column 9), in \"a\": control character",
                      "{\"a\": \"x\ty\"}");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json",
                      "at byte offset 5 (line 1, column 6), in \"a\": unexpected character '\\x01'", "{\"a\":\x01 1}");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json", "at byte offset 8 (line 1, column 9), in \"a\": invalid escape",
                      "{\"a\": \"x\\q\"}");
    EXPECT_OPEN_ERROR(
        MD_E_FRAME, "recording.json",
        "at byte offset 27 (line 2, column 3), after \"sampling_frequency\": unexpected character '\\x22', "
        "expected ',' or '}'",
        "{\"sampling_frequency\": 1\n  \"num_channels\": 1}");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json",
                      "at byte offset 4 (line 1, column 5): unexpected end of file in a string", "{\"ab");
    char missing[160];
    (void)snprintf(missing, sizeof missing, "%s/recording.json", g_dir);
    (void)remove(missing);
    check_error(MD_E_IO, open_rec(10.0, 0u), "recording.json", "cannot open: No such file", __LINE__);
    TEST_ASSERT_EQUAL_INT(0, mkdir(missing, 0700));
    check_error(MD_E_IO, open_rec(10.0, 0u), "recording.json", "not a regular file", __LINE__);
    TEST_ASSERT_EQUAL_INT(0, rmdir(missing));
}

/* ---------------------------------------------------------------- bad fields */

static void test_bad_sampling_frequency(void)
{
    write_zeros("recording.bin", 4000u);
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json", "field \"sampling_frequency\": missing",
                      "{\"num_channels\": 1, \"dtype\": \"int16\"}");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json", "field \"sampling_frequency\": not a number (a string)",
                      "{\"sampling_frequency\": \"30000\", \"num_channels\": 1, \"dtype\": \"int16\"}");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json", "field \"sampling_frequency\": not a number (null)",
                      "{\"sampling_frequency\": null, \"num_channels\": 1, \"dtype\": \"int16\"}");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json", "field \"sampling_frequency\": must be > 0 Hz, got -30000",
                      "{\"sampling_frequency\": -30000, \"num_channels\": 1, \"dtype\": \"int16\"}");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json", "field \"sampling_frequency\": must be > 0 Hz, got 0",
                      "{\"sampling_frequency\": 0, \"num_channels\": 1, \"dtype\": \"int16\"}");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json", "field \"sampling_frequency\": 500 Hz is outside 1000..200000 Hz",
                      "{\"sampling_frequency\": 500, \"num_channels\": 1, \"dtype\": \"int16\"}");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json", "field \"sampling_frequency\": inf is not a finite number",
                      "{\"sampling_frequency\": 1e999, \"num_channels\": 1, \"dtype\": \"int16\"}");
}

static void test_bad_channels_dtype_gain(void)
{
    write_zeros("recording.bin", 4000u);
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json", "field \"num_channels\": missing",
                      "{\"sampling_frequency\": 30000, \"dtype\": \"int16\"}");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json", "field \"num_channels\": 0 is not an integer 1..1024",
                      "{\"sampling_frequency\": 30000, \"num_channels\": 0, \"dtype\": \"int16\"}");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json", "field \"num_channels\": 2.5 is not an integer 1..1024",
                      "{\"sampling_frequency\": 30000, \"num_channels\": 2.5, \"dtype\": \"int16\"}");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json", "field \"num_channels\": 4096 is not an integer 1..1024",
                      "{\"sampling_frequency\": 30000, \"num_channels\": 4096, \"dtype\": \"int16\"}");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json", "field \"dtype\": missing",
                      "{\"sampling_frequency\": 30000, \"num_channels\": 1}");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json", "field \"dtype\": not a string (a number)",
                      "{\"sampling_frequency\": 30000, \"num_channels\": 1, \"dtype\": 16}");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json",
                      "field \"dtype\": \"float64\" is not supported (int16 or float32, little-endian)",
                      "{\"sampling_frequency\": 30000, \"num_channels\": 1, \"dtype\": \"float64\"}");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json", "field \"dtype\": \">i2\" is not supported",
                      "{\"sampling_frequency\": 30000, \"num_channels\": 1, \"dtype\": \">i2\"}");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json", "field \"gain_uV\": must be > 0, got 0",
                      "{\"sampling_frequency\": 30000, \"num_channels\": 1, \"dtype\": \"int16\", \"gain_uV\": 0}");
    EXPECT_OPEN_ERROR(
        MD_E_FRAME, "recording.json", "field \"gain_uV\": must be > 0, got -0.195",
        "{\"sampling_frequency\": 30000, \"num_channels\": 1, \"dtype\": \"int16\", \"gain_uV\": -0.195}");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json", "field \"gain_uV\": not a number (a string)",
                      "{\"sampling_frequency\": 30000, \"num_channels\": 1, \"dtype\": \"int16\", \"gain_uV\": \"1\"}");
    EXPECT_OPEN_ERROR(
        MD_E_FRAME, "recording.json", "field \"offset_uV\": not a number (true/false)",
        "{\"sampling_frequency\": 30000, \"num_channels\": 1, \"dtype\": \"int16\", \"offset_uV\": true}");
    EXPECT_OPEN_ERROR(
        MD_E_FRAME, "recording.json", "field \"byte_order\": \"big\" is not supported (only \"little\")",
        "{\"sampling_frequency\": 30000, \"num_channels\": 1, \"dtype\": \"int16\", \"byte_order\": \"big\"}");
    EXPECT_OPEN_ERROR(
        MD_E_FRAME, "recording.json", "field \"layout\": \"planar\" is not supported (only \"interleaved\")",
        "{\"sampling_frequency\": 30000, \"num_channels\": 1, \"dtype\": \"int16\", \"layout\": \"planar\"}");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json", "field \"seed\": -1 is not an integer",
                      "{\"sampling_frequency\": 30000, \"num_channels\": 1, \"dtype\": \"int16\", \"seed\": -1}");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json", "field \"scenario\": not a string (an array)",
                      "{\"sampling_frequency\": 30000, \"num_channels\": 1, \"dtype\": \"int16\", \"scenario\": []}");
    EXPECT_OPEN_ERROR(
        MD_E_FRAME, "recording.json", "field \"dtype\": given 2 times",
        "{\"sampling_frequency\": 30000, \"num_channels\": 1, \"dtype\": \"int16\", \"dtype\": \"float32\"}");
    write_json("{\"sampling_frequency\": 30000, \"num_channels\": 2, \"dtype\": \"int16\"}");
    check_error(MD_E_ARG, open_rec(0.01, 3u), "recording.json",
                "channel 3 requested, but the recording has 2 channel(s)", __LINE__);
}

/* ---------------------------------------------------------------- bad binary */

static void test_bad_binary(void)
{
    const char *mono = "{\"sampling_frequency\": 1000, \"num_channels\": 1, \"dtype\": \"int16\"}";
    const char *stereo = "{\"sampling_frequency\": 1000, \"num_channels\": 2, \"dtype\": \"int16\"}";
    const char *f32 = "{\"sampling_frequency\": 1000, \"num_channels\": 1, \"dtype\": \"float32\"}";
    EXPECT_OPEN_ERROR(MD_E_IO, "recording.bin", "cannot open: No such file", mono);
    write_zeros("recording.bin", 0u);
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.bin", "empty (0 bytes)", mono);
    write_zeros("recording.bin", 4001u);
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.bin",
                      "4001 bytes is not a whole number of 2-byte frames (1 channel(s) of int16); 1 byte(s) left over",
                      mono);
    write_zeros("recording.bin", 4002u);
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.bin",
                      "4002 bytes is not a whole number of 4-byte frames (2 channel(s) of int16); 2 byte(s) left over",
                      stereo);
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.bin",
                      "4002 bytes is not a whole number of 4-byte frames (1 channel(s) of float32)", f32);
    write_zeros("recording.bin", 4000u);
    EXPECT_OPEN_ERROR(
        MD_E_FRAME, "recording.json", "field \"num_samples\": 2001, but ",
        "{\"sampling_frequency\": 1000, \"num_channels\": 1, \"dtype\": \"int16\", \"num_samples\": 2001}");
    TEST_ASSERT_NOT_NULL(strstr(g_err, "recording.bin holds 2000 samples per channel"));
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json", "field \"file\": empty",
                      "{\"sampling_frequency\": 1000, \"num_channels\": 1, \"dtype\": \"int16\", \"file\": \"\"}");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json", "field \"file\": not a string (a number)",
                      "{\"sampling_frequency\": 1000, \"num_channels\": 1, \"dtype\": \"int16\", \"file\": 1}");
    EXPECT_OPEN_ERROR(MD_E_IO, ".", "not a regular file",
                      "{\"sampling_frequency\": 1000, \"num_channels\": 1, \"dtype\": \"int16\", \"file\": \".\"}");
    EXPECT_OPEN_ERROR(
        MD_E_IO, "nothing.bin", "cannot open",
        "{\"sampling_frequency\": 1000, \"num_channels\": 1, \"dtype\": \"int16\", \"file\": \"nothing.bin\"}");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json", "no interval of 10 s fits in the 2000 samples per channel of ",
                      mono);
    /* the binary shrinks after the sidecar was read */
    TEST_ASSERT_EQUAL_INT(MD_OK, open_rec(1.0, 0u));
    write_zeros("recording.bin", 3000u);
    int16_t x[1000];
    rec_conversion_t conv = {0u, 0u};
    check_error(MD_E_IO, rec_read_interval(&g_rec, 1u, 0u, x, 1000u, &conv, g_err, sizeof g_err), "recording.bin",
                "interval 1 (samples 1000..1999): short read", __LINE__);
    check_error(MD_E_ARG, rec_read_interval(&g_rec, 0u, 0u, x, 999u, &conv, g_err, sizeof g_err), "recording.bin",
                "bad arguments", __LINE__);
    check_error(MD_E_ARG, rec_read_interval(&g_rec, 2u, 0u, x, 1000u, &conv, g_err, sizeof g_err), "recording.bin",
                "bad arguments", __LINE__);
    check_error(MD_E_ARG, rec_read_interval(&g_rec, 0u, 1u, x, 1000u, &conv, g_err, sizeof g_err), "recording.bin",
                "bad arguments", __LINE__);
}

/* ---------------------------------------------------------------- bad intervals */

#define HEAD "{\"sampling_frequency\": 1000, \"num_channels\": 2, \"dtype\": \"int16\", "

static void test_bad_intervals(void)
{
    write_zeros("recording.bin", 4000u); /* 1000 frames */
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json", "field \"intervals\": not an array (an object)",
                      HEAD "\"intervals\": {}}");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json", "field \"intervals[1]\": not an object (a number)",
                      HEAD "\"intervals\": [{\"start_sample\": 0, \"num_samples\": 10}, 3]}");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json", "field \"intervals[0].start_sample\": missing",
                      HEAD "\"intervals\": [{\"num_samples\": 10}]}");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json", "field \"intervals[0].start_sample\": -1 is not an integer",
                      HEAD "\"intervals\": [{\"start_sample\": -1, \"num_samples\": 10}]}");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json", "field \"intervals[0].num_samples\": 0.5 is not an integer 1..",
                      HEAD "\"intervals\": [{\"start_sample\": 0, \"num_samples\": 0.5}]}");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json", "field \"intervals[1]\": samples 990..1009 are past the end of ",
                      HEAD "\"intervals\": [{\"start_sample\": 0, \"num_samples\": 10}, "
                           "{\"start_sample\": 990, \"num_samples\": 20}]}");
    TEST_ASSERT_NOT_NULL(strstr(g_err, "recording.bin (1000 samples per channel)"));
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json", "field \"intervals[0].duration_s\": must be > 0, got 0",
                      HEAD "\"intervals\": [{\"start_sample\": 0, \"num_samples\": 10, \"duration_s\": 0}]}");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json", "field \"intervals[0].depth_um\": 3 entries for 2 channel(s)",
                      HEAD "\"intervals\": [{\"start_sample\": 0, \"num_samples\": 10, \"depth_um\": [1, 2, 3]}]}");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json",
                      "field \"intervals[0].depth_um[1]\": not a finite number or null (a string)",
                      HEAD "\"intervals\": [{\"start_sample\": 0, \"num_samples\": 10, \"depth_um\": [1, \"2\"]}]}");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json", "field \"intervals[0].hall_code\": not a number (a string)",
                      HEAD "\"intervals\": [{\"start_sample\": 0, \"num_samples\": 10, \"hall_code\": \"x\"}]}");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json", "field \"intervals[0].hall_code\": 1 entries for 2 channel(s)",
                      HEAD "\"intervals\": [{\"start_sample\": 0, \"num_samples\": 10, \"hall_code\": [1]}]}");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json", "field \"intervals[0].depth_um\": not a number (an object)",
                      HEAD "\"intervals\": [{\"start_sample\": 0, \"num_samples\": 10, \"depth_um\": {}}]}");
    EXPECT_OPEN_ERROR(MD_E_FRAME, "recording.json", "field \"intervals[0].num_samples\": given 2 times",
                      HEAD "\"intervals\": [{\"start_sample\": 0, \"num_samples\": 10, \"num_samples\": 20}]}");
    /* a tool that needs the list */
    write_json(HEAD "\"intervals\": []}");
    check_error(MD_E_FRAME, open_rec(0.0, 0u), "recording.json", "field \"intervals\": empty", __LINE__);
    write_json(HEAD "\"seed\": 1}");
    check_error(MD_E_FRAME, open_rec(0.0, 0u), "recording.json", "field \"intervals\": missing", __LINE__);
}

static void test_too_many_intervals(void)
{
    write_zeros("recording.bin", 2u * 2u * (REC_MAX_INTERVALS + 1u));
    const size_t cap = 64u * (REC_MAX_INTERVALS + 2u);
    char *json = malloc(cap);
    TEST_ASSERT_NOT_NULL(json);
    size_t n = (size_t)snprintf(json, cap, HEAD "\"intervals\": [");
    for (uint32_t k = 0u; k <= REC_MAX_INTERVALS; ++k) {
        n += (size_t)snprintf(&json[n], cap - n, "%s{\"start_sample\": %u, \"num_samples\": 1}", (k > 0u) ? "," : "",
                              k);
    }
    (void)snprintf(&json[n], cap - n, "]}");
    write_json(json);
    free(json);
    check_error(MD_E_FRAME, open_rec(0.0, 0u), "recording.json", "field \"intervals\": more than 4096 intervals",
                __LINE__);
}

/* A "file" field may hold any byte; the message naming it stays one line. */
static void test_control_bytes_of_a_path_stay_on_one_line(void)
{
    EXPECT_OPEN_ERROR(MD_E_IO, "no\\x0abin\\x09x", "cannot open",
                      "{\"sampling_frequency\": 1000, \"num_channels\": 1, \"dtype\": \"int16\", "
                      "\"file\": \"no\\nbin\\tx\"}");
}

int main(void)
{
    (void)snprintf(g_dir, sizeof g_dir, "/tmp/test_recording.XXXXXX");
    if (mkdtemp(g_dir) == NULL) {
        perror("mkdtemp");
        return 1;
    }
    (void)snprintf(g_json, sizeof g_json, "%s/recording.json", g_dir);
    (void)snprintf(g_bin, sizeof g_bin, "%s/recording.bin", g_dir);
    UNITY_BEGIN();
    RUN_TEST(test_int16_minimal_sidecar_is_cut_into_intervals);
    RUN_TEST(test_export_sidecar_with_interval_list);
    RUN_TEST(test_session_sidecar_with_hall_codes);
    RUN_TEST(test_file_field_relative_and_absolute);
    RUN_TEST(test_float32_microvolts_rounding_clipping);
    RUN_TEST(test_float32_gain);
    RUN_TEST(test_not_json);
    RUN_TEST(test_bad_sampling_frequency);
    RUN_TEST(test_bad_channels_dtype_gain);
    RUN_TEST(test_bad_binary);
    RUN_TEST(test_bad_intervals);
    RUN_TEST(test_too_many_intervals);
    RUN_TEST(test_control_bytes_of_a_path_stay_on_one_line);
    const int rc = UNITY_END();
    (void)rmdir(g_dir);
    return rc;
}
