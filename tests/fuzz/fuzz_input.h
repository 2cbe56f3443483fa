/// @file fuzz_input.h
/// Shared by every fuzz harness: a bounded reader over libFuzzer's input bytes
/// and the invariant check. Reading past the end yields zeros (never an
/// out-of-bounds access), so a harness decodes as many fields as it wants and
/// libFuzzer learns that longer inputs reach further.
///
/// Values are decoded in "modes" so that one input byte can choose between a
/// realistic value (small integers, scaled) and a hostile one (raw IEEE bits:
/// NaN, inf, denormals, 1e308), which is where numeric code breaks.
#ifndef FUZZ_INPUT_H
#define FUZZ_INPUT_H

#include <float.h>
#include <math.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

/// libFuzzer's entry point (each harness defines it).
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/// An invariant the code under test promises: a violation aborts the run so
/// that libFuzzer saves the input as a crash (and a plain run of the binary on
/// that file reproduces it).
#define FUZZ_CHECK(cond)                                                                         \
    do {                                                                                         \
        if (!(cond)) {                                                                           \
            (void)fprintf(stderr, "%s:%d: invariant violated: %s\n", __FILE__, __LINE__, #cond); \
            __builtin_trap();                                                                    \
        }                                                                                        \
    } while (0)

typedef struct {
    const uint8_t *p;
    size_t left;
} fz_t;

static inline void fz_init(fz_t *f, const uint8_t *data, size_t size)
{
    f->p = data;
    f->left = size;
}

static inline size_t fz_left(const fz_t *f)
{
    return f->left;
}

static inline uint8_t fz_u8(fz_t *f)
{
    if (f->left == 0u) {
        return 0u;
    }
    const uint8_t v = *f->p;
    f->p++;
    f->left--;
    return v;
}

static inline uint16_t fz_u16(fz_t *f)
{
    const uint16_t lo = fz_u8(f);
    return (uint16_t)(lo | (uint16_t)((uint16_t)fz_u8(f) << 8u));
}

static inline uint32_t fz_u32(fz_t *f)
{
    const uint32_t lo = fz_u16(f);
    return lo | ((uint32_t)fz_u16(f) << 16u);
}

static inline uint64_t fz_u64(fz_t *f)
{
    const uint64_t lo = fz_u32(f);
    return lo | ((uint64_t)fz_u32(f) << 32u);
}

/// Copies up to n bytes (zeros past the end).
static inline void fz_bytes(fz_t *f, uint8_t *out, size_t n)
{
    for (size_t i = 0u; i < n; ++i) {
        out[i] = fz_u8(f);
    }
}

/// Any double, bit for bit (NaN payloads, infinities, denormals included).
static inline double fz_raw_double(fz_t *f)
{
    const uint64_t bits = fz_u64(f);
    double v;
    memcpy(&v, &bits, sizeof v);
    return v;
}

/// One of the values numeric code most often gets wrong.
static inline double fz_special(uint8_t k)
{
    static const double SPECIAL[16] = {
        0.0,     -0.0,     1.0,   -1.0,   DBL_MIN, -DBL_MIN,         DBL_TRUE_MIN,      -DBL_TRUE_MIN,
        DBL_MAX, -DBL_MAX, 1e154, -1e154, 1e-154,  (double)INFINITY, -(double)INFINITY, (double)NAN};
    return SPECIAL[k & 15u];
}

/// A double chosen by a mode byte: mostly small scaled integers (realistic
/// spike features / waveforms), sometimes specials or raw bits.
///   mode 0..9  : int8 / 8        (dense, small)
///   mode 10..11: int16 / 64      (wider)
///   mode 12    : int16 * 1e6     (large but finite)
///   mode 13    : int16 * 1e-300  (tiny, denormal range)
///   mode 14    : special value
///   mode 15    : raw 8 bytes
static inline double fz_double_mode(fz_t *f, uint8_t mode)
{
    switch (mode & 15u) {
    case 10u:
    case 11u: return (double)(int16_t)fz_u16(f) / 64.0;
    case 12u: return (double)(int16_t)fz_u16(f) * 1e6;
    case 13u: return (double)(int16_t)fz_u16(f) * 1e-300;
    case 14u: return fz_special(fz_u8(f));
    case 15u: return fz_raw_double(f);
    default: return (double)(int8_t)fz_u8(f) / 8.0;
    }
}

/// A double whose mode is read first.
static inline double fz_double(fz_t *f)
{
    return fz_double_mode(f, fz_u8(f));
}

/// True if all n values are finite.
static inline bool fz_all_finite(const double *v, size_t n)
{
    for (size_t i = 0u; i < n; ++i) {
        if (!isfinite(v[i])) {
            return false;
        }
    }
    return true;
}

#endif
