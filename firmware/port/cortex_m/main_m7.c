/* microdrive-fw-m7: the firmware image for the Cortex-M7 (QEMU mps2-an500).
 *
 * Brings the platform up (port, clock), initialises the controller
 * (md_controller.h, the same API as microdrive-fw and the session launcher) when
 * the build has one (md_app, MD_M7_HAVE_APP), runs a bounded idle loop that
 * polls it, and reports. Under QEMU there is no CAN controller: the stub port
 * counts what the node sends and nothing is ever received. The image is built
 * on every cortex-m7 build so its flash/RAM are measured and its start-up
 * path runs as a test. */
#include <stdint.h>

#include "md_m7_semihost.h"
#include "md_m7_startup.h"
#include "md_port_m7.h"
#if defined(MD_M7_HAVE_APP)
#include "md_controller.h"
#endif

/* Frames taken from the CAN controller per loop iteration at most. */
#define MD_M7_RX_BURST 8u

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

    const uint64_t t0_us = port.now_us(port.ctx);
#if defined(MD_M7_HAVE_APP)
    /* the whole controller (node + electrode cycles + shared workspace): static, no heap */
    md_controller_t *ctl = md_controller_instance();
    if (md_controller_init(ctl, &port, t0_us) != MD_OK) {
        md_sh_write0("microdrive-fw-m7: md_controller_init failed\n");
        return 3;
    }
#endif
    uint32_t poll_errors = 0u;
    for (uint32_t i = 0u; i < MD_M7_IDLE_ITERATIONS; ++i) {
        const uint64_t now_us = port.now_us(port.ctx);
#if defined(MD_M7_HAVE_APP)
        /* Received frames go into the node first (none under QEMU). */
        md_frame_t rx;
        for (uint32_t k = 0u; k < MD_M7_RX_BURST && md_port_m7_receive(&port_ctx, &rx); ++k) {
            md_controller_on_frame(ctl, &rx, now_us); /* rejections are counted by the node */
        }
        const uint32_t tx_failures = ctl->node.counters.tx_failures;
        md_controller_poll(ctl, now_us);
        if (ctl->node.counters.tx_failures != tx_failures) {
            poll_errors++;
        }
#else
        (void)now_us;
#endif
        __asm__ volatile("wfi"); /* sleep until the next 1 ms SysTick */
    }
    const uint64_t elapsed_us = port.now_us(port.ctx) - t0_us;

    md_sh_write0("microdrive-fw-m7: idle loop done, ");
    md_sh_write_uint((uint32_t)(elapsed_us / 1000u));
    md_sh_write0(" ms elapsed, frames sent ");
    md_sh_write_uint(port_ctx.frames_sent);
    md_sh_write0(", refused ");
    md_sh_write_uint(port_ctx.frames_refused);
    md_sh_write0(", poll errors ");
    md_sh_write_uint(poll_errors);
    md_sh_write0("\n");
    /* Each iteration waits for a 1 ms tick, so less time means the clock or
     * its interrupt is broken. */
    if (elapsed_us + 1000u < (uint64_t)MD_M7_IDLE_ITERATIONS * 1000u) {
        return 2;
    }
    return (poll_errors == 0u && port_ctx.frames_refused == 0u) ? 0 : 4;
}
