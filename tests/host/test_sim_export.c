/* Host unit: recording export — the files exist with consistent sizes, the
 * ground truth points into the recording, and the same scenario + seed give
 * byte-identical files (another seed does not). */
#define _POSIX_C_SOURCE 200809L
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "export/sim_export.h"
#include "unity.h"

static scenario_t sc;
static char err[1024];

static const char *FILES[4] = {"recording.bin", "recording.json", "ground_truth.csv", "ground_truth.jsonl"};

/* The export folders and file contents of the running test. tearDown removes
 * and frees them, also when a failed assertion ended the test first. */
#define MAX_DIRS 3
#define MAX_BUFS 3
static char g_dir[MAX_DIRS][64];
static int g_n_dirs;
static char *g_buf[MAX_BUFS];

static void cleanup(const char *dir)
{
    char path[512];
    for (int i = 0; i < 4; ++i) {
        (void)snprintf(path, sizeof path, "%s/%s", dir, FILES[i]);
        (void)remove(path);
    }
    (void)remove(dir);
}

static void free_bufs(void)
{
    for (int i = 0; i < MAX_BUFS; ++i) {
        free(g_buf[i]);
        g_buf[i] = NULL;
    }
}

void setUp(void)
{
    g_n_dirs = 0;
}

void tearDown(void)
{
    free_bufs();
    for (int i = 0; i < g_n_dirs; ++i) {
        cleanup(g_dir[i]);
    }
    g_n_dirs = 0;
}

static char *slurp(const char *dir, const char *name, size_t *len)
{
    char path[512];
    (void)snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *f = fopen(path, "rb");
    if (f == NULL) {
        return NULL;
    }
    (void)fseek(f, 0, SEEK_END);
    const long n = ftell(f);
    (void)fseek(f, 0, SEEK_SET);
    char *buf = malloc((size_t)n + 1u);
    if (buf != NULL) {
        *len = fread(buf, 1u, (size_t)n, f);
        buf[*len] = '\0';
    }
    (void)fclose(f);
    return buf;
}

static void make_scenario(void)
{
    static const char y[] = "name: export_test\n"
                            "seed: 11\n"
                            "signal: {large_artifact_rate_hz: 2}\n"
                            "electrodes:\n"
                            "  - start_um: 1150\n"
                            "    neurons: [{depth_um: 1200, x_um: 20, rate_hz: 30}]\n"
                            "  - start_um: 1000\n"
                            "    random_neurons: {count: 5, depth_min_um: 950, depth_max_um: 1100}\n"
                            "export: {intervals: 3, interval_s: 0.5, step_um: 15, settle_s: 0.2}\n";
    TEST_ASSERT_EQUAL_INT(0, scenario_parse(&sc, y, sizeof y - 1u, "export.yaml", err, sizeof err));
}

/* Exports the scenario with `seed` into a new temporary folder (removed by
 * tearDown) and returns the folder. */
static const char *export_new(uint64_t seed)
{
    TEST_ASSERT_LESS_THAN_INT(MAX_DIRS, g_n_dirs);
    char *dir = g_dir[g_n_dirs];
    strcpy(dir, "/tmp/test_sim_export_XXXXXX");
    TEST_ASSERT_NOT_NULL(mkdtemp(dir));
    g_n_dirs++;
    const md_status_t st = sim_export_recording(&sc, seed, dir, err, sizeof err);
    if (st != MD_OK) {
        TEST_MESSAGE(err);
    }
    TEST_ASSERT_EQUAL_INT(MD_OK, st);
    return dir;
}

static void test_same_seed_gives_byte_identical_files(void)
{
    make_scenario();
    const char *d1 = export_new(11u);
    const char *d2 = export_new(11u);
    const char *d3 = export_new(12u);
    for (int i = 0; i < 4; ++i) {
        size_t n1 = 0u, n2 = 0u, n3 = 0u;
        free_bufs();
        char *a = g_buf[0] = slurp(d1, FILES[i], &n1);
        char *b = g_buf[1] = slurp(d2, FILES[i], &n2);
        char *c = g_buf[2] = slurp(d3, FILES[i], &n3);
        TEST_ASSERT_NOT_NULL(a);
        TEST_ASSERT_NOT_NULL(b);
        TEST_ASSERT_NOT_NULL(c);
        TEST_ASSERT_TRUE(n1 > 0u);
        TEST_ASSERT_EQUAL_size_t(n1, n2);
        TEST_ASSERT_EQUAL_MEMORY(a, b, n1);
        if (i == 0) { /* another seed: another recording of the same size */
            TEST_ASSERT_EQUAL_size_t(n1, n3);
            TEST_ASSERT_TRUE(memcmp(a, c, n1) != 0);
        }
    }
}

static void test_files_are_consistent(void)
{
    make_scenario();
    const char *d = export_new(11u);
    size_t nbin = 0u, njson = 0u, ncsv = 0u;
    const char *bin = g_buf[0] = slurp(d, "recording.bin", &nbin);
    const char *json = g_buf[1] = slurp(d, "recording.json", &njson);
    const char *csv = g_buf[2] = slurp(d, "ground_truth.csv", &ncsv);
    TEST_ASSERT_NOT_NULL(bin);
    TEST_ASSERT_NOT_NULL(json);
    TEST_ASSERT_NOT_NULL(csv);
    const size_t samples = 3u * 15000u; /* 3 intervals of 0.5 s at 30 kHz */
    TEST_ASSERT_EQUAL_size_t(samples * 2u * sizeof(int16_t), nbin);
    TEST_ASSERT_NOT_NULL(strstr(json, "\"sampling_frequency\": 30000.000"));
    TEST_ASSERT_NOT_NULL(strstr(json, "\"num_channels\": 2"));
    TEST_ASSERT_NOT_NULL(strstr(json, "\"num_samples\": 45000"));
    TEST_ASSERT_NOT_NULL(strstr(json, "\"dtype\": \"int16\""));
    TEST_ASSERT_NOT_NULL(strstr(json, "\"gain_uV\": 0.195000"));
    TEST_ASSERT_NOT_NULL(strstr(json, "\"start_sample\": 30000"));
    TEST_ASSERT_EQUAL_INT(0, strncmp(csv, "sample_index,channel,neuron_id\n", 31));
    /* every row points into the file, rows ordered, neuron 0 of channel 0 at ~30 Hz */
    const char *p = csv + 31;
    unsigned long long s, prev = 0u;
    unsigned ch;
    int id, rows = 0, ch0 = 0;
    int used = 0;
    while (sscanf(p, "%llu,%u,%d\n%n", &s, &ch, &id, &used) == 3) {
        TEST_ASSERT_TRUE(s < samples);
        TEST_ASSERT_TRUE(ch < 2u);
        TEST_ASSERT_TRUE(id >= 0);
        TEST_ASSERT_TRUE(s >= prev);
        prev = s;
        rows++;
        ch0 += (ch == 0u && id == 0);
        p += used;
    }
    TEST_ASSERT_EQUAL_INT('\0', *p);
    TEST_ASSERT_TRUE(ch0 > 20 && ch0 < 80); /* 30 Hz over 1.5 s */
    TEST_ASSERT_TRUE(rows > ch0);           /* the random neurons of channel 1 fire too */
}

static void test_bad_directory_is_reported(void)
{
    make_scenario();
    TEST_ASSERT_EQUAL_INT(MD_E_IO, sim_export_recording(&sc, 1u, "/proc/no/such/dir", err, sizeof err));
    TEST_ASSERT_NOT_NULL(strstr(err, "/proc/no/such/dir"));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_same_seed_gives_byte_identical_files);
    RUN_TEST(test_files_are_consistent);
    RUN_TEST(test_bad_directory_is_reported);
    return UNITY_END();
}
