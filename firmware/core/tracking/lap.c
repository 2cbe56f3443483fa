#include "tracking/lap.h"

#include <math.h>

static double cost_at(const lap_problem_t *p, size_t r, size_t c)
{
    return p->cost[r * p->cols + c];
}

bool lap_pair_allowed(const lap_problem_t *p, size_t r, size_t c)
{
    return (p->forbidden[r] & (1u << c)) == 0u && cost_at(p, r, c) < LAP_FORBIDDEN;
}

md_status_t lap_problem_init(lap_problem_t *p, const double *cost, size_t rows, size_t cols)
{
    if (p == NULL || cost == NULL || rows == 0u || rows > LAP_MAX_ROWS || cols < rows || cols > LAP_MAX_COLS) {
        return MD_E_ARG;
    }
    p->cost = cost;
    p->rows = rows;
    p->cols = cols;
    for (size_t r = 0u; r < LAP_MAX_ROWS; ++r) {
        p->forbidden[r] = 0u;
        p->fixed_col[r] = LAP_UNASSIGNED;
    }
    return MD_OK;
}

/* Working state of one solve: the partial assignment and its duals
 * (reduced costs c - u - v stay >= 0 on every usable arc of an assigned row). */
typedef struct {
    int8_t col_of_row[LAP_MAX_ROWS];
    int8_t row_of_col[LAP_MAX_COLS];
    double u[LAP_MAX_ROWS];
    double v[LAP_MAX_COLS];
    uint32_t blocked;  ///< columns of pinned rows: no path may pass through them
} lap_work_t;

typedef struct {
    double dist[LAP_MAX_COLS];  ///< shortest reduced path cost to each column
    int8_t pred[LAP_MAX_COLS];  ///< row preceding each column on its path
    uint32_t scanned_cols;
    uint8_t scanned_rows;
} lap_search_t;

/* One Dijkstra step from row i: relax its arcs, return the closest unscanned
 * column (preferring a free column on ties, which ends the search sooner). */
static int closest_column(const lap_problem_t *p, const lap_work_t *s, lap_search_t *w, size_t i, double base,
                          uint32_t blocked)
{
    int best = -1;
    double lowest = HUGE_VAL;
    for (size_t j = 0u; j < p->cols; ++j) {
        if (((w->scanned_cols | blocked) & (1u << j)) != 0u) {
            continue;
        }
        if (lap_pair_allowed(p, i, j)) {
            const double r = base + cost_at(p, i, j) - s->u[i] - s->v[j];
            if (r < w->dist[j]) {
                w->dist[j] = r;
                w->pred[j] = (int8_t)i;
            }
        }
        const bool better = w->dist[j] < lowest;
        const bool tie_free = !(w->dist[j] > lowest) && !(w->dist[j] < lowest) && s->row_of_col[j] < 0;
        if (w->dist[j] < HUGE_VAL && (better || tie_free)) {
            lowest = w->dist[j];
            best = (int)j;
        }
    }
    return best;
}

/* Dual update after a successful search keeps reduced costs >= 0 (Crouse 2016, Alg. 4). */
static void update_duals(const lap_problem_t *p, lap_work_t *s, const lap_search_t *w, size_t row, double min_val)
{
    s->u[row] += min_val;
    for (size_t i = 0u; i < p->rows; ++i) {
        if (i != row && (w->scanned_rows & (1u << i)) != 0u) {
            s->u[i] += min_val - w->dist[(size_t)s->col_of_row[i]];
        }
    }
    for (size_t j = 0u; j < p->cols; ++j) {
        if ((w->scanned_cols & (1u << j)) != 0u) {
            s->v[j] -= min_val - w->dist[j];
        }
    }
}

static void augment_path(lap_work_t *s, const lap_search_t *w, size_t row, int sink)
{
    int j = sink;
    for (size_t step = 0u; step < LAP_MAX_ROWS + 1u; ++step) {
        const int i = w->pred[j];
        s->row_of_col[j] = (int8_t)i;
        const int previous = s->col_of_row[i];
        s->col_of_row[i] = (int8_t)j;
        if ((size_t)i == row) {
            return;
        }
        j = previous;
    }
}

/* One shortest augmenting path from a free row (Crouse 2016, Alg. 4). */
static md_status_t augment_row(const lap_problem_t *p, lap_work_t *s, size_t row)
{
    lap_search_t w = {.scanned_cols = 0u, .scanned_rows = 0u};
    for (size_t j = 0u; j < LAP_MAX_COLS; ++j) {
        w.dist[j] = HUGE_VAL;
        w.pred[j] = -1;
    }
    const uint32_t blocked = s->blocked;
    double min_val = 0.0;
    size_t i = row;
    int sink = -1;
    for (size_t hops = 0u; hops <= p->rows && sink < 0; ++hops) {
        w.scanned_rows |= (uint8_t)(1u << i);
        const int j = closest_column(p, s, &w, i, min_val, blocked);
        if (j < 0) {
            return MD_E_DEGENERATE; /* every reachable column is forbidden */
        }
        min_val = w.dist[j];
        w.scanned_cols |= 1u << (unsigned)j;
        if (s->row_of_col[j] < 0) {
            sink = j;
        } else {
            i = (size_t)s->row_of_col[j];
        }
    }
    if (sink < 0) {
        return MD_E_NUMERIC;
    }
    update_duals(p, s, &w, row, min_val);
    augment_path(s, &w, row, sink);
    return MD_OK;
}

static md_status_t pin_fixed_rows(const lap_problem_t *p, lap_work_t *s)
{
    for (size_t r = 0u; r < p->rows; ++r) {
        const int c = p->fixed_col[r];
        if (c == LAP_UNASSIGNED) {
            continue;
        }
        if (c < 0 || (size_t)c >= p->cols || s->row_of_col[c] >= 0 || !lap_pair_allowed(p, r, (size_t)c)) {
            return MD_E_DEGENERATE;
        }
        s->col_of_row[r] = (int8_t)c;
        s->row_of_col[c] = (int8_t)r;
        s->blocked |= 1u << (unsigned)c;
    }
    return MD_OK;
}

static md_status_t check_costs(const lap_problem_t *p)
{
    for (size_t k = 0u; k < p->rows * p->cols; ++k) {
        /* NaN fails both comparisons; -inf would make every path "shortest". */
        if (!(p->cost[k] >= LAP_FORBIDDEN) && !(p->cost[k] > -LAP_FORBIDDEN && p->cost[k] < LAP_FORBIDDEN)) {
            return MD_E_NUMERIC;
        }
    }
    return MD_OK;
}

md_status_t lap_solve(const lap_problem_t *p, lap_solution_t *out)
{
    if (p == NULL || out == NULL || p->cost == NULL || p->rows == 0u || p->rows > LAP_MAX_ROWS || p->cols < p->rows ||
        p->cols > LAP_MAX_COLS) {
        return MD_E_ARG;
    }
    md_status_t st = check_costs(p);
    lap_work_t s = {.blocked = 0u};
    for (size_t r = 0u; r < LAP_MAX_ROWS; ++r) {
        s.col_of_row[r] = LAP_UNASSIGNED;
        s.u[r] = 0.0;
    }
    for (size_t c = 0u; c < LAP_MAX_COLS; ++c) {
        s.row_of_col[c] = LAP_UNASSIGNED;
        s.v[c] = 0.0;
    }
    if (st == MD_OK) {
        st = pin_fixed_rows(p, &s);
    }
    double total = 0.0;
    for (size_t r = 0u; r < p->rows && st == MD_OK; ++r) {
        if (s.col_of_row[r] == LAP_UNASSIGNED) {
            st = augment_row(p, &s, r);
        }
    }
    for (size_t r = 0u; r < p->rows && st == MD_OK; ++r) {
        out->col_of_row[r] = s.col_of_row[r];
        total += cost_at(p, r, (size_t)s.col_of_row[r]);
    }
    out->cost = total;
    return st;
}
