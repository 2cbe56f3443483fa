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
 * Without -icount the numbers are QEMU wall-clock ticks, not instructions. */
#include <stdint.h>

#include "bench_core.h"
#include "md_m7_semihost.h"
#include "md_m7_startup.h"

#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)
#define SYST_CSR_ENABLE_TICKINT_CPUCLK 0x7u
#define RELOAD 0x00FFFFFFu
#define CPU_HZ 25000000u                 /* mps2-an500 SYSCLK, SysTick's CPU clock */
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

int main(void)
{
    SYST_CSR = 0u;
    SYST_RVR = RELOAD;
    SYST_CVR = 0u;
    SYST_CSR = SYST_CSR_ENABLE_TICKINT_CPUCLK;
    /* CVR = 0 is replaced by RELOAD at the first tick without a wrap
     * interrupt: start counting only once the reload has happened. */
    while (SYST_CVR == 0u) {
    }

    uint64_t t0 = ticks_now();
    cal_loop(CAL_ITERS);
    md_sh_write0("cal ");
    write_u64(instr_since(t0));
    md_sh_write0(" ");
    write_u64(2u * (uint64_t)CAL_ITERS);
    md_sh_write0("\n");

    t0 = ticks_now();
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
            md_sh_write0(" failed: ");
            md_sh_write0(md_status_name(st));
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
