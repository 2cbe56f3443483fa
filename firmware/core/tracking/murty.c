#include "tracking/murty.h"

/* Index of the open node to pop next: lowest cost, then earliest inserted. */
static size_t best_open(const murty_workspace_t *ws)
{
    size_t best = 0u;
    for (size_t i = 1u; i < ws->open_count; ++i) {
        const murty_node_t *a = &ws->open[i];
        const murty_node_t *b = &ws->open[best];
        if (a->solution.cost < b->solution.cost || (!(a->solution.cost > b->solution.cost) && a->order < b->order)) {
            best = i;
        }
    }
    return best;
}

static size_t worst_open(const murty_workspace_t *ws)
{
    size_t worst = 0u;
    for (size_t i = 1u; i < ws->open_count; ++i) {
        const murty_node_t *a = &ws->open[i];
        const murty_node_t *b = &ws->open[worst];
        if (a->solution.cost > b->solution.cost || (!(a->solution.cost < b->solution.cost) && a->order > b->order)) {
            worst = i;
        }
    }
    return worst;
}

/* Keeps at most `room` open nodes: a newcomer replaces the worst when full. */
static void offer(murty_workspace_t *ws, const murty_node_t *node, size_t room)
{
    if (room == 0u) {
        return;
    }
    murty_node_t copy = *node;
    copy.order = ws->inserted++;
    if (ws->open_count < room) {
        ws->open[ws->open_count++] = copy;
        return;
    }
    const size_t w = worst_open(ws);
    if (copy.solution.cost < ws->open[w].solution.cost) {
        ws->open[w] = copy;
    }
}

/* Murty's partition of a popped node: child k keeps the first k-1 free rows
 * of the parent's solution and forbids the k-th row's column. */
static md_status_t partition(murty_workspace_t *ws, const murty_node_t *parent, size_t room)
{
    murty_node_t child = *parent;
    for (size_t r = 0u; r < parent->problem.rows; ++r) {
        if (parent->problem.fixed_col[r] != LAP_UNASSIGNED) {
            continue;
        }
        const int8_t col = parent->solution.col_of_row[r];
        child.problem.forbidden[r] |= 1u << (unsigned)col;
        ws->solves++;
        const md_status_t st = lap_solve(&child.problem, &child.solution);
        if (st == MD_OK) {
            offer(ws, &child, room);
        } else if (st != MD_E_DEGENERATE) {
            return st;
        }
        /* The next child pins this row to the parent's choice. */
        child.problem.forbidden[r] = parent->problem.forbidden[r];
        child.problem.fixed_col[r] = col;
    }
    return MD_OK;
}

md_status_t murty_best(const double *cost, size_t rows, size_t cols, size_t L, murty_workspace_t *ws,
                       lap_solution_t *out, size_t *n_out)
{
    if (ws == NULL || out == NULL || n_out == NULL || L == 0u || L > MURTY_MAX_L) {
        return MD_E_ARG;
    }
    *n_out = 0u;
    ws->open_count = 0u;
    ws->inserted = 0u;
    ws->solves = 1u;
    murty_node_t root;
    md_status_t st = lap_problem_init(&root.problem, cost, rows, cols);
    if (st < 0) {
        return st;
    }
    st = lap_solve(&root.problem, &root.solution);
    if (st == MD_E_DEGENERATE) {
        return MD_OK;
    }
    if (st < 0) {
        return st;
    }
    offer(ws, &root, L);
    for (size_t found = 0u; found < L && ws->open_count > 0u; ++found) {
        const size_t b = best_open(ws);
        const murty_node_t node = ws->open[b];
        ws->open[b] = ws->open[--ws->open_count];
        out[(*n_out)++] = node.solution;
        st = partition(ws, &node, L - *n_out);
        if (st < 0) {
            return st;
        }
    }
    return MD_OK;
}
