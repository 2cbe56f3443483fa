/// @file md_config.h
/// Every compile-time capacity of the firmware, in one place.
///
/// The firmware has no heap: each buffer is sized by a constant below and
/// checked by the static assertions at the end of this file. A board build may
/// override any value with -D on the compiler command line; the assertions then
/// tell at compile time whether the combination is still consistent.
#ifndef MD_CONFIG_H
#define MD_CONFIG_H

/* ---- the rig ------------------------------------------------------------ */
#ifndef MD_ELECTRODES
#define MD_ELECTRODES 3u  ///< electrodes driven by one controller (thesis drive: 3)
#endif

/* ---- signal chain (thesis §2.2.2) --------------------------------------- */
#ifndef MD_MAX_SPIKES
#define MD_MAX_SPIKES 512u  ///< detected spikes kept per recording interval
#endif
#ifndef MD_WAVE_LEN_MAX
#define MD_WAVE_LEN_MAX 48u  ///< samples per spike window (thesis: d_w = 23 at 20 kHz; 1.6 ms at 30 kHz = 48)
#endif
#ifndef MD_MAX_NOISE_SNIPPETS
#define MD_MAX_NOISE_SNIPPETS 256u  ///< spike-free noise windows kept per interval
#endif
#ifndef MD_FEAT_DIM_MAX
#define MD_FEAT_DIM_MAX 3u  ///< PCA feature dimension d (thesis: 2; at most 3)
#endif
#ifndef MD_WAVELET_SCALES_MAX
#define MD_WAVELET_SCALES_MAX 8u  ///< wavelet scales examined by the detector
#endif

/* ---- clustering (thesis ch. 3) ------------------------------------------ */
#ifndef MD_G_MAX
#define MD_G_MAX 4u  ///< most Gaussian clusters in one model (thesis Table 4.1)
#endif
#ifndef MD_EM_MAX_ITER
#define MD_EM_MAX_ITER 200u  ///< bound on EM iterations per fit
#endif
#ifndef MD_EM_TOL_REL
/// EM stops when |Δ log-posterior| ≤ MD_EM_TOL_REL · max(1, |log-posterior|).
/// 1e-7 of ~3000 nats is ~3e-4 nats per interval, 1000x stricter than
/// scikit-learn's default (1e-3 per point). 1e-6 was faster but lowered the
/// closed-loop single_neuron ID consistency (0.47 vs 0.56 over 18 seeds);
/// docs/benchmarks.md has the measured effect on iterations and quality.
#define MD_EM_TOL_REL 1e-7
#endif

/* ---- tracking (thesis ch. 4) -------------------------------------------- */
#ifndef MD_L_MAX
#define MD_L_MAX 8u  ///< global hypotheses kept (thesis Table 4.1: L = 8)
#endif
#ifndef MD_MAX_TARGETS
#define MD_MAX_TARGETS 8u  ///< targets (tracks) alive in one hypothesis
#endif
#ifndef MD_TRACK_POOL
#define MD_TRACK_POOL \
    20u  ///< shared track records per electrode, referenced by hypotheses (exhaustion: least probable child dropped, counted)
#endif

/* ---- protocol ------------------------------------------------------------ */
#ifndef MD_PARAM_COUNT_MAX
#define MD_PARAM_COUNT_MAX 64u  ///< parameters reachable by get/set
#endif

/* ---- consistency --------------------------------------------------------- */
_Static_assert(MD_ELECTRODES >= 1u && MD_ELECTRODES <= 8u, "1..8 electrodes (CAN ids reserve 3 bits)");
_Static_assert(MD_MAX_SPIKES >= 16u, "an interval needs room for at least a few clusters' worth of spikes");
_Static_assert(MD_WAVE_LEN_MAX >= 16u && MD_WAVE_LEN_MAX <= 64u, "window length 16..64 samples");
_Static_assert(MD_FEAT_DIM_MAX >= 1u && MD_FEAT_DIM_MAX <= 3u, "thesis App. B covers d <= 3");
_Static_assert(MD_FEAT_DIM_MAX <= MD_WAVE_LEN_MAX, "features come from waveforms");
_Static_assert(MD_G_MAX >= 1u && MD_G_MAX <= 6u, "G_max 1..6");
_Static_assert(MD_L_MAX >= 1u && MD_L_MAX <= 16u, "L 1..16");
_Static_assert(MD_MAX_TARGETS >= MD_G_MAX, "every cluster of a model may start a track");
_Static_assert(MD_TRACK_POOL >= MD_MAX_TARGETS, "one hypothesis must fit in the pool");
_Static_assert(MD_MAX_NOISE_SNIPPETS >= 8u, "noise statistics need a few snippets");

#endif
