/// @file session.h
/// microdrive-session: one host-in-loop session of the simulator's plant and
/// the controller firmware, on a socket bus (separate processes) or in one
/// process on an in-process bus with a virtual clock. Design: docs/session.md.
///
/// The parts: the options (session_cli.c), the recorder that writes every
/// frame in candump -L format and follows the controller's telemetry for
/// progress lines and the end of the session (session_track.c), the two
/// runners (session_inproc.c, session_procs.c), the scorer call
/// (session_main.c -> tools/session/score.py) and the telemetry steps after it
/// (session_main.c -> md-lcm-bridge --write-log, tools/plots/plot_session.py).
#ifndef SESSION_H
#define SESSION_H

#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>

#include "md_frame.h"
#include "md_params.h"

/// Electrodes a session follows at most (the simulator's limit).
#define SESSION_MAX_ELECTRODES 8u

/// --param NAME=VALUE options a session takes at most.
#define SESSION_MAX_PARAMS 32u

/// One controller parameter set before the session starts (--param).
typedef struct {
    const char *arg;  ///< "NAME=VALUE" as given (passed on to microdrive-fw)
    uint16_t index;   ///< bus index of NAME (md_params table)
    double value;
} session_param_t;

typedef enum { SESSION_BUS_INPROC = 0, SESSION_BUS_SOCKET = 1 } session_bus_mode_t;

/// The simulator's frame rate cap with --controller m7 unless --pace is given:
/// below what the emulated UARTs carry on a loaded 2-core machine (docs/pil.md),
/// so frames do not queue up in the bridge ahead of the plant's heartbeats.
#define SESSION_M7_PACE_FPS 2000u

/// --idle-s with --controller m7 unless given: a 10 s interval takes the
/// emulated UARTs tens of seconds on a loaded machine, with no frame on the
/// bus meanwhile (the simulator has sent it all; it waits in the bridge and
/// the sockets), which is not a controller waiting for nothing.
#define SESSION_M7_IDLE_S 300.0

/// heartbeat_timeout_ms with --controller m7 unless --param sets it: the
/// plant's heartbeats (wall clock) reach the emulated controller through the
/// bridge's queue and the UARTs, whose latency on a loaded machine exceeds the
/// default 500 ms; lost heartbeats would stop motion and change the session
/// (docs/pil.md). Decisions do not depend on the value while none is lost.
#define SESSION_M7_HEARTBEAT_TIMEOUT "heartbeat_timeout_ms=10000"

/// Which controller runs the session.
typedef enum {
    SESSION_CTRL_HOST = 0,  ///< microdrive-fw (socket bus) or the controller in this process (inproc)
    SESSION_CTRL_M7 = 1     ///< microdrive-fw-m7.elf under qemu-system-arm + mdcan bridge (docs/pil.md)
} session_controller_t;

typedef struct {
    const char *scenario;  ///< --scenario FILE
    uint64_t seed;         ///< --seed N (default: the scenario's)
    bool seed_given;
    const char *bus;                             ///< --bus auto|vcan0|udp|udp:PORT|IFACE|inproc
    const char *out;                             ///< --out DIR
    uint32_t cycles;                             ///< --cycles N: every electrode completes N cycles (0: unused)
    double duration_s;                           ///< --duration-s S: simulated seconds (<0: unused)
    double idle_s;                               ///< --idle-s: end when nothing but heartbeats moved for this long
    const char *bin_dir;                         ///< --bin-dir: microdrive-sim/-fw (default: next to this program)
    const char *python;                          ///< --python: interpreter for the scorer
    uint32_t pace_fps;                           ///< --pace: microdrive-sim's frame rate cap on a socket bus
                                                 ///< (default 10000; with --controller m7 SESSION_M7_PACE_FPS)
    bool no_score;                               ///< --no-score: leave report.json out
    bool quiet;                                  ///< --quiet: no progress lines
    bool candump_samples;                        ///< --candump-samples: REC_DATA frames go to candump.log too
    bool no_recording;                           ///< --no-recording: no recording.bin / recording.json
    bool no_lcm;                                 ///< --no-lcm: no session.lcmlog (and therefore no plots)
    bool no_plots;                               ///< --no-plots: no PNG files
    session_param_t params[SESSION_MAX_PARAMS];  ///< --param, in command-line order
    uint32_t n_params;
    session_controller_t controller;  ///< --controller host|m7
    const char *m7_image;             ///< --m7-image: the Cortex-M7 image (default: $MD_M7_IMAGE, else
                                      ///< <bin-dir>/../../cortex-m7/bin/microdrive-fw-m7.elf)
    const char *qemu;                 ///< --qemu: qemu-system-arm (default: $MD_QEMU, else through PATH)
    uint32_t icount_shift;            ///< --icount-shift N: QEMU -icount shift=N (default 1: 2 ns per instruction)
    bool help;
} session_opts_t;

/// Parses argv. 0 ok, -1 usage error (message in msg).
int session_cli_parse(session_opts_t *o, int argc, char *const argv[], char *msg, size_t msglen);
/// Writes the --help text to f.
void session_cli_print_usage(FILE *f);

/// Applies the --param options to a controller's parameter table, in order,
/// through md_params_set (same checks as a set over the bus). 0 ok; -1 with
/// the refused one named in msg (nothing after it applied).
int session_apply_params(md_params_t *p, const session_opts_t *o, char *msg, size_t msglen);

/// When the session is over (per electrode, from the controller's telemetry).
typedef struct {
    uint32_t cycles;       ///< stop when every electrode has this many TLM_STATUS (0: unused)
    uint64_t duration_us;  ///< stop when simulated time passed it and every interval that
                           ///< started before it has its TLM_STATUS (0: unused)
} session_goal_t;

/// Intervals one electrode's saved recording holds at most (tools/recording
/// reads as many: REC_MAX_INTERVALS).
#define SESSION_REC_MAX_INTERVALS 4096u
#define SESSION_REC_PATH_MAX 4096u

/// One recorded interval of the session's recording.
typedef struct {
    uint64_t start_sample;  ///< first sample in the binary
    uint32_t num_samples;   ///< samples that arrived (REC_DATA)
    uint32_t requested;     ///< REC_REQ NumSamples
    uint16_t interval_id;   ///< REC_REQ IntervalId
    int32_t cycle;          ///< TLM_STATUS Cycle after it (-1: none)
    double start_s;         ///< simulated time of its first sample (NaN: no SIM_CLOCK)
    double depth_um;        ///< TLM_STATUS Depth_um after it (NaN: none, or no Hall depth)
    int32_t hall_code;      ///< last HALL_READING RawCode up to its REC_END (-1: none)
    bool gap;               ///< a REC_DATA Seq was skipped or repeated
    bool ended;             ///< its REC_END was seen
    bool complete;          ///< REC_END complete, every requested sample, in sequence
} session_rec_interval_t;

/// One electrode's recording in progress.
typedef struct {
    FILE *bin;             ///< the binary, written as samples pass
    uint64_t written;      ///< samples in the binary
    uint32_t fs_hz;        ///< FE_INFO SampleRate_hz (0: not seen)
    double gain_uv;        ///< FE_INFO Gain_uV_per_lsb
    int32_t open;          ///< interval between REC_REQ and REC_END (-1: none)
    int32_t await_status;  ///< interval whose TLM_STATUS is due (-1: none)
    int32_t last_hall;     ///< last HALL_READING RawCode (-1: none)
    uint16_t next_seq;     ///< REC_DATA Seq expected next
    uint32_t n;            ///< intervals in iv
    uint64_t dropped;      ///< intervals past SESSION_REC_MAX_INTERVALS, not saved
    session_rec_interval_t iv[SESSION_REC_MAX_INTERVALS];
} session_rec_electrode_t;

/// The session's recording (session_rec.c; docs/session.md "The recording"):
/// DIR/recording.bin + recording.json (one electrode), else
/// DIR/recording-e<k>.bin + .json per electrode. About 1.3 MB: static storage.
typedef struct {
    bool active;
    char dir[SESSION_REC_PATH_MAX];
    char scenario[64];
    uint64_t seed;
    uint32_t electrodes;
    int write_error;  ///< errno of the first failed write (0: none)
    session_rec_electrode_t el[SESSION_MAX_ELECTRODES];
} session_rec_t;

/// Opens one binary per electrode in dir. 0 ok; -1 (message in msg, nothing left open).
int session_rec_open(session_rec_t *r, const char *dir, uint32_t electrodes, const char *scenario, uint64_t seed,
                     char *msg, size_t msglen);
/// Follows one frame (FE_INFO, REC_REQ, REC_DATA, HALL_READING, REC_END,
/// TLM_STATUS); `clock_us` is the last SIM_CLOCK if `clock_seen`.
void session_rec_frame(session_rec_t *r, const md_frame_t *f, uint64_t clock_us, bool clock_seen);
/// Drops intervals that never ended, cuts each binary to its last interval,
/// writes the sidecars and says what was written on `report`. 0 ok, -1 a
/// file could not be written (named on `report`).
int session_rec_close(session_rec_t *r, FILE *report);
/// Closes the binaries without a sidecar (a session that failed to start).
void session_rec_abandon(session_rec_t *r);

/// The recorder: log file plus what the telemetry says so far.
typedef struct {
    FILE *log;       ///< candump -L lines (owned by the caller)
    char iface[16];  ///< interface column of the log
    bool quiet;
    bool log_samples;     ///< REC_DATA frames go to the log too (--candump-samples)
    session_rec_t *rec;   ///< the session's recording (NULL: none)
    bool stamp_sim;       ///< time stamps = simulated time (last SIM_CLOCK), not the caller's
    uint32_t electrodes;  ///< electrodes of the scenario
    session_goal_t goal;
    uint64_t frames;
    uint64_t sim_clock_us;  ///< last SIM_CLOCK
    bool clock_seen;
    uint64_t activity;  ///< frames other than heartbeats (progress = this changes)
    uint32_t status_count[SESSION_MAX_ELECTRODES];
    int32_t status_last_cycle[SESSION_MAX_ELECTRODES];  ///< -1: none yet
    int32_t need_cycle[SESSION_MAX_ELECTRODES];         ///< duration goal: last cycle started before it
    bool moved_on;          ///< a REC_REQ, ACT_CMD or TLM_CYCLE followed the latest TLM_STATUS: the
                            ///< controller is past that cycle, whose telemetry (sent right after its
                            ///< TLM_STATUS) is therefore all in
    bool fw_booted;         ///< the controller's boot-up heartbeat was seen
    uint32_t fe_info_mask;  ///< electrodes announced by the front-end (FE_INFO)
    uint64_t hb_seen[6];    ///< heartbeats per node id 1..5
} session_track_t;

/// Initialises the recorder (log may be NULL: nothing written).
void session_track_init(session_track_t *t, FILE *log, const char *iface, uint32_t electrodes, session_goal_t goal,
                        bool quiet);

/// Logs one frame with its time stamp and follows the telemetry; prints a
/// progress line per TLM_STATUS unless quiet.
void session_track_frame(session_track_t *t, const md_frame_t *f, uint64_t stamp_us);

/// True when the goal is reached for every electrode.
bool session_track_done(const session_track_t *t);

/// True when, in addition, the telemetry of the cycle that reached the goal is
/// complete (moved_on): what a socket-bus session waits for before it stops
/// the processes, since the controller sends that telemetry after the
/// TLM_STATUS that completes the goal.
bool session_track_done_complete(const session_track_t *t);

/// One-line summary (cycles per electrode, simulated time) to `out`.
void session_track_summary(const session_track_t *t, FILE *out);

/// Why a runner ended.
typedef enum {
    SESSION_END_GOAL = 0,  ///< the goal was reached
    SESSION_END_IDLE,      ///< nothing moved for idle_s (controller waiting for nothing)
    SESSION_END_SIGNAL,    ///< SIGINT/SIGTERM
    SESSION_END_ERROR      ///< a process died, a bus failed
} session_end_t;

/// Human-readable name of an end reason.
const char *session_end_name(session_end_t e);

/// Runs the session in this process (inproc bus, virtual clock). Writes
/// DIR/candump.log and DIR/truth.jsonl. Returns how it ended.
session_end_t session_run_inproc(const session_opts_t *o, const char *resolved_bus, session_track_t *t, FILE *truth);

/// Runs microdrive-fw and microdrive-sim as processes on a socket bus with a
/// recorder endpoint here. `bus_spec` is the spec given (auto resolved here).
/// `bus_used` receives the resolved spec (vcan0, udp:PORT).
session_end_t session_run_procs(const session_opts_t *o, session_track_t *t, char *bus_used, size_t bus_used_len);

/// Set by the signal handler: the runners end soon after.
extern volatile int session_stop_signal;

#endif
