/// @file fuzz_recording.c
/// Fuzz target: the recording reader (tools/recording/recording.h), the one
/// reader of a JSON sidecar and its binary used by mhtc-replay and
/// cluster-consistency. The input is written as two files in a private
/// folder (/dev/shm, else /tmp) and read through the real API:
///   byte 0    options: bits 0-1 interval_s {0 (list required), 0.002, 0.1, 1},
///             bits 2-3 channel {0, 1, 3, 1023}, bit 4 no binary on disk
///   bytes 1-2 length L of the binary (little-endian, taken modulo what is left + 1)
///   L bytes   recording.bin
///   the rest  recording.json (the sidecar text, as is)
/// Invariants: a documented status; a refusal is one line "PATH: reason"
/// naming the sidecar or the binary; an accepted sidecar has fields in their
/// documented ranges and intervals inside the binary; every interval of the
/// requested channel reads back as the independent decoding of the bytes
/// (int16 as stored, float32 rounded, clipped and counted as recording.h says).
#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "fuzz_input.h"
#include "recording.h"

#define READ_CAP (1u << 16)  ///< samples read per interval at most (longer ones are skipped)

static char g_dir[64];
static char g_json[128];
static char g_bin[128];
static rec_recording_t g_rec;
static int16_t g_x[READ_CAP];

static void cleanup(void)
{
    (void)unlink(g_json);
    (void)unlink(g_bin);
    (void)rmdir(g_dir);
}

static void setup_once(void)
{
    if (g_dir[0] != '\0') {
        return;
    }
    (void)snprintf(g_dir, sizeof g_dir, "/dev/shm/fuzz_recording.XXXXXX");
    if (mkdtemp(g_dir) == NULL) {
        (void)snprintf(g_dir, sizeof g_dir, "/tmp/fuzz_recording.XXXXXX");
        FUZZ_CHECK(mkdtemp(g_dir) != NULL);
    }
    (void)snprintf(g_json, sizeof g_json, "%s/recording.json", g_dir);
    (void)snprintf(g_bin, sizeof g_bin, "%s/recording.bin", g_dir);
    (void)atexit(cleanup);
}

static void write_file(const char *path, const uint8_t *p, size_t n)
{
    FILE *f = fopen(path, "wb");
    FUZZ_CHECK(f != NULL);
    FUZZ_CHECK(n == 0u || fwrite(p, 1u, n, f) == n);
    FUZZ_CHECK(fclose(f) == 0);
}

/* "PATH: reason" with a non-empty reason; control bytes of PATH written as \xNN. */
static bool names(const char *err, const char *raw_path)
{
    char path[4u * REC_PATH_MAX + 1u];
    size_t n = 0u;
    for (const unsigned char *p = (const unsigned char *)raw_path; *p != '\0'; ++p) {
        n += (*p < 0x20u || *p == 0x7fu) ? (size_t)sprintf(&path[n], "\\x%02x", *p) : (path[n] = (char)*p, 1u);
    }
    path[n] = '\0';
    return n > 0u && strncmp(err, path, n) == 0 && err[n] == ':' && err[n + 1u] == ' ' && err[n + 2u] != '\0';
}

/* A refusal: one line "PATH: reason" where PATH is the sidecar or the binary. */
static void check_message(const char *err)
{
    FUZZ_CHECK(strlen(err) < REC_ERR_MAX);
    const bool ok = strchr(err, '\n') == NULL && (names(err, g_json) || names(err, g_rec.bin_path));
    if (!ok) {
        (void)fprintf(stderr, "not one \"PATH: reason\" line: '%s'\n", err);
    }
    FUZZ_CHECK(ok);
}

static void check_accepted(const rec_options_t *opt)
{
    const rec_recording_t *r = &g_rec;
    FUZZ_CHECK(strcmp(r->json_path, g_json) == 0);
    FUZZ_CHECK(isfinite(r->fs_hz) && r->fs_hz >= REC_FS_MIN_HZ && r->fs_hz <= REC_FS_MAX_HZ);
    FUZZ_CHECK(r->n_channels >= 1u && r->n_channels <= REC_MAX_CHANNELS && opt->channel < r->n_channels);
    FUZZ_CHECK(r->dtype == REC_DTYPE_INT16 || r->dtype == REC_DTYPE_FLOAT32);
    FUZZ_CHECK(isfinite(r->gain_uv) && r->gain_uv > 0.0);
    const double want_count = (r->dtype == REC_DTYPE_FLOAT32 && r->gain_uv > REC_F32_MAX_COUNT_UV)
                                  ? REC_F32_MAX_COUNT_UV
                                  : r->gain_uv;
    FUZZ_CHECK(!(r->count_uv < want_count) && !(r->count_uv > want_count));
    FUZZ_CHECK(memchr(r->scenario, '\0', sizeof r->scenario) != NULL);
    FUZZ_CHECK(memchr(r->bin_path, '\0', sizeof r->bin_path) != NULL && r->bin_path[0] != '\0');
    FUZZ_CHECK(r->total_samples > 0u);
    FUZZ_CHECK(r->n_intervals >= 1u && r->n_intervals <= REC_MAX_INTERVALS);
    FUZZ_CHECK(r->interval_list == 0 || r->interval_list == 1);
    FUZZ_CHECK(r->interval_list == 1 || opt->interval_s > 0.0);
    for (uint32_t k = 0u; k < r->n_intervals; ++k) {
        const rec_interval_t *iv = &r->iv[k];
        FUZZ_CHECK(iv->num_samples >= 1u && iv->start_sample <= r->total_samples &&
                   iv->num_samples <= r->total_samples - iv->start_sample);
        FUZZ_CHECK(isfinite(iv->duration_s) && iv->duration_s > 0.0);
        FUZZ_CHECK(isnan(iv->depth_um) || isfinite(iv->depth_um));
    }
}

/* recording.h's conversion of one stored sample, written independently. */
static int16_t expect_sample(const uint8_t *b, rec_dtype_t dt, double scale, rec_conversion_t *conv)
{
    if (dt == REC_DTYPE_INT16) {
        return (int16_t)(uint16_t)(b[0] | (b[1] << 8));
    }
    const uint32_t u = (uint32_t)b[0] | ((uint32_t)b[1] << 8) | ((uint32_t)b[2] << 16) | ((uint32_t)b[3] << 24);
    float v;
    memcpy(&v, &u, sizeof v);
    if (isnan(v) || isinf(v)) {
        conv->non_finite++;
        return 0;
    }
    const double y = (double)v * scale;
    double r = floor(fabs(y) + 0.5); /* halves away from zero */
    r = (y < 0.0) ? -r : r;
    if (r > 32767.0 || r < -32768.0) {
        conv->clipped++;
        return (r > 0.0) ? INT16_MAX : INT16_MIN;
    }
    return (int16_t)r;
}

/* Reads every interval of opt->channel and compares with the bytes on disk. */
static void check_samples(const rec_options_t *opt, const uint8_t *file, size_t file_len)
{
    const rec_recording_t *r = &g_rec;
    const size_t bps = (r->dtype == REC_DTYPE_FLOAT32) ? 4u : 2u;
    const size_t frame = (size_t)r->n_channels * bps;
    FUZZ_CHECK(r->total_samples * frame == file_len);
    const double scale = r->gain_uv / r->count_uv;
    char err[REC_ERR_MAX];
    for (uint32_t k = 0u; k < r->n_intervals; ++k) {
        const rec_interval_t *iv = &r->iv[k];
        if (iv->num_samples > READ_CAP) {
            continue;
        }
        rec_conversion_t conv = {0u, 0u};
        rec_conversion_t want = {0u, 0u};
        /* one sample too little room is refused before anything is read */
        FUZZ_CHECK(rec_read_interval(r, k, opt->channel, g_x, (size_t)iv->num_samples - 1u, &conv, err, sizeof err) ==
                   MD_E_ARG);
        FUZZ_CHECK(rec_read_interval(r, k, opt->channel, g_x, READ_CAP, &conv, err, sizeof err) == MD_OK);
        for (uint64_t i = 0u; i < iv->num_samples; ++i) {
            const uint8_t *b = &file[(size_t)(iv->start_sample + i) * frame + (size_t)opt->channel * bps];
            FUZZ_CHECK(g_x[i] == expect_sample(b, r->dtype, scale, &want));
        }
        FUZZ_CHECK(conv.clipped == want.clipped && conv.non_finite == want.non_finite);
    }
    FUZZ_CHECK(rec_read_interval(r, r->n_intervals, opt->channel, g_x, READ_CAP, &(rec_conversion_t){0u, 0u}, err,
                                 sizeof err) == MD_E_ARG);
    FUZZ_CHECK(rec_read_interval(r, 0u, r->n_channels, g_x, READ_CAP, &(rec_conversion_t){0u, 0u}, err, sizeof err) ==
               MD_E_ARG);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static const double INTERVAL_S[4] = {0.0, 0.002, 0.1, 1.0};
    static const uint32_t CHANNEL[4] = {0u, 1u, 3u, 1023u};
    setup_once();
    fz_t f;
    fz_init(&f, data, size);
    const uint8_t o = fz_u8(&f);
    const rec_options_t opt = {INTERVAL_S[o & 3u], CHANNEL[(o >> 2) & 3u]};
    const bool no_bin = (o & 16u) != 0u;
    const size_t bin_len = (size_t)fz_u16(&f) % (fz_left(&f) + 1u);
    const uint8_t *bin = f.p;
    const uint8_t *json = f.p + bin_len;
    const size_t json_len = fz_left(&f) - bin_len;

    write_file(g_json, json, json_len);
    if (no_bin) {
        FUZZ_CHECK(unlink(g_bin) == 0 || errno == ENOENT);
    } else {
        write_file(g_bin, bin, bin_len);
    }

    char err[REC_ERR_MAX];
    const md_status_t st = rec_read_sidecar(g_json, &opt, &g_rec, err, sizeof err);
    FUZZ_CHECK(st == MD_OK || st == MD_E_IO || st == MD_E_FRAME || st == MD_E_ARG);
    if (st != MD_OK) {
        check_message(err);
        return 0;
    }
    FUZZ_CHECK(err[0] == '\0');
    check_accepted(&opt);
    /* Only files of this folder are compared ("file" may name any path: not read). */
    if (strcmp(g_rec.bin_path, g_bin) == 0 && !no_bin) {
        check_samples(&opt, bin, bin_len);
    } else if (strcmp(g_rec.bin_path, g_json) == 0) {
        check_samples(&opt, json, json_len);
    }
    return 0;
}
