/// @file mdcan_bridge.c
/// `mdcan bridge`: a serial line carrying md_link packets (common/link) on
/// one side, a project bus on the other, every frame passed both ways, as a
/// USB-to-CAN adapter would. The serial side is a Unix socket (QEMU's
/// `-chardev socket,server=on`), a pty or tty (QEMU `-serial pty`, a real
/// UART adapter) or any other file that can be read and written. With N
/// `--serial` the bus-to-serial byte stream is striped over them (byte k on
/// line k mod N, as the Cortex-M7 image reads its five UARTs) and frames
/// from the serial side are read from the first line. docs/pil.md.
#define _GNU_SOURCE
#include "mdcan_bridge.h"

#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include "md_bus.h"
#include "md_link.h"

/// Bytes queued per serial line: a 10 s interval of REC_DATA (10 000 frames
/// of ~75 encoded bytes) several times over, since the bus may deliver
/// faster than an emulated UART takes.
#define BRIDGE_TXQ_BYTES (16u << 20)
/// Serial lines (stripes) at most.
#define BRIDGE_LINES_MAX 8
/// Frames taken from the bus per pass at most (then the serial side again).
#define BRIDGE_BUS_BURST 4096
#define BRIDGE_READ_CHUNK 4096
#define BRIDGE_POLL_MS 100

static volatile sig_atomic_t g_stop;
static uint8_t g_txq[BRIDGE_LINES_MAX][BRIDGE_TXQ_BYTES];

typedef struct {
    uint64_t bus_rx, bus_tx, bus_tx_errors, serial_tx_bytes, serial_rx_bytes, txq_overflow, txq_peak;
} bridge_stats_t;

static void on_signal(int sig)
{
    (void)sig;
    g_stop = 1;
}

static uint64_t mono_ms(void)
{
    struct timespec ts;
    (void)clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000u + (uint64_t)ts.tv_nsec / 1000000u;
}

static int bridge_usage(void)
{
    fprintf(stderr, "usage: mdcan bridge --serial PATH [--serial PATH]... --bus SPEC [--wait-ms N]\n"
                    "PATH: a Unix socket (e.g. QEMU -chardev socket,path=PATH,server=on), a pty/tty or a file;\n"
                    "several: the bus-to-serial bytes striped over them, frames read from the first\n"
                    "--wait-ms N: wait up to N ms for PATH to appear (default 10000)\n");
    return 2;
}

/* Connects to a Unix socket, or opens a tty (raw) or another file. -1 on failure. */
static int open_serial(const char *path, long wait_ms)
{
    const uint64_t t0 = mono_ms();
    struct stat st;
    while (stat(path, &st) != 0) {
        if (g_stop != 0 || mono_ms() - t0 > (uint64_t)wait_ms) {
            fprintf(stderr, "mdcan bridge: %s: %s\n", path, strerror(errno));
            return -1;
        }
        const struct timespec ten_ms = {0, 10000000L};
        (void)nanosleep(&ten_ms, NULL);
    }
    int fd = -1;
    if (S_ISSOCK(st.st_mode)) {
        struct sockaddr_un sa;
        memset(&sa, 0, sizeof sa);
        sa.sun_family = AF_UNIX;
        if (strlen(path) >= sizeof sa.sun_path) {
            fprintf(stderr, "mdcan bridge: socket path too long: %s\n", path);
            return -1;
        }
        (void)snprintf(sa.sun_path, sizeof sa.sun_path, "%s", path);
        fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
        if (fd < 0 || connect(fd, (const struct sockaddr *)&sa, sizeof sa) != 0) {
            fprintf(stderr, "mdcan bridge: connect %s: %s\n", path, strerror(errno));
            if (fd >= 0) {
                (void)close(fd);
            }
            return -1;
        }
    } else {
        fd = open(path, O_RDWR | O_NOCTTY | O_CLOEXEC);
        if (fd < 0) {
            fprintf(stderr, "mdcan bridge: open %s: %s\n", path, strerror(errno));
            return -1;
        }
        struct termios tio;
        if (isatty(fd) && tcgetattr(fd, &tio) == 0) {
            cfmakeraw(&tio);
            (void)tcsetattr(fd, TCSANOW, &tio);
        }
    }
    (void)fcntl(fd, F_SETFL, fcntl(fd, F_GETFL) | O_NONBLOCK);
    return fd;
}

typedef struct {
    size_t head, tail; /* bytes [tail, head) modulo the size are queued */
    int line;          /* index into g_txq */
} txq_t;

static size_t txq_used(const txq_t *q)
{
    return q->head - q->tail;
}

/* n bytes striped over the lines' queues, byte k of the stream on line
 * (*next + k) mod lines; all or nothing. */
static bool txq_put(txq_t *q, int lines, int *next, const uint8_t *p, size_t n)
{
    for (int j = 0; j < lines; ++j) {
        if (BRIDGE_TXQ_BYTES - txq_used(&q[j]) < n / (size_t)lines + 1u) {
            return false;
        }
    }
    for (size_t i = 0u; i < n; ++i) {
        txq_t *l = &q[*next];
        g_txq[l->line][l->head % BRIDGE_TXQ_BYTES] = p[i];
        l->head++;
        *next = (*next + 1) % lines;
    }
    return true;
}

/* Writes what the serial side takes now. -1 on a write error. */
static int txq_flush(txq_t *q, int fd, bridge_stats_t *s)
{
    for (int k = 0; k < 64 && txq_used(q) > 0u; ++k) {
        const size_t off = q->tail % BRIDGE_TXQ_BYTES;
        size_t n = txq_used(q);
        if (n > BRIDGE_TXQ_BYTES - off) {
            n = BRIDGE_TXQ_BYTES - off;
        }
        const ssize_t w = write(fd, &g_txq[q->line][off], n);
        if (w < 0) {
            return (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) ? 0 : -1;
        }
        q->tail += (size_t)w;
        s->serial_tx_bytes += (uint64_t)w;
    }
    return 0;
}

static void print_stats(const bridge_stats_t *s, const md_link_decoder_t *d, const md_bus_t *bus)
{
    fprintf(stderr,
            "mdcan bridge: bus->serial %llu frames (%llu bytes, queue peak %llu bytes, lost to a full queue "
            "%llu); serial->bus %llu frames (%llu bytes; send errors %llu; dropped packets: crc %u, frame %u, "
            "escape %u, too long %u); bus rx overflow %llu, malformed %llu\n",
            (unsigned long long)s->bus_rx, (unsigned long long)s->serial_tx_bytes, (unsigned long long)s->txq_peak,
            (unsigned long long)s->txq_overflow, (unsigned long long)s->bus_tx, (unsigned long long)s->serial_rx_bytes,
            (unsigned long long)s->bus_tx_errors, (unsigned)d->bad_crc, (unsigned)d->bad_frame, (unsigned)d->bad_esc,
            (unsigned)d->too_long, (unsigned long long)bus->stats.rx_overflow,
            (unsigned long long)bus->stats.rx_malformed);
}

/* Bus frames into the serial queues. -1 on a bus error. */
static int bus_to_queue(md_bus_t *bus, txq_t *q, int lines, int *next, bridge_stats_t *s)
{
    for (int k = 0; k < BRIDGE_BUS_BURST; ++k) {
        md_frame_t f;
        const int rc = md_bus_receive(bus, &f, 0);
        if (rc == 0) {
            return 0;
        }
        if (rc < 0) {
            return (rc == -EINTR) ? 0 : -1;
        }
        uint8_t enc[MD_LINK_ENCODED_MAX];
        const size_t n = md_link_encode(&f, enc, sizeof enc);
        s->bus_rx++;
        if (n == 0u || !txq_put(q, lines, next, enc, n)) {
            s->txq_overflow++;
            if (s->txq_overflow <= 10u) {
                fprintf(stderr, "mdcan bridge: serial queue full: frame 0x%X lost\n", (unsigned)f.id);
            }
        }
        size_t used = 0u;
        for (int j = 0; j < lines; ++j) {
            used += txq_used(&q[j]);
        }
        if (used > s->txq_peak) {
            s->txq_peak = used;
        }
    }
    return 0;
}

/* Serial bytes into frames on the bus. 1 at end of file, -1 on error. */
static int serial_to_bus(int fd, md_link_decoder_t *d, md_bus_t *bus, bridge_stats_t *s)
{
    uint8_t buf[BRIDGE_READ_CHUNK];
    for (int k = 0; k < 64; ++k) {
        const ssize_t n = read(fd, buf, sizeof buf);
        if (n == 0) {
            return 1;
        }
        if (n < 0) {
            return (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) ? 0 : -1;
        }
        s->serial_rx_bytes += (uint64_t)n;
        for (ssize_t i = 0; i < n; ++i) {
            md_frame_t f;
            const md_link_result_t r = md_link_decode_byte(d, buf[i], &f);
            if (r == MD_LINK_FRAME) {
                if (md_bus_send(bus, &f) == 0) {
                    s->bus_tx++;
                } else {
                    s->bus_tx_errors++;
                }
            } else if (r != MD_LINK_NONE) {
                fprintf(stderr, "mdcan bridge: dropped a serial packet (reason %d)\n", (int)r);
            }
        }
    }
    return 0;
}

typedef struct {
    const char *serial[BRIDGE_LINES_MAX];
    int lines;
    const char *spec;
    long wait_ms;
} bridge_opts_t;

/* --serial PATH... --bus SPEC [--wait-ms MS]: 0, or 2 after the usage. */
static int bridge_parse(int argc, char **argv, bridge_opts_t *o)
{
    o->lines = 0;
    o->spec = NULL;
    o->wait_ms = 10000;
    for (int i = 2; i < argc; ++i) {
        if (strcmp(argv[i], "--serial") == 0 && i + 1 < argc && o->lines < BRIDGE_LINES_MAX) {
            o->serial[o->lines++] = argv[++i];
        } else if (strcmp(argv[i], "--bus") == 0 && i + 1 < argc) {
            o->spec = argv[++i];
        } else if (strcmp(argv[i], "--wait-ms") == 0 && i + 1 < argc) {
            char *end = NULL;
            o->wait_ms = strtol(argv[++i], &end, 10);
            if (end == argv[i] || *end != '\0' || o->wait_ms < 0) {
                return bridge_usage();
            }
        } else {
            return bridge_usage();
        }
    }
    return (o->lines == 0 || o->spec == NULL) ? bridge_usage() : 0;
}

/* Signals, the bus and every serial line, in order (QEMU serves its chardevs one after the other):
 * 0, or the exit status with nothing left open. */
static int bridge_open(const bridge_opts_t *o, md_bus_t *bus, int *fds)
{
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    (void)sigaction(SIGINT, &sa, NULL);
    (void)sigaction(SIGTERM, &sa, NULL);
    (void)signal(SIGPIPE, SIG_IGN); /* a closed serial side is an EPIPE, handled below */
    char why[200] = "";
    const int rc = md_bus_open(bus, o->spec, why, sizeof why);
    if (rc != 0) {
        fprintf(stderr, "mdcan bridge: cannot open bus '%s': %s (%s)\n", o->spec, why, strerror(-rc));
        return 3;
    }
    if (bus->kind == MD_BUS_INPROC || md_bus_fd(bus) < 0) {
        fprintf(stderr, "mdcan bridge: bus '%s' has no file descriptor to wait on (inproc?)\n", o->spec);
        md_bus_close(bus);
        return 2;
    }
    for (int j = 0; j < o->lines; ++j) {
        fds[j] = open_serial(o->serial[j], o->wait_ms);
        if (fds[j] < 0) {
            for (int k = 0; k < j; ++k) {
                (void)close(fds[k]);
            }
            md_bus_close(bus);
            return 3;
        }
        fprintf(stderr, "mdcan bridge: serial %s <-> bus %s (%s)\n", o->serial[j], bus->name, why);
    }
    return 0;
}

/* Every queue written to its line; false when one is closed or fails (*status 1 for a failure). */
static bool bridge_flush(txq_t *q, const int *fds, int lines, bridge_stats_t *st, int *status)
{
    for (int j = 0; j < lines; ++j) {
        if (txq_flush(&q[j], fds[j], st) != 0) {
            if (errno == EPIPE || errno == ECONNRESET) {
                fprintf(stderr, "mdcan bridge: serial side closed\n");
            } else {
                fprintf(stderr, "mdcan bridge: serial write failed: %s\n", strerror(errno));
                *status = 1;
            }
            return false;
        }
    }
    return true;
}

/* Frames both ways until a signal, a closed side or a failure: the exit status (0 or 1). Frames from the
 * serial side come from the first line. */
static int bridge_loop(md_bus_t *bus, const int *fds, int lines, md_link_decoder_t *dec, txq_t *q, bridge_stats_t *st)
{
    int next = 0;
    int status = 0;
    while (g_stop == 0) {
        struct pollfd pfd[BRIDGE_LINES_MAX + 1];
        for (int j = 0; j < lines; ++j) {
            pfd[j] = (struct pollfd){fds[j], (short)((j == 0 ? POLLIN : 0) | (txq_used(&q[j]) > 0u ? POLLOUT : 0)), 0};
        }
        pfd[lines] = (struct pollfd){md_bus_fd(bus), POLLIN, 0};
        const int n = poll(pfd, (nfds_t)lines + 1u, BRIDGE_POLL_MS);
        if (n < 0 && errno != EINTR) {
            return 1;
        }
        if (bus_to_queue(bus, q, lines, &next, st) != 0) {
            fprintf(stderr, "mdcan bridge: bus receive failed\n");
            return 1;
        }
        if (!bridge_flush(q, fds, lines, st, &status)) {
            return status;
        }
        const int r = serial_to_bus(fds[0], dec, bus, st);
        if (r != 0) {
            if (r < 0) {
                fprintf(stderr, "mdcan bridge: serial read failed: %s\n", strerror(errno));
                return 1;
            }
            fprintf(stderr, "mdcan bridge: serial side closed\n");
            return 0;
        }
        if ((pfd[0].revents & (POLLHUP | POLLERR)) != 0 && (pfd[0].revents & POLLIN) == 0) {
            fprintf(stderr, "mdcan bridge: serial side hung up\n");
            return 0;
        }
    }
    return status;
}

int mdcan_bridge_main(int argc, char **argv)
{
    bridge_opts_t o;
    int rc = bridge_parse(argc, argv, &o);
    if (rc != 0) {
        return rc;
    }
    md_bus_t bus;
    int fds[BRIDGE_LINES_MAX];
    rc = bridge_open(&o, &bus, fds);
    if (rc != 0) {
        return rc;
    }
    static md_link_decoder_t dec;
    md_link_decoder_init(&dec);
    static txq_t q[BRIDGE_LINES_MAX];
    for (int j = 0; j < o.lines; ++j) {
        q[j] = (txq_t){0u, 0u, j};
    }
    bridge_stats_t st;
    memset(&st, 0, sizeof st);
    int status = bridge_loop(&bus, fds, o.lines, &dec, q, &st);
    print_stats(&st, &dec, &bus);
    for (int j = 0; j < o.lines; ++j) {
        (void)close(fds[j]);
    }
    md_bus_close(&bus);
    if (st.txq_overflow > 0u || st.bus_tx_errors > 0u ||
        dec.bad_crc + dec.bad_frame + dec.bad_esc + dec.too_long > 0u) {
        status = 1;
    }
    return status;
}
