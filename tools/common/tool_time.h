/// @file tool_time.h
/// Timing helpers the host tools share (benchmarks, mhtc-replay): a
/// monotonic clock in milliseconds and the qsort comparator of the medians
/// they report. Header only; POSIX (clock_gettime).
#ifndef TOOL_TIME_H
#define TOOL_TIME_H

#include <time.h>

/// CLOCK_MONOTONIC in ms (only differences mean something).
static inline double tool_now_ms(void)
{
    struct timespec ts;
    (void)clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e3 + (double)ts.tv_nsec * 1e-6;
}

/// qsort comparator of doubles, ascending (no NaN expected: times).
static inline int tool_cmp_double(const void *a, const void *b)
{
    const double x = *(const double *)a;
    const double y = *(const double *)b;
    return (x < y) ? -1 : ((x > y) ? 1 : 0);
}

#endif
