/// @file md_exp.h
/// exp(x) for the mixture's hot loops (E-step responsibilities, evidence
/// terms): the same value as libm's exp to within 1 ulp, at about half of
/// newlib's instruction count on the Cortex-M7 (docs/benchmarks.md), inline.
///
/// Method (Tang 1989, the table-driven scheme of most libms): x = (k·64 + j)
/// ln2/64 + r with |r| ≤ ln2/128 by round-to-nearest of x·64/ln2 (Cody-Waite
/// split of ln2/64, so r is exact); exp(x) = 2^k · 2^(j/64) · e^r with
/// 2^(j/64) from a 64-entry table and e^r - 1 by its Taylor polynomial of
/// degree 5 (truncation r^6/720 < 0.2 ulp).
///
/// Range: results below DBL_MIN (x < MD_EXP_X_MIN ≈ -708.4) are returned as
/// 0 (absolute error < 2.3e-308: the callers add them to sums ≥ 1); x above
/// MD_EXP_X_MAX (709.77; exp stays finite up to 709.78) gives +inf; NaN gives NaN.
#ifndef MD_EXP_H
#define MD_EXP_H

#include <math.h>
#include <stdint.h>
#include <string.h>

#define MD_EXP_TABLE_BITS 6u
#define MD_EXP_TABLE_SIZE 64u
#define MD_EXP_X_MIN (-708.39)  ///< below: 0 (2^k would leave the normal range)
#define MD_EXP_X_MAX 709.77     ///< above: +inf (2^k would leave the normal range; the callers use x ≤ 0)

/// 2^(j/64), j = 0..63, correctly rounded.
extern const double md_exp_table[MD_EXP_TABLE_SIZE];

/// e^x within 1 ulp for MD_EXP_X_MIN ≤ x ≤ MD_EXP_X_MAX (see the file comment). O(1).
static inline double md_exp(double x)
{
    if (!(x >= MD_EXP_X_MIN)) {
        return (isnan(x) != 0) ? x : 0.0;
    }
    if (x > MD_EXP_X_MAX) {
        return HUGE_VAL;
    }
    const double shift = 0x1.8p52;                /* adding it rounds to an integer (ties to even) */
    const double inv_step = 0x1.71547652b82fep6;  /* 64 / ln 2 */
    const double step_hi = 0x1.62e42feep-7;       /* ln 2 / 64, 33 significant bits: k·step_hi is exact */
    const double step_lo = 0x1.a39ef35793c76p-39; /* ln 2 / 64 - step_hi */
    const double kd = (x * inv_step + shift) - shift;
    const double r = (x - kd * step_hi) - kd * step_lo;
    /* |kd| ≤ 65 408 here; offset by 2^20 so the split into k and j is unsigned */
    const int32_t k_signed = (int32_t)kd;
    const uint32_t ki = (uint32_t)k_signed + 0x100000u;
    const uint32_t j = ki & (MD_EXP_TABLE_SIZE - 1u);
    const uint32_t biased = (ki >> MD_EXP_TABLE_BITS) + 1023u - (0x100000u >> MD_EXP_TABLE_BITS);
    const uint64_t scale_bits = (uint64_t)biased << 52u; /* 2^k as an IEEE 754 double */
    double scale = 0.0;
    /* cppcheck-suppress misra-c2012-21.15 ; deliberate: a double's exponent field from its bits */
    (void)memcpy(&scale, &scale_bits, sizeof scale);
    const double p = r + (r * r) * (0.5 + r * (1.0 / 6.0 + r * (1.0 / 24.0 + r * (1.0 / 120.0))));
    const double t = md_exp_table[j];
    return (t + t * p) * scale;
}

#endif
