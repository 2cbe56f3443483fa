/* microdrive-fw-m7: the firmware image for the Cortex-M7 (QEMU mps2-an500).
 *
 * Brings the platform up (port = CAN over the UART link, clock, work counter
 * calibration), initialises the controller (md_controller.h, the same API as
 * microdrive-fw and the session launcher) when the build has one (md_app,
 * MD_M7_HAVE_APP), and runs the platform loop: received frames into the
 * controller, poll, sleep until the next interrupt (a UART byte or the 1 ms
 * SysTick) when nothing is due.
 *
 * Options come from the semihosting command line (QEMU
 * `-semihosting-config enable=on,arg=microdrive-fw-m7,arg=--auto-start,...`):
 *   --iterations N       loop passes, then report and exit (0, the default:
 *                        run until QEMU is stopped; on a board: forever)
 *   --auto-start         parameter auto_start = 1 (as microdrive-fw --auto-start)
 *   --param NAME=VALUE   set a controller parameter with the checks of a set
 *                        over the bus (VALUE: decimal, optional fraction)
 * docs/pil.md (processor in the loop), docs/target.md. */
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "md_can_uart.h"
#include "md_m7_semihost.h"
#include "md_m7_startup.h"
#include "md_port_m7.h"
#if defined(MD_M7_HAVE_APP)
#include "md_controller.h"
#endif

/* Frames handed to the controller per loop pass at most before it is polled
 * again, so a stream of frames cannot starve the heartbeat and supervision. */
#define MD_M7_RX_BURST 64u
/* Command line bytes taken at most. */
#define MD_M7_CMDLINE_MAX 1024u
/* Words of the command line taken at most. */
#define MD_M7_ARGS_MAX 72u
/* Platform time between two status lines on the console. */
#define MD_M7_REPORT_PERIOD_US 60000000u

typedef struct {
    uint64_t iterations; /* 0: unbounded (UINT64_MAX passes) */
    bool auto_start;
    const char *param[MD_M7_ARGS_MAX];
    uint32_t n_param;
} m7_options_t;

static char cmdline[MD_M7_CMDLINE_MAX];

static void say(const char *a, uint32_t v, const char *b)
{
    md_sh_write0(a);
    md_sh_write_uint(v);
    md_sh_write0(b);
}

/* Value of a decimal digit character, or -1. */
static int digit_value(char ch)
{
    return (ch >= '0' && ch <= '9') ? (int)ch - (int)'0' : -1;
}

/* Decimal digits only; false on anything else or overflow. */
static bool parse_u64(const char *s, uint64_t *out)
{
    uint64_t v = 0u;
    size_t i = 0u;
    for (; i < 20u && s[i] != '\0'; ++i) {
        const int d = digit_value(s[i]);
        if (d < 0 || v > (UINT64_MAX - 9u) / 10u) {
            return false;
        }
        v = v * 10u + (uint64_t)d;
    }
    *out = v;
    return i > 0u && s[i] == '\0';
}

/* [-]digits[.digits], at most 15 significant digits: the value is
 * mantissa / 10^k, a correctly rounded division of two exact doubles, i.e. the
 * double strtod gives (newlib's strtod allocates, so it is not used). */
static bool parse_decimal(const char *s, double *out)
{
    const bool neg = s[0] == '-';
    size_t i = 0u;
    if (neg) {
        i = 1u;
    }
    uint64_t m = 0u;
    uint32_t digits = 0u;
    uint32_t frac = 0u;
    bool dot = false;
    for (; i < 40u && s[i] != '\0'; ++i) {
        const int d = digit_value(s[i]);
        if (s[i] == '.' && !dot) {
            dot = true;
        } else if (d < 0 || digits >= 15u) {
            return false;
        } else {
            m = m * 10u + (uint64_t)d;
            digits++;
            if (dot) {
                frac++;
            }
        }
    }
    if (digits == 0u || s[i] != '\0') {
        return false;
    }
    double p10 = 1.0;
    for (uint32_t k = 0u; k < frac; ++k) {
        p10 *= 10.0;
    }
    const double v = (double)m / p10;
    *out = neg ? -v : v;
    return true;
}

/* Splits the command line in place and reads the options. false: bad option. */
static bool parse_options(m7_options_t *o)
{
    /* offsets of the words in cmdline (static: the image's stack is budgeted) */
    static uint16_t word_at[MD_M7_ARGS_MAX];
    memset(o, 0, sizeof *o);
    if (md_sh_get_cmdline(cmdline, sizeof cmdline) < 0) {
        return true; /* no command line: defaults */
    }
    uint32_t argc = 0u;
    bool in_word = false;
    for (uint32_t i = 0u; i < MD_M7_CMDLINE_MAX && cmdline[i] != '\0'; ++i) {
        if (cmdline[i] == ' ') {
            cmdline[i] = '\0';
            in_word = false;
        } else if (!in_word && argc < MD_M7_ARGS_MAX) {
            word_at[argc] = (uint16_t)i;
            argc++;
            in_word = true;
        } else {
            /* inside a word (or past the last word taken) */
        }
    }
    uint32_t i = 1u; /* word 0: the program */
    for (uint32_t k = 0u; k < MD_M7_ARGS_MAX && i < argc; ++k) {
        const char *w = &cmdline[word_at[i]];
        const char *next = (i + 1u < argc) ? &cmdline[word_at[i + 1u]] : NULL;
        if (strcmp(w, "--auto-start") == 0) {
            o->auto_start = true;
            i += 1u;
        } else if (strcmp(w, "--iterations") == 0 && next != NULL && parse_u64(next, &o->iterations)) {
            i += 2u;
        } else if (strcmp(w, "--param") == 0 && next != NULL && o->n_param < MD_M7_ARGS_MAX) {
            o->param[o->n_param] = next;
            o->n_param++;
            i += 2u;
        } else {
            md_sh_write0("microdrive-fw-m7: bad option '");
            md_sh_write0(w);
            md_sh_write0("' (--iterations N, --auto-start, --param NAME=VALUE)\n");
            return false;
        }
    }
    return true;
}

#if defined(MD_M7_HAVE_APP)
/* One NAME=VALUE through md_params_set. */
static bool set_named_param(md_node_t *node, const char *arg)
{
    const char *eq = strchr(arg, '=');
    const ptrdiff_t name_len = (eq == NULL) ? 0 : eq - arg;
    const size_t len = (size_t)name_len;
    double v = 0.0;
    for (size_t i = 0u; i < md_params_count() && len > 0u; ++i) {
        const md_param_def_t *d = md_params_def(i);
        if (strlen(d->name) == len && strncmp(d->name, arg, len) == 0) {
            if (parse_decimal(&arg[len + 1u], &v) && md_params_set(&node->params, d->index, v) == MD_PARAM_OK) {
                return true;
            }
            break;
        }
    }
    md_sh_write0("microdrive-fw-m7: --param '");
    md_sh_write0(arg);
    md_sh_write0("' refused (unknown name, not a decimal, or out of range)\n");
    return false;
}

static bool configure(md_node_t *node, const m7_options_t *o)
{
    if (o->auto_start && md_params_set(&node->params, md_params_def(MD_P_AUTO_START)->index, 1.0) != MD_PARAM_OK) {
        return false;
    }
    for (uint32_t i = 0u; i < o->n_param && i < MD_M7_ARGS_MAX; ++i) {
        if (!set_named_param(node, o->param[i])) {
            return false;
        }
    }
    return true;
}
#endif

static void report_link(const md_port_m7_ctx_t *pc, uint64_t now_us)
{
    const md_can_uart_stats_t *s = md_can_uart_stats();
    say("microdrive-fw-m7: t ", (uint32_t)(now_us / 1000u), " ms");
    say(", frames sent ", pc->frames_sent, "");
    say(", failed ", pc->frames_failed, "");
    say(", refused ", pc->frames_refused, "");
    say(", received ", pc->frames_received, "");
    say("; link: tx timeouts ", s->tx_timeouts, "");
    say(", rx bad crc ", s->rx_bad_crc, "");
    say(" frame ", s->rx_bad_frame, "");
    say(" esc ", s->rx_bad_esc, "");
    say(" long ", s->rx_too_long, "");
    say(", uart overruns ", s->rx_overruns, "");
    say(", ring full ", s->rx_ring_full, "\n");
}

/* The platform up: the clock and the work counter's calibration, reported on
 * the console so a run's costs can be converted to instructions. */
static void start_clock(md_port_m7_ctx_t *pc)
{
    md_port_m7_clock_start();
    md_sh_write0("microdrive-fw-m7: up (Cortex-M7, mps2-an500, CAN over UART0)\n");
    const uint64_t calib = md_port_m7_calibrate(pc);
    say("microdrive-fw-m7: work counter: ", pc->insn_per_tick, " instructions per SysTick tick; ");
    say("calibration loop of ", MD_M7_CALIB_INSNS, " instructions measured as ");
    say("", (uint32_t)calib, "\n");
}

#if defined(MD_M7_HAVE_APP)
/* One pass of the controller: the received frames (MD_M7_RX_BURST at most),
 * then a poll at *now_us; a poll that failed to send counts in *poll_errors.
 * True: work is due again already (no sleep). */
static bool serve(md_controller_t *ctl, const md_port_t *port, md_port_m7_ctx_t *pc, uint64_t *now_us,
                  uint32_t *poll_errors)
{
    md_frame_t rx;
    for (uint32_t k = 0u; k < MD_M7_RX_BURST && md_port_m7_receive(pc, &rx); ++k) {
        md_controller_on_frame(ctl, &rx, port->now_us(port->ctx)); /* rejections are counted by the node */
    }
    const uint32_t tx_failures = ctl->node.counters.tx_failures;
    *now_us = port->now_us(port->ctx);
    md_controller_poll(ctl, *now_us);
    if (ctl->node.counters.tx_failures != tx_failures) {
        (*poll_errors)++;
    }
    return md_controller_next_deadline_us(ctl) <= port->now_us(port->ctx);
}
#endif

/* Sleep until the next interrupt unless work is waiting; interrupts masked
 * around the check, so a byte arriving in between still wakes the wfi (a
 * pending interrupt ends it even while masked). */
static void sleep_unless_busy(bool busy)
{
    __asm__ volatile("cpsid i" ::: "memory");
    if (!busy && !md_can_uart_rx_pending()) {
        __asm__ volatile("wfi");
    }
    __asm__ volatile("cpsie i" ::: "memory");
    __asm__ volatile("isb");
}

/* The closing report of a bounded run and its exit status: 2 when the loop
 * took less time than its waits must (each pass without work due waits for an
 * interrupt, with nothing on the UART the 1 ms tick: the clock or its
 * interrupt is broken), 4 on a poll error or a refused or failed frame. */
static int finish(const md_port_t *port, const md_port_m7_ctx_t *pc, uint64_t t0_us, const m7_options_t *opt,
                  uint64_t busy_passes, uint32_t poll_errors)
{
    const uint64_t elapsed_us = port->now_us(port->ctx) - t0_us;
    md_sh_write0("microdrive-fw-m7: idle loop done, ");
    md_sh_write_uint((uint32_t)(elapsed_us / 1000u));
    md_sh_write0(" ms elapsed, frames sent ");
    md_sh_write_uint(pc->frames_sent);
    md_sh_write0(", refused ");
    md_sh_write_uint(pc->frames_refused);
    md_sh_write0(", poll errors ");
    md_sh_write_uint(poll_errors);
    md_sh_write0("\n");
    report_link(pc, port->now_us(port->ctx));
    if (elapsed_us + 1000u * (busy_passes + 1u) < opt->iterations * 1000u) {
        return 2;
    }
    return (poll_errors == 0u && pc->frames_refused == 0u && pc->frames_failed == 0u) ? 0 : 4;
}

int main(void)
{
    static md_port_m7_ctx_t port_ctx;
    static m7_options_t opt;
    md_port_t port;
    if (!parse_options(&opt)) {
        return 2;
    }
    if (md_port_m7_init(&port, &port_ctx) != MD_OK) {
        return 1;
    }
    start_clock(&port_ctx);

    const uint64_t t0_us = port.now_us(port.ctx);
#if defined(MD_M7_HAVE_APP)
    /* the whole controller (node + electrode cycles + shared workspace): static, no heap */
    md_controller_t *ctl = md_controller_instance();
    if (md_controller_init(ctl, &port, t0_us) != MD_OK) {
        md_sh_write0("microdrive-fw-m7: md_controller_init failed\n");
        return 3;
    }
    if (!configure(md_controller_node(ctl), &opt)) {
        return 2;
    }
#endif
    const uint64_t passes = (opt.iterations == 0u) ? UINT64_MAX : opt.iterations;
    uint32_t poll_errors = 0u;
    uint64_t busy_passes = 0u;
    uint64_t next_report_us = t0_us + MD_M7_REPORT_PERIOD_US;
    for (uint64_t i = 0u; i < passes; ++i) {
#if defined(MD_M7_HAVE_APP)
        uint64_t now_us = 0u;
        const bool busy = serve(ctl, &port, &port_ctx, &now_us, &poll_errors);
#else
        const uint64_t now_us = port.now_us(port.ctx);
        const bool busy = false;
#endif
        busy_passes += busy ? 1u : 0u;
        if (opt.iterations == 0u && now_us >= next_report_us) {
            report_link(&port_ctx, now_us);
            next_report_us = now_us + MD_M7_REPORT_PERIOD_US;
        }
        sleep_unless_busy(busy);
    }
    return finish(&port, &port_ctx, t0_us, &opt, busy_passes, poll_errors);
}
