/// @file bench_core.h
/// One electrode cycle split into separately runnable stages (the stages of
/// pipeline/interval_chain.h, the controller's unit, plus control), for the host
/// benchmark (tools/bench/md_bench.c: wall time, callgrind instruction counts)
/// and the Cortex-M7 benchmark (tools/bench/bench_m7.c: QEMU -icount).
///
/// The interval is a 10 s synthetic trace (signal/spike_synth.h) at
/// BENCH_FS_HZ with three neurons of different amplitude (~300 spikes).
/// bench_setup() runs BENCH_WARMUP whole cycles on earlier intervals so the
/// tracker has hypotheses and the SNR curve has history, keeps a copy of the
/// tracker, curve table and SFSM, and prepares the measured interval. Each
/// bench_run_stage() then restores what the stage changes and runs it on the
/// same data, so every run of a stage does identical work (repeatable counts).
///
/// Pure C, no I/O, static storage only (portable to the target); not
/// re-entrant. Memory: see bench_static_bytes().
#ifndef BENCH_CORE_H
#define BENCH_CORE_H

#include <stddef.h>
#include <stdint.h>

#include "md_status.h"

#define BENCH_FS_HZ 30000u  ///< sample rate of the synthetic trace
#define BENCH_SECONDS 10u   ///< interval length
#define BENCH_SAMPLES (BENCH_FS_HZ * BENCH_SECONDS)
#define BENCH_CHUNK 30u  ///< samples per push (one CAN FD frame of samples)
#define BENCH_WARMUP 4u  ///< whole cycles before the measured interval
#define BENCH_D 2u       ///< PCA feature dimension (as the controller)

/// Stages, in cycle order. BENCH_ST_CLUSTER is clustering alone (G = 1..4,
/// Laplace, no prior targets): it is part of MHTC's step, so the cycle total
/// leaves it out.
typedef enum {
    BENCH_ST_DETECT = 0,  ///< ic_begin + ic_push (30-sample chunks) + ic_end (streaming detection, extraction)
    BENCH_ST_PCA,      ///< ic_features: pca_fit_i16, projections of spikes and noise, Ξ, noise RMS, robust amplitude
    BENCH_ST_CLUSTER,  ///< cluster_fit_models, G = 1..4, Laplace (not in the cycle sum)
    BENCH_ST_MHTC,     ///< ic_track: one mhtc_update on the int16 windows, L = 8, G_max = 4, Laplace
    BENCH_ST_QUALITY,  ///< ic_score: SNR of every track + isolation distance of the dominant one
    BENCH_ST_CONTROL,  ///< sc_table_observe + sc_curve_suggest + sfsm_decide
    BENCH_ST_COUNT
} bench_stage_t;

/// Short stage name ("detect", "pca", ...); "?" if out of range.
const char *bench_stage_name(bench_stage_t s);

/// 1 if the stage is part of one electrode's cycle (all but BENCH_ST_CLUSTER).
int bench_stage_in_cycle(bench_stage_t s);

/// Synthesises the intervals, runs the warm-up cycles and prepares the
/// measured interval. MD_OK, or the first failing stage's status.
md_status_t bench_setup(void);

/// Runs stage s on the measured interval from the saved state. MD_OK or the
/// stage's status (MD_E_ARG for s out of range or before bench_setup();
/// MD_E_STATE for pca, mhtc or quality when a detect ran after the stage
/// they need: the drivers run the stages in cycle order).
md_status_t bench_run_stage(bench_stage_t s);

/// Facts of the measured interval (valid after bench_setup()).
typedef struct {
    uint32_t true_spikes;     ///< spikes inserted by the synthesiser
    uint32_t detected;        ///< windows extracted
    uint32_t noise;           ///< noise snippets
    uint32_t d_w;             ///< window length (samples)
    uint32_t hyp;             ///< MHTC hypotheses after the measured step
    uint32_t tracks;          ///< tracks of the leading hypothesis
    uint32_t models;          ///< model hypotheses MHTC clustered in the measured step
    uint32_t reused;          ///< of those, how many reused a similar parent's EM fit (no EM of their own)
    uint32_t shared;          ///< of those, how many were copied from a parent with the same track records
    uint32_t warm;            ///< EM fits started from another parent's fit (mhtc_config_t.warm_start)
    uint32_t cluster_best_g;  ///< best G of clustering alone
} bench_info_t;

/// Copies the facts of the measured interval into *info.
void bench_info(bench_info_t *info);

/// The measured interval's spike features (n × BENCH_D, row-major, µV) for
/// comparisons with other clusterers; *n receives n.
const double *bench_features(size_t *n);

/// Bytes of static storage the benchmark uses (trace, workspaces, copies).
size_t bench_static_bytes(void);

/* ------------------------------------------------------------------ */
/* Replay: the cycle over recorded intervals                           */
/* ------------------------------------------------------------------ */

/// Replay mode: instead of the synthetic interval, the intervals of a
/// recording (e.g. a session's recording.bin, docs/session.md) are run in
/// order through the controller's cycle, the tracker, SNR curves, SFSM and
/// approach guard carrying their state from one interval to the next as in
/// the controller, so that the work of each interval can be measured and put
/// next to the cycle cost the controller reported for it (docs/pil.md). The
/// tracker has the controller's default configuration (mhtc_config_default:
/// what md_cycle.c makes of the default parameters), the tracker's travel is
/// the distance between the depths of this and the last tracked interval (as
/// md_cycle.c measures it); SFSM, SNR curves and guard run with their
/// library defaults and a 0..5000 µm window (they decide, but their decisions
/// do not feed back: the depths are the recording's). The stages split the
/// cycle where the controller's work counter does: BENCH_RP_PUSH is what
/// TLM_STATUS CycleCost minus ProcessCost measures (the samples streamed in
/// 30-sample chunks, one per REC_DATA frame), the rest is ProcessCost.
/// Shares the static storage of the synthetic mode: bench_setup() and
/// bench_replay_setup() each start over.
typedef enum {
    BENCH_RP_PUSH = 0,  ///< ic_push in 30-sample chunks (ic_begin runs unmeasured, as md_cycle.c's start_recording)
    BENCH_RP_END,       ///< ic_end: the end of detection, extraction of windows and noise snippets
    BENCH_RP_PCA,       ///< ic_features
    BENCH_RP_MHTC,      ///< ic_track with the travel since the last tracked interval
    BENCH_RP_QUALITY,   ///< ic_score
    BENCH_RP_CONTROL,   ///< as md_cycle.c decide() + guard(): SNR curve, SFSM, approach guard
    BENCH_RP_COUNT
} bench_replay_stage_t;

/// Short replay stage name ("push", "end", ...); "?" if out of range.
const char *bench_replay_stage_name(bench_replay_stage_t s);

/// Starts a replay of a channel sampled at fs_hz with gain_uv µV per count:
/// a fresh tracker, SFSM, SNR-curve table and guard. MD_E_ARG if the
/// interval chain does not take fs_hz (7500..32768 Hz) or gain_uv <= 0.
md_status_t bench_replay_setup(uint32_t fs_hz, double gain_uv);

/// Where the driver puts the next interval's samples (int16 counts); *cap
/// receives the room (BENCH_SAMPLES).
int16_t *bench_replay_samples(size_t *cap);

/// The next interval: n samples (1..cap) now in the buffer, recorded at
/// depth_um (NaN: unknown, no travel). Starts the chain (ic_begin). MD_E_ARG
/// before bench_replay_setup() or on a bad n; the chain's error otherwise.
md_status_t bench_replay_interval(size_t n, double depth_um);

/// Runs stage s of the current interval; stages run once each, in order.
/// MD_E_STATE out of order or after a stage of this interval failed (the
/// controller then skips the cycle: the tracker is unchanged); the stage's
/// own status otherwise.
md_status_t bench_replay_run(bench_replay_stage_t s);

/// What the interval said, in TLM_STATUS's terms, to check that the replay
/// computed what the controller did (valid after BENCH_RP_QUALITY).
typedef struct {
    uint32_t n_spikes;  ///< windows given to the tracker (TLM_STATUS NumSpikes)
    uint32_t dominant;  ///< dominant track id, 0 if none (DominantTrack)
    uint32_t n_tracks;  ///< tracks of the leading hypothesis (NumTracks)
    uint32_t n_hyp;     ///< hypotheses (NumHypotheses)
    uint32_t models;    ///< model hypotheses clustered in the step
    float snr;          ///< SNR of the dominant track as TLM_STATUS carries it (Snr, float32)
} bench_replay_info_t;

/// Copies the current interval's facts into *info.
void bench_replay_info(bench_replay_info_t *info);

#endif
