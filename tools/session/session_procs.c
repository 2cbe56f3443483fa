/// @file session_procs.c
/// The session on a socket bus (vcan0 / UDP multicast): microdrive-fw and
/// microdrive-sim as separate processes, and the recorder as an endpoint of
/// this process. The controller starts first and the simulator only once the
/// controller's boot-up heartbeat is on the bus, so the controller sees the
/// plant's start-up batch, as in the in-process mode. With --controller m7
/// the controller is the Cortex-M7 image under qemu-system-arm, its UART on a
/// Unix socket that `mdcan bridge` connects to the bus (docs/pil.md).
#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <signal.h>
#include <spawn.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "md_bus.h"
#include "session.h"

extern char **environ;

#define PROCS_SLICE_US 50000
#define PROCS_BOOT_WAIT_US 10000000u
/* After the goal: how long to wait for the telemetry of the cycle that reached
 * it (session_track_done_complete), wall time. */
#define PROCS_TAIL_WAIT_US 60000000u
#define PROCS_TERM_WAIT_MS 15000 /* a slow VM may be in the middle of a 10 s batch */
/// SocketCAN (no flow control): the recorder's socket buffer. A 10 s interval
/// is ~11 000 frames in a burst, each charged ~1 kB of buffer, and the
/// recorder must lose none of them even on a loaded machine.
#define PROCS_RCVBUF_BYTES (64 << 20)
/// SocketCAN: the buffer below which a reader that falls behind for the
/// length of one interval's burst loses frames (11 000 frames x ~1 kB).
#define PROCS_BURST_BYTES (12 << 20)
#ifndef SO_RCVBUFFORCE
#define SO_RCVBUFFORCE 33 /* Linux; glibc hides it outside _GNU_SOURCE */
#endif

static md_bus_t g_rec; /* must not move while open */

static uint64_t wall_us(void)
{
    struct timespec ts;
    (void)clock_gettime(CLOCK_REALTIME, &ts);
    return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

static uint64_t mono_us(void)
{
    struct timespec ts;
    (void)clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

/* Starts argv[0] (through PATH if it has no '/') with stdout and stderr into
 * log_path. -1 on failure. */
static pid_t spawn_logged(char *const argv[], const char *log_path)
{
    posix_spawn_file_actions_t fa;
    pid_t pid = -1;
    if (posix_spawn_file_actions_init(&fa) != 0) {
        return -1;
    }
    (void)posix_spawn_file_actions_addopen(&fa, 1, log_path, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    (void)posix_spawn_file_actions_adddup2(&fa, 1, 2);
    const int rc = (strchr(argv[0], '/') != NULL) ? posix_spawn(&pid, argv[0], &fa, NULL, argv, environ)
                                                  : posix_spawnp(&pid, argv[0], &fa, NULL, argv, environ);
    (void)posix_spawn_file_actions_destroy(&fa);
    if (rc != 0) {
        fprintf(stderr, "microdrive-session: cannot start %s: %s\n", argv[0], strerror(rc));
        return -1;
    }
    return pid;
}

static int record_slice(session_track_t *t, int64_t slice_us);

/* SIGTERM, a bounded wait, then SIGKILL. Returns the exit status or -1.
 * The recorder keeps reading meanwhile: the simulator may be in the middle
 * of a batch, and on UDP its flow control waits for every reader, the
 * recorder included (a recorder that stopped reading for 10 s would be
 * marked stalled and lose the rest of the batch). */
static int stop_child(pid_t pid, session_track_t *t)
{
    int status = 0;
    if (pid <= 0) {
        return -1;
    }
    (void)kill(pid, SIGTERM);
    const uint64_t t0 = mono_us();
    while (mono_us() - t0 < (uint64_t)PROCS_TERM_WAIT_MS * 1000u) {
        if (waitpid(pid, &status, WNOHANG) == pid) {
            return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
        }
        (void)record_slice(t, 10000);
    }
    (void)kill(pid, SIGKILL);
    (void)waitpid(pid, &status, 0);
    return -1;
}

static bool child_gone(pid_t pid, const char *name)
{
    int status = 0;
    if (waitpid(pid, &status, WNOHANG) != pid) {
        return false;
    }
    fprintf(stderr, "microdrive-session: %s ended early (%s %d)\n", name, WIFEXITED(status) ? "exit" : "signal",
            WIFEXITED(status) ? WEXITSTATUS(status) : WTERMSIG(status));
    return true;
}

/* Receives for at most slice_us; every frame goes to the recorder. */
static int record_slice(session_track_t *t, int64_t slice_us)
{
    md_frame_t f;
    int rc = md_bus_receive(&g_rec, &f, slice_us);
    while (rc == 1) {
        session_track_frame(t, &f, wall_us());
        rc = md_bus_receive(&g_rec, &f, 0);
    }
    return (rc < 0 && rc != -EINTR) ? rc : 0;
}

static long read_rmem_max(void)
{
    long v = -1;
    FILE *f = fopen("/proc/sys/net/core/rmem_max", "r");
    if (f != NULL) {
        if (fscanf(f, "%ld", &v) != 1) {
            v = -1;
        }
        (void)fclose(f);
    }
    return v;
}

/* Warns when the limits of this machine can make the session lose frames:
 * a UDP bus without flow control, or SocketCAN (no flow control at all) with
 * socket buffers smaller than one interval's burst. Lost frames are still
 * counted, and a session that lost any ends with status 1. */
static void warn_buffer_limits(int fd)
{
    int granted = 0;
    socklen_t glen = sizeof granted;
    if (fd < 0 || getsockopt(fd, SOL_SOCKET, SO_RCVBUF, &granted, &glen) != 0) {
        granted = 0;
    }
    const long rmem_max = read_rmem_max();
    if (g_rec.kind == MD_BUS_UDP && g_rec.sock.flow == 0u) {
        fprintf(stderr,
                "microdrive-session: WARNING: the UDP bus has no flow control here (the bus line says why): a "
                "process that falls behind loses frames once its %d-byte socket buffer is full "
                "(net.core.rmem_max %ld); see docs/bus.md\n",
                granted, rmem_max);
    } else if (g_rec.kind == MD_BUS_SOCKETCAN && granted < PROCS_BURST_BYTES) {
        fprintf(stderr,
                "microdrive-session: WARNING: SocketCAN has no flow control and the socket buffers are small "
                "(recorder %d bytes, net.core.rmem_max %ld; one interval's burst needs ~%d): a process that falls "
                "behind loses frames; run as root or raise net.core.rmem_max (docs/bus.md)\n",
                granted, rmem_max, PROCS_BURST_BYTES);
    }
}

static int open_recorder(const session_opts_t *o, session_track_t *t, char *bus_used, size_t len)
{
    char why[200] = "";
    const int rc = md_bus_open(&g_rec, o->bus, why, sizeof why);
    if (rc != 0) {
        fprintf(stderr, "microdrive-session: cannot open bus '%s': %s (%s)\n", o->bus, why, strerror(-rc));
        return -1;
    }
    if (g_rec.kind == MD_BUS_UDP) {
        (void)snprintf(bus_used, len, "udp:%u", (unsigned)g_rec.sock.port);
        (void)snprintf(t->iface, sizeof t->iface, "udp%u", (unsigned)g_rec.sock.port);
    } else if (g_rec.kind == MD_BUS_SOCKETCAN) {
        (void)snprintf(bus_used, len, "%s", g_rec.name);
        (void)snprintf(t->iface, sizeof t->iface, "%.15s", g_rec.name);
    } else {
        fprintf(stderr, "microdrive-session: bus '%s' is not a socket bus\n", o->bus);
        md_bus_close(&g_rec);
        return -1;
    }
    /* SocketCAN has no flow control: beyond rmem_max when allowed (root).
     * The UDP bus keeps its stock buffer: its flow control makes the
     * senders wait for the recorder instead. */
    const int fd = md_bus_fd(&g_rec), size = PROCS_RCVBUF_BYTES;
    if (g_rec.kind == MD_BUS_SOCKETCAN && fd >= 0 &&
        setsockopt(fd, SOL_SOCKET, SO_RCVBUFFORCE, &size, sizeof size) != 0) {
        (void)setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &size, sizeof size);
    }
    fprintf(stderr, "microdrive-session: bus %s (%s)\n", bus_used, why);
    warn_buffer_limits(fd);
    return 0;
}

static session_end_t procs_loop(const session_opts_t *o, session_track_t *t, pid_t fw, pid_t bridge, pid_t sim)
{
    uint64_t last_activity = t->activity, activity_at = mono_us(), goal_at = 0u;
    const uint64_t idle_us = (uint64_t)(o->idle_s * 1e6);
    for (;;) { /* ends by the goal, idleness, a signal or a dead process */
        if (record_slice(t, PROCS_SLICE_US) != 0) {
            return SESSION_END_ERROR;
        }
        /* The goal's last TLM_STATUS is followed by that cycle's telemetry;
         * over a slow link (--controller m7) it is still on its way: the
         * processes stop once the controller has moved on to its next step. */
        if (session_track_done_complete(t)) {
            return SESSION_END_GOAL;
        }
        if (session_track_done(t)) {
            if (goal_at == 0u) {
                goal_at = mono_us();
            } else if (mono_us() - goal_at >= PROCS_TAIL_WAIT_US) {
                fprintf(stderr,
                        "microdrive-session: WARNING: the controller did not move on within %u s of the "
                        "goal: the telemetry of its last cycle may be incomplete\n",
                        (unsigned)(PROCS_TAIL_WAIT_US / 1000000u));
                return SESSION_END_GOAL;
            }
        }
        if (session_stop_signal != 0) {
            return SESSION_END_SIGNAL;
        }
        if (child_gone(fw, o->controller == SESSION_CTRL_M7 ? "qemu-system-arm" : "microdrive-fw") ||
            child_gone(sim, "microdrive-sim") || (bridge > 0 && child_gone(bridge, "mdcan bridge"))) {
            return SESSION_END_ERROR;
        }
        const uint64_t now = mono_us();
        if (t->activity != last_activity) {
            last_activity = t->activity;
            activity_at = now;
        } else if (now - activity_at >= idle_us) {
            return SESSION_END_IDLE;
        }
    }
}

/* microdrive-fw --bus B --auto-start [--param ...] with its log in DIR/fw.log. */
static pid_t start_host_controller(const session_opts_t *o, const char *bus, const char *fw_log)
{
    static char fw_path[4096], bus_arg[64];
    (void)snprintf(bus_arg, sizeof bus_arg, "%s", bus);
    (void)snprintf(fw_path, sizeof fw_path, "%s/microdrive-fw", o->bin_dir);
    /* --param NAME=VALUE goes to microdrive-fw, which applies it before the start */
    static char params[SESSION_MAX_PARAMS][128];
    char *fw_argv[5u + 2u * SESSION_MAX_PARAMS] = {fw_path, "--bus", bus_arg, "--auto-start"};
    size_t n = 4u;
    for (uint32_t i = 0u; i < o->n_params && i < SESSION_MAX_PARAMS; ++i) {
        (void)snprintf(params[i], sizeof params[i], "%s", o->params[i].arg);
        fw_argv[n++] = "--param";
        fw_argv[n++] = params[i];
    }
    fw_argv[n] = NULL;
    return spawn_logged(fw_argv, fw_log);
}

/// UARTs of the AN500 that carry the link (md_can_uart.h: MD_CAN_UART_STRIPES).
#define M7_UARTS 5
/* Unix sockets of the M7's UARTs (short paths: sun_path has 108 bytes). */
static char g_uart_dir[64], g_uart_sock[M7_UARTS][96];

/* The image: --m7-image, else $MD_M7_IMAGE, else the cortex-m7 build next to this one. -1 if unreadable. */
static int m7_image_path(const session_opts_t *o, char *image, size_t size)
{
    const char *env_image = getenv("MD_M7_IMAGE");
    if (o->m7_image != NULL) {
        (void)snprintf(image, size, "%s", o->m7_image);
    } else if (env_image != NULL && env_image[0] != '\0') {
        (void)snprintf(image, size, "%s", env_image);
    } else {
        (void)snprintf(image, size, "%s/../../cortex-m7/bin/microdrive-fw-m7.elf", o->bin_dir);
    }
    if (access(image, R_OK) != 0) {
        fprintf(stderr,
                "microdrive-session: no Cortex-M7 image %s (cmake --preset cortex-m7 && cmake --build "
                "--preset cortex-m7, or --m7-image)\n",
                image);
        return -1;
    }
    return 0;
}

/* QEMU's -semihosting-config: the image's command line as arg=WORD (QEMU option syntax: no commas in a
 * word). -1 if a --param has a comma or the line does not fit. */
static int m7_semihosting(const session_opts_t *o, char *semi, size_t size)
{
    int at = snprintf(semi, size, "enable=on,target=native,arg=microdrive-fw-m7,arg=--auto-start");
    for (uint32_t i = 0u; i < o->n_params && i < SESSION_MAX_PARAMS && at > 0 && (size_t)at < size; ++i) {
        if (strchr(o->params[i].arg, ',') != NULL) {
            fprintf(stderr, "microdrive-session: --param %s: no commas with --controller m7\n", o->params[i].arg);
            return -1;
        }
        at += snprintf(semi + at, size - (size_t)at, ",arg=--param,arg=%s", o->params[i].arg);
    }
    if (at <= 0 || (size_t)at >= size) {
        fprintf(stderr, "microdrive-session: the image's command line is too long\n");
        return -1;
    }
    return 0;
}

/* A fresh folder for the UART sockets and QEMU's -chardev/-serial words for each UART. -1 on failure. */
static int m7_uarts(char chardev[M7_UARTS][512], char serial[M7_UARTS][16])
{
    (void)snprintf(g_uart_dir, sizeof g_uart_dir, "/tmp/md-pil-XXXXXX");
    if (mkdtemp(g_uart_dir) == NULL) {
        fprintf(stderr, "microdrive-session: mkdtemp: %s\n", strerror(errno));
        g_uart_dir[0] = '\0';
        return -1;
    }
    for (int j = 0; j < M7_UARTS; ++j) {
        (void)snprintf(g_uart_sock[j], sizeof g_uart_sock[j], "%s/uart%d.sock", g_uart_dir, j);
        (void)snprintf(chardev[j], 512, "socket,id=uart%d,path=%.100s,server=on,wait=on", j, g_uart_sock[j]);
        (void)snprintf(serial[j], 16, "chardev:uart%d", j);
    }
    return 0;
}

/* mdcan bridge from the UART sockets to the bus, its log in DIR/bridge.log. */
static pid_t m7_start_bridge(const session_opts_t *o, const char *bus)
{
    static char mdcan[4096], bridge_log[4096], bus_arg[64];
    (void)snprintf(mdcan, sizeof mdcan, "%s/mdcan", o->bin_dir);
    (void)snprintf(bus_arg, sizeof bus_arg, "%s", bus);
    (void)snprintf(bridge_log, sizeof bridge_log, "%s/bridge.log", o->out);
    char *const bridge_argv[] = {mdcan,      "bridge",       "--serial",  g_uart_sock[0], "--serial", g_uart_sock[1],
                                 "--serial", g_uart_sock[2], "--serial",  g_uart_sock[3], "--serial", g_uart_sock[4],
                                 "--bus",    bus_arg,        "--wait-ms", "10000",        NULL};
    return spawn_logged(bridge_argv, bridge_log);
}

/* The Cortex-M7 image under QEMU (semihosting console into fw_log), its five
 * UARTs on Unix sockets that QEMU serves, and the bridge from those sockets to
 * the bus (DIR/bridge.log). QEMU waits for the bridge before the image starts. */
static pid_t start_m7_controller(const session_opts_t *o, const char *bus, const char *fw_log, pid_t *bridge)
{
    static char image[4096], qemu[4096], icount[32];
    static char chardev[M7_UARTS][512], serial[M7_UARTS][16];
    static char semi[4096];
    const char *env_qemu = getenv("MD_QEMU");
    if (m7_image_path(o, image, sizeof image) != 0) {
        return -1;
    }
    (void)snprintf(qemu, sizeof qemu, "%s",
                   o->qemu != NULL ? o->qemu
                                   : ((env_qemu != NULL && env_qemu[0] != '\0') ? env_qemu : "qemu-system-arm"));
    if (m7_uarts(chardev, serial) != 0) {
        return -1;
    }
    (void)snprintf(icount, sizeof icount, "shift=%u", (unsigned)o->icount_shift);
    if (m7_semihosting(o, semi, sizeof semi) != 0) {
        return -1;
    }
    char *const qemu_argv[] = {qemu,       "-M",       "mps2-an500", "-display", "none",     "-monitor",
                               "none",     "-icount",  icount,       "-chardev", chardev[0], "-serial",
                               serial[0],  "-chardev", chardev[1],   "-serial",  serial[1],  "-chardev",
                               chardev[2], "-serial",  serial[2],    "-chardev", chardev[3], "-serial",
                               serial[3],  "-chardev", chardev[4],   "-serial",  serial[4],  "-semihosting-config",
                               semi,       "-kernel",  image,        NULL};
    _Static_assert(M7_UARTS == 5, "qemu_argv lists five UARTs");
    fprintf(stderr, "microdrive-session: controller: %s under %s -icount %s, UART0..4 on %s/uart*.sock\n", image, qemu,
            icount, g_uart_dir);
    const pid_t pid = spawn_logged(qemu_argv, fw_log);
    if (pid < 0) {
        return -1;
    }
    *bridge = m7_start_bridge(o, bus);
    return pid;
}

/* The controller first; the simulator once its boot-up heartbeat is seen. */
static session_end_t procs_start(const session_opts_t *o, session_track_t *t, const char *bus, pid_t *fw, pid_t *bridge,
                                 pid_t *sim)
{
    static char sim_path[4096], fw_log[4096], sim_log[4096], truth[4096], seed[32];
    static char bus_arg[64], scen[4096], pace[32];
    (void)snprintf(pace, sizeof pace, "%u", (unsigned)o->pace_fps);
    (void)snprintf(bus_arg, sizeof bus_arg, "%s", bus);
    (void)snprintf(scen, sizeof scen, "%s", o->scenario);
    (void)snprintf(sim_path, sizeof sim_path, "%s/microdrive-sim", o->bin_dir);
    (void)snprintf(fw_log, sizeof fw_log, "%s/fw.log", o->out);
    (void)snprintf(sim_log, sizeof sim_log, "%s/sim.log", o->out);
    (void)snprintf(truth, sizeof truth, "%s/truth.jsonl", o->out);
    (void)snprintf(seed, sizeof seed, "%" PRIu64, o->seed);
    const bool m7 = o->controller == SESSION_CTRL_M7;
    *fw = m7 ? start_m7_controller(o, bus, fw_log, bridge) : start_host_controller(o, bus, fw_log);
    if (*fw < 0 || (m7 && *bridge < 0)) {
        return SESSION_END_ERROR;
    }
    const char *fw_name = m7 ? "qemu-system-arm" : "microdrive-fw";
    const uint64_t t0 = mono_us();
    while (!t->fw_booted && mono_us() - t0 < PROCS_BOOT_WAIT_US) {
        if (record_slice(t, PROCS_SLICE_US) != 0 || child_gone(*fw, fw_name) ||
            (m7 && child_gone(*bridge, "mdcan bridge")) || session_stop_signal != 0) {
            return SESSION_END_ERROR;
        }
    }
    if (!t->fw_booted) {
        fprintf(stderr, "microdrive-session: no boot-up heartbeat of the controller (see %s)\n", fw_log);
        return SESSION_END_ERROR;
    }
    char *const sim_argv[] = {sim_path,  "--scenario", scen,           "--seed", seed,     "--bus", bus_arg,
                              "--truth", truth,        "--duration-s", "0",      "--pace", pace,    NULL};
    *sim = spawn_logged(sim_argv, sim_log);
    return (*sim < 0) ? SESSION_END_ERROR : SESSION_END_GOAL;
}

/* The last "bus stats:" line of a process's log (md_bus_stats_format).
 * Returns true with the counts if there is one. */
static bool log_bus_stats(const char *path, unsigned long long *overflow, unsigned long long *malformed,
                          unsigned long long *waits, unsigned long long *timeouts)
{
    FILE *f = fopen(path, "r");
    if (f == NULL) {
        return false;
    }
    char line[512];
    bool found = false;
    while (fgets(line, sizeof line, f) != NULL) {
        const char *p = strstr(line, "bus stats: ");
        unsigned long long rx = 0, ov = 0, mal = 0, tx = 0, txe = 0, w = 0, to = 0;
        if (p != NULL && sscanf(p,
                                "bus stats: rx %llu, rx overflow %llu, rx malformed %llu, tx %llu, tx errors %llu, "
                                "flow waits %llu, flow timeouts %llu",
                                &rx, &ov, &mal, &tx, &txe, &w, &to) == 7) {
            *overflow = ov;
            *malformed = mal;
            *waits = w;
            *timeouts = to;
            found = true;
        }
    }
    (void)fclose(f);
    return found;
}

/* Frames lost by the simulator and the controller (their bus counters, from
 * their logs) and by the recorder: printed; any loss fails the session. */
static bool report_losses(const session_opts_t *o)
{
    static char path[4096];
    static const char *const names[2] = {"microdrive-sim", "microdrive-fw"};
    static const char *const logs[2] = {"sim.log", "fw.log"};
    bool lost = g_rec.stats.rx_overflow > 0u || g_rec.stats.rx_malformed > 0u;
    fprintf(stderr, "microdrive-session: frames lost: recorder %" PRIu64 " (malformed %" PRIu64 ")",
            g_rec.stats.rx_overflow, g_rec.stats.rx_malformed);
    for (unsigned i = 0; i < 2u; i++) {
        unsigned long long ov = 0, mal = 0, w = 0, to = 0;
        (void)snprintf(path, sizeof path, "%s/%s", o->out, logs[i]);
        if (log_bus_stats(path, &ov, &mal, &w, &to)) {
            fprintf(stderr, ", %s %llu (malformed %llu; flow waits %llu, timeouts %llu)", names[i], ov, mal, w, to);
            lost = lost || ov > 0u || mal > 0u;
        } else {
            fprintf(stderr, ", %s not reported (no bus stats in %s)", names[i], logs[i]);
        }
    }
    fprintf(stderr, "\n");
    return lost;
}

session_end_t session_run_procs(const session_opts_t *o, session_track_t *t, char *bus_used, size_t bus_used_len)
{
    pid_t fw = -1, bridge = -1, sim = -1;
    if (open_recorder(o, t, bus_used, bus_used_len) != 0) {
        return SESSION_END_ERROR;
    }
    session_end_t end = procs_start(o, t, bus_used, &fw, &bridge, &sim);
    if (end == SESSION_END_GOAL) {
        end = procs_loop(o, t, fw, bridge, sim);
    }
    (void)stop_child(sim, t);
    /* the bridge before QEMU, so that its counters are of the session */
    if (bridge > 0 && stop_child(bridge, t) != 0) {
        fprintf(stderr, "microdrive-session: the bridge lost or refused frames (see %s/bridge.log)\n", o->out);
        end = SESSION_END_ERROR;
    }
    (void)stop_child(fw, t);
    if (g_uart_dir[0] != '\0') {
        for (int j = 0; j < M7_UARTS; ++j) {
            (void)unlink(g_uart_sock[j]);
        }
        (void)rmdir(g_uart_dir);
    }
    (void)record_slice(t, 200000); /* the last frames in flight */
    if (report_losses(o)) {
        fprintf(stderr, "microdrive-session: frames were lost on the bus: the report could be wrong\n");
        end = SESSION_END_ERROR;
    }
    md_bus_close(&g_rec);
    return end;
}
