/// @file bench_core.h
/// One electrode cycle split into separately runnable stages (the stages of
/// pipeline/interval_chain.h, the controller's unit, plus control), for the host
/// benchmark (tools/bench/md_bench.c: wall time, callgrind instruction counts)
/// and the Cortex-M7 benchmark (tests/target/bench_m7.c: QEMU -icount).
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

#include "common/md_status.h"

#define BENCH_FS_HZ 30000u      ///< sample rate of the synthetic trace
#define BENCH_SECONDS 10u       ///< interval length
#define BENCH_SAMPLES (BENCH_FS_HZ * BENCH_SECONDS)
#define BENCH_CHUNK 30u         ///< samples per push (one CAN FD frame of samples)
#define BENCH_WARMUP 4u         ///< whole cycles before the measured interval
#define BENCH_D 2u              ///< PCA feature dimension (as the controller)

/// Stages, in cycle order. BENCH_ST_CLUSTER is clustering alone (G = 1..4,
/// Laplace, no prior targets): it is part of MHTC's step, so the cycle total
/// leaves it out.
typedef enum {
    BENCH_ST_DETECT = 0,  ///< ic_begin + ic_push (30-sample chunks) + ic_end (streaming detection, extraction)
    BENCH_ST_PCA,         ///< ic_features: pca_fit_i16, projections of spikes and noise, Ξ, noise RMS, robust amplitude
    BENCH_ST_CLUSTER,     ///< cluster_fit_models, G = 1..4, Laplace (not in the cycle sum)
    BENCH_ST_MHTC,        ///< ic_track: one mhtc_step on the int16 windows, L = 8, G_max = 4, Laplace
    BENCH_ST_QUALITY,     ///< ic_score: SNR of every track + isolation distance of the dominant one
    BENCH_ST_CONTROL,     ///< sc_table_observe + sc_curve_suggest + sfsm_step
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
    uint32_t true_spikes;  ///< spikes inserted by the synthesiser
    uint32_t detected;     ///< windows extracted
    uint32_t noise;        ///< noise snippets
    uint32_t d_w;          ///< window length (samples)
    uint32_t hyp;          ///< MHTC hypotheses after the measured step
    uint32_t tracks;       ///< tracks of the leading hypothesis
    uint32_t models;       ///< model hypotheses MHTC clustered in the measured step
    uint32_t reused;       ///< of those, how many reused a similar parent's EM fit (no EM of their own)
    uint32_t shared;       ///< of those, how many were copied from a parent with the same track records
    uint32_t warm;         ///< EM fits started from another parent's fit (mhtc_config_t.warm_start)
    uint32_t cluster_best_g; ///< best G of clustering alone
} bench_info_t;

/// Copies the facts of the measured interval into *info.
void bench_info(bench_info_t *info);

/// The measured interval's spike features (n × BENCH_D, row-major, µV) for
/// comparisons with other clusterers; *n receives n.
const double *bench_features(size_t *n);

/// Bytes of static storage the benchmark uses (trace, workspaces, copies).
size_t bench_static_bytes(void);

#endif
