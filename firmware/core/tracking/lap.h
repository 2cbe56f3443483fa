/// @file lap.h
/// Rectangular linear assignment by shortest augmenting paths
/// (Jonker–Volgenant style, in the form of Crouse 2016).
///
/// Assigns every one of `rows` rows to a distinct column out of `cols`
/// (rows <= cols) at minimum total cost. Costs at or above LAP_FORBIDDEN mark
/// pairs that may not be assigned (a zero entry of the thesis' association
/// matrix A, eq. 4.25, whose -log is infinite). Rows may be pinned to a
/// column, which is how Murty's partitioning restricts a child problem.
///
/// Why no dual warm start (Miller–Stone–Cox): it is exact for square problems
/// only, and ours are at most LAP_MAX_ROWS × LAP_MAX_COLS (4 × 16), where a full
/// solve is a few hundred operations — padding to square would cost more.
///
/// Memory: caller-owned structs and a small stack frame; no allocation.
/// Time: O(rows^2 · cols).
#ifndef LAP_H
#define LAP_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "md_status.h"
#include "md_config.h"

#define LAP_MAX_ROWS MD_G_MAX                          ///< clusters of one model
#define LAP_MAX_COLS (MD_MAX_TARGETS + 2u * MD_G_MAX)  ///< targets + new + false columns (eq. 4.25)
#define LAP_FORBIDDEN 1e300                            ///< cost at/above which a pair is forbidden
#define LAP_UNASSIGNED (-1)

_Static_assert(LAP_MAX_ROWS <= LAP_MAX_COLS, "every row needs a column");
_Static_assert(LAP_MAX_COLS < 127u, "column indices are stored in int8_t");

/// A problem: a row-major rows×cols cost matrix (not owned) and the
/// restrictions Murty's partitioning adds.
typedef struct {
    const double *cost;  ///< rows*cols entries, row-major
    size_t rows, cols;
    uint32_t forbidden[LAP_MAX_ROWS];  ///< bit c set: pair (row, c) excluded
    int8_t fixed_col[LAP_MAX_ROWS];    ///< column a row is pinned to, or LAP_UNASSIGNED
} lap_problem_t;

/// An assignment: every row's column and the total cost.
typedef struct {
    int8_t col_of_row[LAP_MAX_ROWS];
    double cost;
} lap_solution_t;

/// True if pair (r, c) may be used in problem p.
bool lap_pair_allowed(const lap_problem_t *p, size_t r, size_t c);

/// Initialises p for a fresh problem (no restrictions). MD_E_ARG on bad sizes.
md_status_t lap_problem_init(lap_problem_t *p, const double *cost, size_t rows, size_t cols);

/// Solves p: pinned rows keep their columns, the others are assigned at
/// minimum cost. MD_E_DEGENERATE if no assignment avoids the forbidden pairs
/// (or two rows are pinned to one column); MD_E_NUMERIC on a NaN/-inf cost.
md_status_t lap_solve(const lap_problem_t *p, lap_solution_t *s);

#endif
