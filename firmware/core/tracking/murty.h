/// @file murty.h
/// Murty's ranked assignment: the L best solutions of a rectangular linear
/// assignment problem, cheapest first (Murty 1968; thesis §4.3.3 uses it on
/// A* = -log A, eq. 4.25, to generate the L best data-association hypotheses
/// of each model hypothesis without enumerating them).
///
/// Memory: a caller-owned workspace of MURTY_MAX_L nodes. Only the best
/// (L - found) open subproblems are ever kept: a child never costs less than
/// its parent, so anything ranked lower cannot enter the top L
/// (the bounded-queue optimisation of Miller, Stone & Cox 1997).
/// Time: at most L · rows LAP solves of O(rows^2 · cols) each.
#ifndef MURTY_H
#define MURTY_H

#include <stddef.h>
#include <stdint.h>

#include "tracking/lap.h"

#define MURTY_MAX_L MD_L_MAX

typedef struct {
    lap_problem_t problem;
    lap_solution_t solution;
    uint32_t order;  ///< insertion number: equal costs pop first-in first-out, so results are deterministic
} murty_node_t;

typedef struct {
    murty_node_t open[MURTY_MAX_L];
    size_t open_count;
    uint32_t inserted;
    uint32_t solves;  ///< LAP solves performed (for benchmarks)
} murty_workspace_t;

/// Writes the best min(L, feasible) assignments of the rows×cols cost matrix
/// (costs >= LAP_FORBIDDEN forbidden) into out[0..*n_out), in order of
/// non-decreasing cost. *n_out = 0 (and MD_OK) when no assignment is feasible.
/// MD_E_ARG on bad sizes or L > MURTY_MAX_L; MD_E_NUMERIC on NaN costs.
md_status_t murty_best(const double *cost, size_t rows, size_t cols, size_t L, murty_workspace_t *ws,
                       lap_solution_t *out, size_t *n_out);

#endif
