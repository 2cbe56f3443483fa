/* md-bench-m7: the cycle stages of tools/bench/bench_core.h on the Cortex-M7
 * (QEMU mps2-an500), measured in instructions.
 *
 * QEMU models no DWT cycle counter. Run with `-icount shift=0`: virtual time
 * then advances exactly 1 ns per guest instruction, and SysTick (clocked from
 * the 25 MHz CPU clock, reload 2^24 - 1, wraps counted by its interrupt)
 * ticks once per 40 instructions. Each figure is therefore
 * ticks x 40 instructions, resolution 40 instructions. A calibration loop of
 * known length (CAL_ITERS x 2 instructions) is measured first so the reader
 * can check the scale (scripts/bench.sh does). Output, over semihosting:
 *   cal <measured instr> <expected instr>
 *   stage <name> instr <n> in_cycle <0|1>
 *   cycle instr <sum of the cycle's stages>
 * Without -icount the numbers are QEMU wall-clock ticks, not instructions.
 *
 * Replay mode (`-semihosting-config enable=on,target=native,arg=md-bench-m7,
 * arg=--replay,arg=PLAN,arg=SAMPLES`): the cycle over every interval of a
 * recording instead (bench_core.h, bench_replay_*), reading the samples from
 * the host file SAMPLES (int16, one channel, e.g. a session's recording.bin)
 * where the plan says. PLAN (tools/bench/replay_cost.py writes it; all
 * little-endian): "MDRP", version 1 (u32), sample rate in Hz (u32), number of
 * intervals (u32), gain in µV per count (f64); then per interval start sample
 * (u64), samples (u32), interval id (u32), depth in µm (f64, NaN unknown),
 * controller cycle (u32), complete (u32: 0 = the controller did not process
 * it). One line per interval:
 *   interval <k> id <id> cycle <c> samples <n> spikes <s> dominant <track>
 *   tracks <t> hyp <h> models <m> snr_bits <float32 bits> push <instr>
 *   end <instr> pca <instr> mhtc <instr> quality <instr> control <instr>
 *   status <OK, or the failing stage and its status: the cycle is skipped>
 * or "interval <k> id <id> cycle <c> incomplete" for one the controller did
 * not process; then "replay intervals <n> processed <m>". */
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "bench_core.h"
#include "md_m7_semihost.h"
#include "md_m7_startup.h"

#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)
#define SYST_CSR_ENABLE_TICKINT_CPUCLK 0x7u
#define RELOAD 0x00FFFFFFu
#define CPU_HZ 25000000u                   /* mps2-an500 SYSCLK, SysTick's CPU clock */
#define NS_PER_TICK (1000000000u / CPU_HZ) /* = instructions per tick under -icount shift=0 */
#define CAL_ITERS 5000000u

static volatile uint32_t g_wraps;

void SysTick_Handler(void)
{
    g_wraps = g_wraps + 1u;
}

/* Ticks since start, 64 bits; retried if a wrap lands between the reads. */
static uint64_t ticks_now(void)
{
    for (;;) {
        const uint32_t w = g_wraps;
        const uint32_t cvr = SYST_CVR;
        if (g_wraps == w) {
            return (uint64_t)w * ((uint64_t)RELOAD + 1u) + (uint64_t)(RELOAD - cvr);
        }
    }
}

static uint64_t instr_since(uint64_t t0)
{
    return (ticks_now() - t0) * NS_PER_TICK;
}

static void write_u64(uint64_t v)
{
    char buf[24];
    uint32_t i = 0u;
    do {
        buf[i++] = (char)('0' + (int)(v % 10u));
        v /= 10u;
    } while (v != 0u && i < 23u);
    char out[24];
    for (uint32_t k = 0u; k < i; ++k) {
        out[k] = buf[i - 1u - k];
    }
    out[i] = '\0';
    md_sh_write0(out);
}

/* Exactly 2 instructions per iteration (subs, bne). */
static void cal_loop(uint32_t n)
{
    __asm__ volatile("1: subs %0, %0, #1\n\tbne 1b" : "+r"(n) : : "cc");
}

#define CMDLINE_MAX 2048u
#define PLAN_MAGIC 0x5052444Du /* "MDRP" */
#define PLAN_VERSION 1u
#define PLAN_HEADER_BYTES 24u
#define PLAN_RECORD_BYTES 32u
#define REPLAY_MAX_INTERVALS 65535u
#define READ_CHUNK_BYTES 65536u

static char g_cmdline[CMDLINE_MAX];

static uint32_t le32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}

static uint64_t le64(const uint8_t *p)
{
    return (uint64_t)le32(p) | ((uint64_t)le32(p + 4) << 32);
}

static double le_f64(const uint8_t *p)
{
    const uint64_t u = le64(p);
    double d;
    memcpy(&d, &u, sizeof d);
    return d;
}

/* Reads exactly len bytes (bounded: one call per READ_CHUNK_BYTES). 0 if read. */
static int read_exact(int32_t h, void *buf, uint32_t len)
{
    uint8_t *p = (uint8_t *)buf;
    uint32_t done = 0u;
    while (done < len) {
        const uint32_t want = (len - done < READ_CHUNK_BYTES) ? (len - done) : READ_CHUNK_BYTES;
        if (md_sh_read(h, p + done, want) != (int32_t)want) {
            return -1;
        }
        done += want;
    }
    return 0;
}

/* The next space-separated word of the command line from *pos (NUL-terminated
 * in place), or NULL at its end. */
static char *next_word(char **pos)
{
    char *p = *pos;
    while (*p == ' ') {
        ++p;
    }
    if (*p == '\0') {
        *pos = p;
        return NULL;
    }
    char *w = p;
    while (*p != '\0' && *p != ' ') {
        ++p;
    }
    if (*p == ' ') {
        *p++ = '\0';
    }
    *pos = p;
    return w;
}

static void write_status(const char *what, md_status_t st)
{
    md_sh_write0(what);
    md_sh_write0(md_status_name(st));
}

/* The facts the replay computed for one interval (what the controller would
 * report) and each stage's instructions, on the interval's line. */
static void write_replay_facts(uint32_t n, const uint64_t *instr)
{
    bench_replay_info_t info;
    bench_replay_info(&info);
    uint32_t snr_bits = 0u;
    memcpy(&snr_bits, &info.snr, sizeof snr_bits);
    md_sh_write0(" samples ");
    md_sh_write_uint(n);
    md_sh_write0(" spikes ");
    md_sh_write_uint(info.n_spikes);
    md_sh_write0(" dominant ");
    md_sh_write_uint(info.dominant);
    md_sh_write0(" tracks ");
    md_sh_write_uint(info.n_tracks);
    md_sh_write0(" hyp ");
    md_sh_write_uint(info.n_hyp);
    md_sh_write0(" models ");
    md_sh_write_uint(info.models);
    md_sh_write0(" snr_bits ");
    md_sh_write_hex(snr_bits);
    for (unsigned s = 0u; s < (unsigned)BENCH_RP_COUNT; ++s) {
        md_sh_write0(" ");
        md_sh_write0(bench_replay_stage_name((bench_replay_stage_t)s));
        md_sh_write0(" ");
        write_u64(instr[s]);
    }
}

/* One interval of the plan: samples read, then every stage timed. 1 if the
 * controller's cycle processed it (every stage OK), 0 if not, -1 on an I/O error. */
static int replay_interval(int32_t samples, const uint8_t *rec, uint32_t k)
{
    const uint64_t start = le64(rec);
    const uint32_t n = le32(rec + 8);
    const uint32_t id = le32(rec + 12);
    const double depth = le_f64(rec + 16);
    const uint32_t cycle = le32(rec + 24);
    const uint32_t complete = le32(rec + 28);
    md_sh_write0("interval ");
    md_sh_write_uint(k);
    md_sh_write0(" id ");
    md_sh_write_uint(id);
    md_sh_write0(" cycle ");
    md_sh_write_uint(cycle);
    if (complete == 0u) {
        md_sh_write0(" incomplete\n");
        return 0;
    }
    size_t cap = 0u;
    int16_t *x = bench_replay_samples(&cap);
    if (n == 0u || n > cap || start > (uint64_t)(UINT32_MAX / 2u) - n) {
        md_sh_write0(" bad interval in the plan\n");
        return -1;
    }
    if (md_sh_seek(samples, (uint32_t)start * 2u) != 0 || read_exact(samples, x, n * 2u) != 0) {
        md_sh_write0(" cannot read its samples\n");
        return -1;
    }
    uint64_t instr[BENCH_RP_COUNT] = {0u};
    md_status_t st = bench_replay_interval(n, depth);
    unsigned failed = (st == MD_OK) ? (unsigned)BENCH_RP_COUNT : 0u;
    for (unsigned s = 0u; st == MD_OK && s < (unsigned)BENCH_RP_COUNT; ++s) {
        const uint64_t t0 = ticks_now();
        st = bench_replay_run((bench_replay_stage_t)s);
        instr[s] = instr_since(t0);
        failed = (st == MD_OK) ? failed : s;
    }
    write_replay_facts(n, instr);
    if (st == MD_OK) {
        md_sh_write0(" status OK\n");
        return 1;
    }
    md_sh_write0(" status ");
    md_sh_write0((failed < (unsigned)BENCH_RP_COUNT) ? bench_replay_stage_name((bench_replay_stage_t)failed) : "begin");
    write_status(":", st);
    md_sh_write0("\n");
    return 0;
}

/* Replay mode: every interval of the plan. 0 if every interval was read. */
static int replay(const char *plan_path, const char *samples_path)
{
    const int32_t plan = md_sh_open_read(plan_path);
    const int32_t samples = md_sh_open_read(samples_path);
    uint8_t head[PLAN_HEADER_BYTES];
    if (plan < 0 || samples < 0 || read_exact(plan, head, sizeof head) != 0 || le32(head) != PLAN_MAGIC ||
        le32(head + 4) != PLAN_VERSION) {
        md_sh_write0("replay: cannot open or read the plan and the samples (or not a version 1 plan)\n");
        return 1;
    }
    const uint32_t fs_hz = le32(head + 8);
    const uint32_t n_iv = le32(head + 12);
    const double gain_uv = le_f64(head + 16);
    const md_status_t st = bench_replay_setup(fs_hz, gain_uv);
    if (st != MD_OK || n_iv > REPLAY_MAX_INTERVALS) {
        write_status("replay: setup failed (sample rate, gain or more than 65535 intervals): ", st);
        md_sh_write0("\n");
        return 1;
    }
    uint32_t processed = 0u;
    for (uint32_t k = 0u; k < n_iv; ++k) {
        uint8_t rec[PLAN_RECORD_BYTES];
        if (read_exact(plan, rec, sizeof rec) != 0) {
            md_sh_write0("replay: the plan ends early\n");
            return 1;
        }
        const int r = replay_interval(samples, rec, k);
        if (r < 0) {
            return 1;
        }
        processed += (r > 0) ? 1u : 0u;
    }
    (void)md_sh_close(plan);
    (void)md_sh_close(samples);
    md_sh_write0("replay intervals ");
    md_sh_write_uint(n_iv);
    md_sh_write0(" processed ");
    md_sh_write_uint(processed);
    md_sh_write0("\n");
    return 0;
}

/* SysTick free-running at the CPU clock, its wrap interrupt counting periods. */
static void start_systick(void)
{
    SYST_CSR = 0u;
    SYST_RVR = RELOAD;
    SYST_CVR = 0u;
    SYST_CSR = SYST_CSR_ENABLE_TICKINT_CPUCLK;
    /* CVR = 0 is replaced by RELOAD at the first tick without a wrap
     * interrupt: start counting only once the reload has happened. */
    while (SYST_CVR == 0u) {
    }
}

/* The calibration line: a loop of known length against the counter. */
static void write_calibration(void)
{
    const uint64_t t0 = ticks_now();
    cal_loop(CAL_ITERS);
    md_sh_write0("cal ");
    write_u64(instr_since(t0));
    md_sh_write0(" ");
    write_u64(2u * (uint64_t)CAL_ITERS);
    md_sh_write0("\n");
}

/* --replay PLAN SAMPLES on the semihosting command line: the replay's exit
 * status; -1 without options (the synthetic interval). */
static int run_command_line(void)
{
    if (md_sh_get_cmdline(g_cmdline, CMDLINE_MAX) <= 0) {
        return -1;
    }
    char *pos = g_cmdline;
    (void)next_word(&pos); /* the program */
    const char *opt = next_word(&pos);
    if (opt == NULL) {
        return -1;
    }
    const char *plan = next_word(&pos);
    const char *samples = next_word(&pos);
    if (strcmp(opt, "--replay") != 0 || plan == NULL || samples == NULL || next_word(&pos) != NULL) {
        md_sh_write0("usage: md-bench-m7 [--replay PLAN SAMPLES]\n");
        return 2;
    }
    return replay(plan, samples);
}

/* The synthetic interval: set-up, then every stage timed. */
static int bench_synthetic(void)
{
    uint64_t t0 = ticks_now();
    md_status_t st = bench_setup();
    md_sh_write0("setup instr ");
    write_u64(instr_since(t0));
    md_sh_write0("\n");
    if (st != MD_OK) {
        md_sh_write0("setup failed: ");
        md_sh_write0(md_status_name(st));
        md_sh_write0("\n");
        return 1;
    }
    bench_info_t info;
    bench_info(&info);
    md_sh_write0("interval true_spikes ");
    md_sh_write_uint(info.true_spikes);
    md_sh_write0(" detected ");
    md_sh_write_uint(info.detected);
    md_sh_write0(" hyp ");
    md_sh_write_uint(info.hyp);
    md_sh_write0(" tracks ");
    md_sh_write_uint(info.tracks);
    md_sh_write0("\n");
    uint64_t cycle = 0u;
    for (unsigned s = 0u; s < (unsigned)BENCH_ST_COUNT; ++s) {
        t0 = ticks_now();
        st = bench_run_stage((bench_stage_t)s);
        const uint64_t n = instr_since(t0);
        md_sh_write0("stage ");
        md_sh_write0(bench_stage_name((bench_stage_t)s));
        if (st != MD_OK) {
            write_status(" failed: ", st);
            md_sh_write0("\n");
            return 1;
        }
        md_sh_write0(" instr ");
        write_u64(n);
        md_sh_write0(bench_stage_in_cycle((bench_stage_t)s) ? " in_cycle 1\n" : " in_cycle 0\n");
        cycle += bench_stage_in_cycle((bench_stage_t)s) ? n : 0u;
    }
    md_sh_write0("cycle instr ");
    write_u64(cycle);
    md_sh_write0("\n");
    return 0;
}

int main(void)
{
    start_systick();
    write_calibration();
    const int replayed = run_command_line();
    return (replayed >= 0) ? replayed : bench_synthetic();
}
