/// @file md_lcm_bridge.c
/// md-lcm-bridge: CAN telemetry (live bus or candump -L log) and the
/// simulator's ground truth (JSON lines) into LCM messages of package
/// mdlcm, published on an LCM URL and/or written to an LCM event log.
/// docs/telemetry.md has the channels, the time base and example commands.
///
///   md-lcm-bridge (--bus SPEC | --from-log FILE) [--truth FILE] [--lcm-url URL]
///                 [--write-log FILE] [--time sim|frame] [--duration-s S] [--quiet]
///
/// Exit status: 0 ok; 1 runtime error (file, LCM, a message could not be
/// published or written); 2 usage; 3 bus could not be opened.
#define _GNU_SOURCE
#include <errno.h>
#include <inttypes.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <lcm/eventlog.h>
#include <lcm/lcm.h>

#include "lcm_bridge.h"
#include "md_bus.h"
#include "md_bus_text.h"

#define EXIT_RUNTIME 1
#define EXIT_USAGE 2
#define EXIT_BUS 3
#define RECEIVE_SLICE_US 100000  ///< live loop wakes this often (signals, truth tail, duration)

static volatile sig_atomic_t g_stop = 0;

static void on_signal(int sig)
{
    (void)sig;
    g_stop = 1;
}

typedef struct {
    const char *bus_spec, *from_log, *truth, *lcm_url, *write_log;
    lb_time_mode_t time_mode;
    double duration_s;  ///< live only; 0 = until SIGINT/SIGTERM
    int quiet;
} opts_t;

/// Where messages go: an LCM instance and/or an event log.
typedef struct {
    lcm_t *lcm;
    lcm_eventlog_t *log;
    int64_t last_ts;  ///< event timestamps are kept non-decreasing for lcm-logplayer
    int64_t events;
    uint64_t write_errors;
} sink_t;

/// The ground-truth file, read a line at a time; in live mode it is tailed
/// (a line without its newline yet is kept until the rest arrives).
typedef struct {
    FILE *f;
    int tail;
    char *buf;
    size_t len, cap;
    int have_line;         ///< buf holds a complete pending line
    int64_t line_time_us;  ///< its time (lb_truth_time_us), -1 = unparseable
    int eof;
} truth_t;

static int usage(void)
{
    fprintf(stderr, "usage: md-lcm-bridge (--bus SPEC | --from-log FILE) [--truth FILE] [--lcm-url URL]\n"
                    "                     [--write-log FILE] [--time sim|frame] [--duration-s S] [--quiet]\n"
                    "  --bus SPEC       live: vcan0 | can0 | <ifname> | udp | udp:<port> | auto (docs/bus.md)\n"
                    "  --from-log FILE  replay a candump -L log ('-' = stdin), then exit\n"
                    "  --truth FILE     simulator ground truth, JSON lines (tailed in live mode)\n"
                    "  --lcm-url URL    publish on this LCM provider (memq://, udpm://239.255.76.67:7667?ttl=0 ...)\n"
                    "  --write-log FILE write an LCM event log (lcm-logplayer, lcm-logger format)\n"
                    "                   without --lcm-url, --write-log publishes nothing; with neither,\n"
                    "                   LCM's default URL (LCM_DEFAULT_URL) is used\n"
                    "  --time sim|frame utime from SIM_CLOCK (default, deterministic) or the frame's\n"
                    "                   log stamp / wall clock\n"
                    "  --duration-s S   live: stop after S seconds (default: at SIGINT/SIGTERM)\n");
    return EXIT_USAGE;
}

static int parse_args(int argc, char **argv, opts_t *o)
{
    memset(o, 0, sizeof *o);
    o->time_mode = LB_TIME_SIM;
    for (int i = 1; i < argc; ++i) {
        const char *a = argv[i];
        const char *v = (i + 1 < argc) ? argv[i + 1] : NULL;
        if (strcmp(a, "--quiet") == 0) {
            o->quiet = 1;
            continue;
        }
        if (v == NULL) {
            fprintf(stderr, "md-lcm-bridge: '%s' needs a value (or is unknown)\n", a);
            return -1;
        }
        ++i;
        if (strcmp(a, "--bus") == 0) {
            o->bus_spec = v;
        } else if (strcmp(a, "--from-log") == 0) {
            o->from_log = v;
        } else if (strcmp(a, "--truth") == 0) {
            o->truth = v;
        } else if (strcmp(a, "--lcm-url") == 0) {
            o->lcm_url = v;
        } else if (strcmp(a, "--write-log") == 0) {
            o->write_log = v;
        } else if (strcmp(a, "--time") == 0 && (strcmp(v, "sim") == 0 || strcmp(v, "frame") == 0)) {
            o->time_mode = (strcmp(v, "sim") == 0) ? LB_TIME_SIM : LB_TIME_FRAME;
        } else if (strcmp(a, "--duration-s") == 0) {
            char *end = NULL;
            o->duration_s = strtod(v, &end);
            if (end == v || *end != '\0' || !(o->duration_s >= 0.0)) {
                fprintf(stderr, "md-lcm-bridge: --duration-s needs a number >= 0, got '%s'\n", v);
                return -1;
            }
        } else {
            fprintf(stderr, "md-lcm-bridge: unknown option or value '%s %s'\n", a, v);
            return -1;
        }
    }
    if ((o->bus_spec == NULL) == (o->from_log == NULL)) {
        fprintf(stderr, "md-lcm-bridge: give exactly one of --bus and --from-log\n");
        return -1;
    }
    return 0;
}

static int sink_emit(void *ctx, const char *channel, int64_t utime, const uint8_t *data, size_t len)
{
    sink_t *s = ctx;
    int rc = 0;
    if (s->lcm != NULL && lcm_publish(s->lcm, channel, data, (unsigned int)len) != 0) {
        rc = -1;
    }
    if (s->log != NULL) {
        s->last_ts = (utime > s->last_ts) ? utime : s->last_ts;
        lcm_eventlog_event_t ev = {.eventnum = s->events,
                                   .timestamp = s->last_ts,
                                   .channellen = (int32_t)strlen(channel),
                                   .datalen = (int32_t)len,
                                   .channel = (char *)(uintptr_t)channel,
                                   .data = (void *)(uintptr_t)data};
        if (lcm_eventlog_write_event(s->log, &ev) != 0) {
            s->write_errors++;
            rc = -1;
        }
        s->events++;
    }
    if (s->lcm != NULL) {
        /* memq:// queues every message until handled: drain, nobody here subscribes */
        while (lcm_handle_timeout(s->lcm, 0) > 0) {
        }
    }
    return rc;
}

/* ---- ground truth ------------------------------------------------------------------------------ */

/// Reads the next complete line into t->buf. 1 = line ready, 0 = none yet
/// (tail mode), -1 = end of file or error.
static int truth_read_line(truth_t *t)
{
    if (t->f == NULL || t->eof) {
        return -1;
    }
    for (;;) {
        const int c = fgetc(t->f);
        if (c == EOF) {
            if (!t->tail) {
                t->eof = 1;
                return t->len > 0u ? 1 : -1; /* a last line without newline still counts */
            }
            clearerr(t->f);
            return 0;
        }
        if (t->len + 2u > t->cap) {
            const size_t cap = t->cap ? 2u * t->cap : 4096u;
            char *nb = realloc(t->buf, cap);
            if (nb == NULL) {
                return -1;
            }
            t->buf = nb;
            t->cap = cap;
        }
        t->buf[t->len++] = (char)c;
        t->buf[t->len] = '\0';
        if (c == '\n') {
            return 1;
        }
    }
}

/// Publishes every truth record due by now_us (all of them when now_us < 0).
static void truth_pump(truth_t *t, lb_t *st, int64_t now_us)
{
    for (;;) {
        if (!t->have_line) {
            if (truth_read_line(t) != 1) {
                return;
            }
            t->have_line = 1;
            t->line_time_us = lb_truth_time_us(st, t->buf);
        }
        if (now_us >= 0 && t->line_time_us > now_us) {
            return;
        }
        (void)lb_feed_truth_line(st, t->buf);
        t->have_line = 0;
        t->len = 0u;
    }
}

/* ---- inputs ----------------------------------------------------------------------------------- */

/// One candump -L line "(sec.usec) iface frame" → frame and time. 0 or -1.
static int parse_candump_line(const char *line, md_frame_t *f, int64_t *time_us)
{
    long long sec = 0, usec = 0;
    char iface[64], text[MD_BUS_TEXT_MAX + 8];
    if (sscanf(line, " (%lld.%lld) %63s %147s", &sec, &usec, iface, text) != 4) {
        return -1;
    }
    *time_us = (int64_t)(sec * 1000000LL + usec);
    return md_bus_text_parse(text, f, NULL) == 0 ? 0 : -1;
}

static int run_log(const opts_t *o, lb_t *st, truth_t *t, uint64_t *bad_lines)
{
    FILE *f = (strcmp(o->from_log, "-") == 0) ? stdin : fopen(o->from_log, "r");
    if (f == NULL) {
        fprintf(stderr, "md-lcm-bridge: cannot open '%s': %s\n", o->from_log, strerror(errno));
        return EXIT_RUNTIME;
    }
    char *line = NULL;
    size_t cap = 0u;
    while (!g_stop && getline(&line, &cap, f) >= 0) {
        md_frame_t frame;
        int64_t time_us = 0;
        if (parse_candump_line(line, &frame, &time_us) != 0) {
            *bad_lines += (line[0] == '\n' || line[0] == '\0') ? 0u : 1u;
            continue;
        }
        lb_feed_frame(st, &frame, time_us);
        truth_pump(t, st, lb_now_us(st));
    }
    const int err = ferror(f);
    free(line);
    if (f != stdin) {
        (void)fclose(f);
    }
    return err ? EXIT_RUNTIME : 0;
}

static int64_t realtime_us(void)
{
    struct timespec ts;
    (void)clock_gettime(CLOCK_REALTIME, &ts);
    return (int64_t)ts.tv_sec * 1000000LL + ts.tv_nsec / 1000;
}

static int run_bus(const opts_t *o, lb_t *st, truth_t *t)
{
    static md_bus_t bus; /* must not move while open (md_bus.h) */
    char why[160] = "";
    const int rc = md_bus_open(&bus, o->bus_spec, why, sizeof why);
    if (!o->quiet || rc != 0) {
        fprintf(stderr, "md-lcm-bridge: bus %s: %s\n", o->bus_spec, why);
    }
    if (rc != 0) {
        return EXIT_BUS;
    }
    const int64_t t0 = realtime_us();
    const int64_t limit_us = (int64_t)(o->duration_s * 1e6);
    while (!g_stop && (limit_us == 0 || realtime_us() - t0 < limit_us)) {
        md_frame_t frame;
        const int got = md_bus_receive(&bus, &frame, RECEIVE_SLICE_US);
        if (got < 0 && got != -EINTR) {
            fprintf(stderr, "md-lcm-bridge: receive failed: %s\n", strerror(-got));
            break;
        }
        if (got == 1) {
            lb_feed_frame(st, &frame, realtime_us());
        }
        truth_pump(t, st, lb_now_us(st));
    }
    md_bus_close(&bus);
    return 0;
}

static int open_sinks(const opts_t *o, sink_t *s)
{
    if (o->lcm_url != NULL || o->write_log == NULL) {
        s->lcm = lcm_create(o->lcm_url); /* NULL = LCM_DEFAULT_URL or LCM's default */
        if (s->lcm == NULL) {
            fprintf(stderr, "md-lcm-bridge: lcm_create(%s) failed (a multicast route? try memq://)\n",
                    o->lcm_url ? o->lcm_url : "default");
            return -1;
        }
    }
    if (o->write_log != NULL) {
        s->log = lcm_eventlog_create(o->write_log, "w");
        if (s->log == NULL) {
            fprintf(stderr, "md-lcm-bridge: cannot write '%s': %s\n", o->write_log, strerror(errno));
            return -1;
        }
    }
    return 0;
}

int main(int argc, char **argv)
{
    opts_t o;
    if (parse_args(argc, argv, &o) != 0) {
        return usage();
    }
    truth_t t = {.tail = (o.bus_spec != NULL)};
    if (o.truth != NULL && (t.f = fopen(o.truth, "r")) == NULL) {
        fprintf(stderr, "md-lcm-bridge: cannot open truth '%s': %s\n", o.truth, strerror(errno));
        return EXIT_RUNTIME;
    }
    sink_t sink = {0};
    lb_t *st = malloc(lb_size());
    if (st == NULL || open_sinks(&o, &sink) != 0) {
        return EXIT_RUNTIME;
    }
    (void)lb_init(st, o.time_mode, sink_emit, &sink);
    signal(SIGINT, on_signal);
    signal(SIGTERM, on_signal);

    uint64_t bad_lines = 0u;
    int rc = (o.from_log != NULL) ? run_log(&o, st, &t, &bad_lines) : run_bus(&o, st, &t);
    lb_flush(st); /* open cycle groups first, then the rest of the truth */
    truth_pump(&t, st, -1);
    lb_flush(st);

    const lb_stats_t *s = lb_stats(st);
    if (!o.quiet) {
        fprintf(stderr,
                "md-lcm-bridge: frames %" PRIu64 " (telemetry %" PRIu64 ", ignored %" PRIu64 ", malformed %" PRIu64
                ", dropped %" PRIu64 ", late %" PRIu64 "), bad log lines %" PRIu64 ", truth records %" PRIu64
                " (errors %" PRIu64 ", ignored %" PRIu64 "), messages %" PRIu64 " (errors %" PRIu64 ")\n",
                s->frames, s->telemetry, s->ignored, s->malformed, s->dropped, s->late, bad_lines, s->truth_records,
                s->truth_errors, s->truth_ignored, s->messages, s->sink_errors);
    }
    if (rc == 0 && s->sink_errors > 0u) {
        rc = EXIT_RUNTIME;
    }
    if (sink.log != NULL) {
        lcm_eventlog_destroy(sink.log);
    }
    if (sink.lcm != NULL) {
        lcm_destroy(sink.lcm);
    }
    if (t.f != NULL) {
        (void)fclose(t.f);
    }
    free(t.buf);
    free(st);
    return rc;
}
