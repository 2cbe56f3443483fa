/// @file fuzz_murty.c
/// Fuzz target 5c: Murty's ranked assignment over the LAP solver
/// (firmware/core/tracking/murty.h, lap.h) on arbitrary cost matrices:
/// any rows, cols and L (valid or not), costs from small integers to
/// forbidden (>= LAP_FORBIDDEN), ±1e154, NaN and ±inf. Checks, against a
/// brute-force enumeration of every assignment whenever that is cheap:
///  - the status is exactly the expected one: MD_E_ARG for bad sizes or L,
///    MD_E_NUMERIC for a NaN or a cost <= -LAP_FORBIDDEN, MD_OK otherwise;
///  - n_out = min(L, number of feasible assignments);
///  - every solution assigns each row a distinct allowed column, its cost is
///    the sum of its entries, solutions are pairwise distinct and sorted;
///  - the k-th cost equals the brute-force k-th best cost.
#include <stdint.h>
#include <string.h>

#include "fuzz_input.h"
#include "tracking/murty.h"

#define FZ_BRUTE_MAX 6000u /* assignments enumerated at most per input */

typedef struct {
    double best[MURTY_MAX_L];  ///< cheapest costs found, ascending
    size_t kept, feasible;
} brute_t;

static double g_cost[(LAP_MAX_ROWS + 1u) * (LAP_MAX_COLS + 1u)]; /* sizes up to one past each limit */

static double entry(fz_t *in)
{
    const uint8_t e = fz_u8(in);
    if (e < 32u) {
        return LAP_FORBIDDEN;
    }
    if (e < 44u) {
        return fz_double(in); /* hostile: specials, raw bits, huge, tiny */
    }
    return (double)(int8_t)e / 4.0;
}

static void brute_keep(brute_t *b, double c, size_t L)
{
    b->feasible++;
    if (b->kept == L && !(c < b->best[L - 1u])) {
        return;
    }
    size_t k = (b->kept < L) ? b->kept++ : L - 1u; /* full: the worst kept one drops out */
    while (k > 0u && c < b->best[k - 1u]) {
        b->best[k] = b->best[k - 1u];
        k--;
    }
    b->best[k] = c;
}

/* Every injective row->column map of allowed pairs, by an odometer over columns. */
static void brute_force(size_t rows, size_t cols, size_t L, brute_t *b)
{
    size_t col[LAP_MAX_ROWS] = {0u};
    memset(b, 0, sizeof *b);
    for (;;) {
        bool ok = true;
        double sum = 0.0;
        for (size_t r = 0u; r < rows && ok; ++r) {
            const double c = g_cost[r * cols + col[r]];
            ok = c < LAP_FORBIDDEN;
            for (size_t q = 0u; q < r && ok; ++q) {
                ok = col[q] != col[r];
            }
            sum += c;
        }
        if (ok) {
            brute_keep(b, sum, L);
        }
        size_t r = 0u;
        while (r < rows && ++col[r] == cols) {
            col[r++] = 0u;
        }
        if (r == rows) {
            return;
        }
    }
}

static double assignment_cost(const lap_solution_t *s, size_t rows, size_t cols)
{
    double sum = 0.0;
    uint32_t used = 0u;
    for (size_t r = 0u; r < rows; ++r) {
        const int c = s->col_of_row[r];
        FUZZ_CHECK(c >= 0 && (size_t)c < cols);
        FUZZ_CHECK((used & (1u << (unsigned)c)) == 0u);
        used |= 1u << (unsigned)c;
        FUZZ_CHECK(g_cost[r * cols + (size_t)c] < LAP_FORBIDDEN);
        sum += g_cost[r * cols + (size_t)c];
    }
    return sum;
}

static bool same_assignment(const lap_solution_t *a, const lap_solution_t *b, size_t rows)
{
    return memcmp(a->col_of_row, b->col_of_row, rows * sizeof a->col_of_row[0]) == 0;
}

static void check_solutions(const lap_solution_t *out, size_t n_out, size_t rows, size_t cols, size_t L, double scale)
{
    FUZZ_CHECK(n_out <= L);
    for (size_t k = 0u; k < n_out; ++k) {
        const double c = assignment_cost(&out[k], rows, cols);
        FUZZ_CHECK(fabs(c - out[k].cost) <= 1e-9 * scale);
        if (k > 0u) {
            FUZZ_CHECK(out[k].cost >= out[k - 1u].cost - 1e-9 * scale);
        }
        for (size_t q = 0u; q < k; ++q) {
            FUZZ_CHECK(!same_assignment(&out[k], &out[q], rows));
        }
    }
    size_t perms = 1u;
    for (size_t r = 0u; r < rows; ++r) {
        perms *= cols - r;
    }
    if (perms > FZ_BRUTE_MAX) {
        return;
    }
    brute_t b;
    brute_force(rows, cols, L, &b);
    FUZZ_CHECK(n_out == ((b.feasible < L) ? b.feasible : L));
    for (size_t k = 0u; k < n_out; ++k) {
        FUZZ_CHECK(fabs(out[k].cost - b.best[k]) <= 1e-9 * scale);
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fz_t in;
    fz_init(&in, data, size);
    const size_t rows = fz_u8(&in) % (LAP_MAX_ROWS + 2u); /* 0 and MAX+1 invalid */
    const size_t cols = fz_u8(&in) % (LAP_MAX_COLS + 2u); /* 0 and MAX+1 invalid */
    const size_t L = fz_u8(&in) % (MURTY_MAX_L + 2u);     /* 0 and MAX+1 invalid */
    bool numeric_bad = false;
    double scale = 1.0; /* largest magnitude of an allowed cost, times rows */
    for (size_t k = 0u; k < rows * cols; ++k) {
        g_cost[k] = entry(&in);
        const double c = g_cost[k];
        if (!(c >= LAP_FORBIDDEN) && !(c > -LAP_FORBIDDEN && c < LAP_FORBIDDEN)) {
            numeric_bad = true;
        } else if (c < LAP_FORBIDDEN) {
            scale = fmax(scale, fabs(c) * (double)(rows + 1u));
        }
    }
    static murty_workspace_t ws;
    lap_solution_t out[MURTY_MAX_L + 1u];
    size_t n_out = 99u;
    const md_status_t st = murty_best(g_cost, rows, cols, L, &ws, out, &n_out);
    const bool bad_size = rows == 0u || rows > LAP_MAX_ROWS || cols < rows || cols > LAP_MAX_COLS || L == 0u ||
                          L > MURTY_MAX_L;
    if (bad_size) {
        FUZZ_CHECK(st == MD_E_ARG);
        return 0;
    }
    if (numeric_bad) {
        FUZZ_CHECK(st == MD_E_NUMERIC);
        return 0;
    }
    FUZZ_CHECK(st == MD_OK);
    check_solutions(out, n_out, rows, cols, L, scale);
    return 0;
}
