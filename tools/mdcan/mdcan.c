/// @file mdcan.c
/// candump/cansend for the project's buses: `mdcan dump` prints frames in
/// candump -L log format, `mdcan send` takes cansend's frame syntax. Works on
/// every bus spec md_bus_open knows (vcan0, udp, udp:<port>, auto), which
/// makes the UDP bus as inspectable as SocketCAN.
///
///   mdcan dump --bus SPEC [--count N] [--timeout-ms T] [--iface LABEL]
///   mdcan send --bus SPEC FRAME [FRAME...]
///   mdcan bridge --serial PATH --bus SPEC [--wait-ms N]   (mdcan_bridge.c)
///
/// Exit status: 0 ok; 1 dump ended by --timeout-ms before --count frames, or
/// a send failed; 2 usage or frame syntax; 3 bus could not be opened.
#define _GNU_SOURCE
#include <errno.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "md_bus.h"
#include "md_bus_text.h"
#include "mdcan_bridge.h"

#define EXIT_INCOMPLETE 1
#define EXIT_USAGE 2
#define EXIT_BUS 3
/// dump waits in slices this long so Ctrl-C ends it promptly.
#define DUMP_SLICE_US 100000

static volatile sig_atomic_t g_stop = 0;

static void on_signal(int sig)
{
    (void)sig;
    g_stop = 1;
}

static int usage(void)
{
    fprintf(stderr, "usage: mdcan dump --bus SPEC [--count N] [--timeout-ms T] [--iface LABEL]\n"
                    "       mdcan send --bus SPEC FRAME [FRAME...]\n"
                    "       mdcan bridge --serial PATH --bus SPEC [--wait-ms N]\n"
                    "SPEC:  vcan0 | can0 | <ifname> | udp | udp:<port> | auto\n"
                    "FRAME: 123#DEADBEEF (11-bit) | 1ABCDEF0#0011 (29-bit) | 123##1<data> (CAN FD, 1 = BRS)\n"
                    "dump prints candump -L lines: (sec.usec) LABEL ID#DATA; --timeout-ms ends it after T ms\n"
                    "without frames; exit 1 if --count frames did not arrive.\n");
    return EXIT_USAGE;
}

static int parse_count(const char *s, long long max, long long *out)
{
    char *end = NULL;
    errno = 0;
    const long long v = strtoll(s, &end, 10);
    if (errno != 0 || end == s || *end != '\0' || v < 0 || v > max) {
        return -1;
    }
    *out = v;
    return 0;
}

static int open_bus(md_bus_t *bus, const char *spec, char *why, size_t why_len)
{
    const int rc = md_bus_open(bus, spec, why, why_len);
    if (rc != 0) {
        fprintf(stderr, "mdcan: cannot open bus '%s': %s (%s)\n", spec, why, strerror(-rc));
    }
    return rc;
}

/// candump's interface column must be [A-Za-z0-9]+ for log readers
/// (cantools, python-can), so buses whose name has ':' get a plain label.
static void default_label(const md_bus_t *bus, char *label, size_t cap)
{
    switch (bus->kind) {
    case MD_BUS_SOCKETCAN: (void)snprintf(label, cap, "%s", bus->name); break;
    case MD_BUS_UDP: (void)snprintf(label, cap, "udp%u", (unsigned)bus->sock.port); break;
    case MD_BUS_INPROC: (void)snprintf(label, cap, "inproc"); break;
    default: (void)snprintf(label, cap, "bus"); break;
    }
}

static void print_stats(const md_bus_t *bus)
{
    fprintf(stderr, "mdcan: %s: rx %llu, malformed %llu, overflow %llu, tx %llu, tx errors %llu\n", bus->name,
            (unsigned long long)bus->stats.rx_frames, (unsigned long long)bus->stats.rx_malformed,
            (unsigned long long)bus->stats.rx_overflow, (unsigned long long)bus->stats.tx_frames,
            (unsigned long long)bus->stats.tx_errors);
}

static int print_frame(const char *label, const md_frame_t *f)
{
    char text[MD_BUS_TEXT_MAX];
    if (md_bus_text_format(f, text, sizeof text) < 0) {
        return -1;  // cannot happen: the bus hands out only valid frames
    }
    struct timespec ts;
    (void)clock_gettime(CLOCK_REALTIME, &ts);
    printf("(%010lld.%06ld) %s %s\n", (long long)ts.tv_sec, ts.tv_nsec / 1000L, label, text);
    return fflush(stdout) == 0 ? 0 : -1;
}

typedef struct {
    const char *bus;
    const char *iface;
    long long count;       ///< 0 = unlimited
    long long timeout_ms;  ///< idle timeout; -1 = none
    int first_frame;       ///< argv index of the first FRAME (send)
} options_t;

static int parse_options(int argc, char **argv, bool is_dump, options_t *o)
{
    o->bus = NULL;
    o->iface = NULL;
    o->count = 0;
    o->timeout_ms = -1;
    o->first_frame = argc;
    int i = 2;
    for (; i < argc && strncmp(argv[i], "--", 2) == 0; i += 2) {
        const char *opt = argv[i];
        if (i + 1 >= argc) {
            fprintf(stderr, "mdcan: %s needs a value\n", opt);
            return -1;
        }
        const char *val = argv[i + 1];
        if (strcmp(opt, "--bus") == 0) {
            o->bus = val;
        } else if (is_dump && strcmp(opt, "--iface") == 0) {
            o->iface = val;
        } else if (is_dump && strcmp(opt, "--count") == 0) {
            if (parse_count(val, 1000000000LL, &o->count) != 0) {
                fprintf(stderr, "mdcan: bad --count '%s'\n", val);
                return -1;
            }
        } else if (is_dump && strcmp(opt, "--timeout-ms") == 0) {
            if (parse_count(val, 86400000LL, &o->timeout_ms) != 0) {
                fprintf(stderr, "mdcan: bad --timeout-ms '%s'\n", val);
                return -1;
            }
        } else {
            fprintf(stderr, "mdcan: unknown option '%s'\n", opt);
            return -1;
        }
    }
    o->first_frame = i;
    if (o->bus == NULL) {
        fprintf(stderr, "mdcan: --bus SPEC is required\n");
        return -1;
    }
    if (is_dump != (i == argc)) {
        fprintf(stderr, is_dump ? "mdcan: dump takes no frames\n" : "mdcan: send needs at least one FRAME\n");
        return -1;
    }
    return 0;
}

static int cmd_dump(const options_t *o)
{
    md_bus_t bus;
    char why[200] = "";
    if (open_bus(&bus, o->bus, why, sizeof why) != 0) {
        return EXIT_BUS;
    }
    char label[32];
    default_label(&bus, label, sizeof label);
    if (o->iface != NULL) {
        (void)snprintf(label, sizeof label, "%s", o->iface);
    }
    // Tests and scripts wait for this line before they send.
    fprintf(stderr, "mdcan: listening on %s: %s\n", bus.name, why);
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    (void)sigaction(SIGINT, &sa, NULL);
    (void)sigaction(SIGTERM, &sa, NULL);
    long long printed = 0;
    int64_t idle_us = 0;
    int status = 0;
    while (g_stop == 0 && (o->count == 0 || printed < o->count)) {
        md_frame_t f;
        const int rc = md_bus_receive(&bus, &f, DUMP_SLICE_US);
        if (rc < 0) {
            fprintf(stderr, "mdcan: receive: %s\n", strerror(-rc));
            status = EXIT_BUS;
            break;
        }
        if (rc == 0) {
            idle_us += DUMP_SLICE_US;
            if (o->timeout_ms >= 0 && idle_us >= (int64_t)o->timeout_ms * 1000) {
                break;
            }
            continue;
        }
        idle_us = 0;
        if (print_frame(label, &f) != 0) {
            status = EXIT_BUS;
            break;
        }
        ++printed;
    }
    if (status == 0 && o->count > 0 && printed < o->count) {
        fprintf(stderr, "mdcan: %lld of %lld frames before the timeout\n", printed, o->count);
        status = EXIT_INCOMPLETE;
    }
    print_stats(&bus);
    md_bus_close(&bus);
    return status;
}

static int cmd_send(const options_t *o, int argc, char **argv)
{
    // Parse every frame first: a typo sends nothing.
    for (int i = o->first_frame; i < argc; ++i) {
        md_frame_t f;
        const char *why = "";
        if (md_bus_text_parse(argv[i], &f, &why) != 0) {
            fprintf(stderr, "mdcan: bad frame '%s': %s\n", argv[i], why);
            return EXIT_USAGE;
        }
    }
    md_bus_t bus;
    char why[200] = "";
    if (open_bus(&bus, o->bus, why, sizeof why) != 0) {
        return EXIT_BUS;
    }
    int status = 0;
    for (int i = o->first_frame; i < argc && status == 0; ++i) {
        md_frame_t f;
        (void)md_bus_text_parse(argv[i], &f, NULL);
        const int rc = md_bus_send(&bus, &f);
        if (rc != 0) {
            fprintf(stderr, "mdcan: send '%s': %s\n", argv[i], strerror(-rc));
            status = EXIT_INCOMPLETE;
        }
    }
    md_bus_close(&bus);
    return status;
}

int main(int argc, char **argv)
{
    if (argc < 2) {
        return usage();
    }
    if (strcmp(argv[1], "bridge") == 0) {
        return mdcan_bridge_main(argc, argv);
    }
    const bool is_dump = strcmp(argv[1], "dump") == 0;
    if (!is_dump && strcmp(argv[1], "send") != 0) {
        return usage();
    }
    options_t o;
    if (parse_options(argc, argv, is_dump, &o) != 0) {
        return usage();
    }
    return is_dump ? cmd_dump(&o) : cmd_send(&o, argc, argv);
}
