/* microdrive-fw-m7: the firmware image for the Cortex-M7 (QEMU mps2-an500).
 *
 * Today it brings the platform up (port, clock), runs a bounded idle loop and
 * reports; it exists so the image's flash/RAM can be measured and the
 * start-up path is exercised on every build. The controller application is
 * driven from the marked places once md_app exposes its entry points. */
#include <stdint.h>

#include "md_m7_semihost.h"
#include "md_m7_startup.h"
#include "md_port_m7.h"

/* Iterations of the idle loop; each sleeps until the next 1 ms SysTick. On a
 * board the loop runs forever (watchdog-supervised); under QEMU it ends so
 * the image can be run as a test. */
#ifndef MD_M7_IDLE_ITERATIONS
#define MD_M7_IDLE_ITERATIONS 200u
#endif

int main(void)
{
    static md_port_m7_ctx_t port_ctx;
    md_port_t port;
    if (md_port_m7_init(&port, &port_ctx) != MD_OK) {
        return 1;
    }
    md_port_m7_clock_start();
    md_sh_write0("microdrive-fw-m7: up (Cortex-M7, mps2-an500)\n");

    /* APP INIT: md_app_init(&app, &port, ...) goes here. */
    const uint64_t t0_us = port.now_us(port.ctx);
    for (uint32_t i = 0u; i < MD_M7_IDLE_ITERATIONS; ++i) {
        /* BOARD CAN RX: drain the CAN controller's RX FIFO here and push
         * each frame into the application (md_app_on_frame(...)). */
        /* APP STEP: md_app_step(&app, port.now_us(port.ctx)) goes here. */
        __asm__ volatile("wfi");
    }
    const uint64_t elapsed_us = port.now_us(port.ctx) - t0_us;

    md_sh_write0("microdrive-fw-m7: idle loop done, ");
    md_sh_write_uint((uint32_t)(elapsed_us / 1000u));
    md_sh_write0(" ms elapsed, frames sent ");
    md_sh_write_uint(port_ctx.frames_sent);
    md_sh_write0(", refused ");
    md_sh_write_uint(port_ctx.frames_refused);
    md_sh_write0("\n");
    /* Each iteration waits for a 1 ms tick, so less time means the clock or
     * its interrupt is broken. */
    return (elapsed_us + 1000u >= (uint64_t)MD_M7_IDLE_ITERATIONS * 1000u) ? 0 : 2;
}
