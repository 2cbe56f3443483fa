/// @file em_hac.c
/// Ward's agglomerative clustering by nearest-neighbour chain (see em_hac.h).
#include "cluster/em_hac.h"

#include <math.h>
#include <string.h>

#include "numeric/linalg.h"

#define EM_HAC_NONE 0xFFFFu

/* Ward's merge cost between the clusters held in slots a and b. */
static double em_hac_cost(const em_hac_work_t *ws, size_t d, size_t a, size_t b)
{
    double r2 = 0.0;
    for (size_t j = 0u; j < d; ++j) {
        const double r = ws->centroid[a][j] - ws->centroid[b][j];
        r2 += r * r;
    }
    return ws->size[a] * ws->size[b] / (ws->size[a] + ws->size[b]) * r2;
}

/* Nearest active slot to a; a tie keeps `prefer` (the chain's previous
 * element), which is what stops the chain from cycling. */
static size_t em_hac_nearest(const em_hac_work_t *ws, size_t d, size_t a, size_t prefer, double *cost)
{
    size_t best = EM_HAC_NONE;
    double best_cost = INFINITY;
    if (prefer != EM_HAC_NONE) {
        best = prefer;
        best_cost = em_hac_cost(ws, d, a, prefer);
    }
    for (size_t c = 0u; c < ws->n; ++c) {
        if ((c == a) || !(ws->size[c] > 0.0)) {
            continue;
        }
        const double k = em_hac_cost(ws, d, a, c);
        if (k < best_cost) {
            best_cost = k;
            best = c;
        }
    }
    *cost = best_cost;
    return best;
}

/* Merges slot b into slot a and records the merge. */
static void em_hac_merge(em_hac_work_t *ws, size_t d, size_t a, size_t b, double cost, size_t m)
{
    const double na = ws->size[a];
    const double nb = ws->size[b];
    for (size_t j = 0u; j < d; ++j) {
        ws->centroid[a][j] = (na * ws->centroid[a][j] + nb * ws->centroid[b][j]) / (na + nb);
    }
    ws->size[a] = na + nb;
    ws->size[b] = 0.0;
    ws->merge_a[m] = (uint16_t)a;
    ws->merge_b[m] = (uint16_t)b;
    ws->merge_cost[m] = cost;
    ws->order[m] = (uint16_t)m;
}

static size_t em_hac_first_active(const em_hac_work_t *ws)
{
    for (size_t c = 0u; c < ws->n; ++c) {
        if (ws->size[c] > 0.0) {
            return c;
        }
    }
    return EM_HAC_NONE;
}

md_status_t em_hac_ward(const em_data_t *data, em_hac_work_t *ws)
{
    if ((data == NULL) || (ws == NULL) || (data->y == NULL) || (data->n == 0u) || (data->n > EM_N_MAX) ||
        (data->d == 0u) || (data->d > EM_D_MAX) || !linalg_all_finite(data->y, data->n * data->d)) {
        return MD_E_ARG;
    }
    const size_t d = data->d;
    ws->n = data->n;
    for (size_t i = 0u; i < data->n; ++i) {
        memcpy(ws->centroid[i], &data->y[i * d], d * sizeof(double));
        ws->size[i] = 1.0;
    }
    size_t top = 0u; /* chain length */
    size_t merges = 0u;
    /* each step pushes one slot or merges (pops two); pushes ≤ 2·merges + n, so 4n bounds the steps */
    for (size_t step = 0u; (merges + 1u < data->n) && (step < 4u * data->n + 4u); ++step) {
        if (top == 0u) {
            ws->chain[top++] = (uint16_t)em_hac_first_active(ws);
        }
        const size_t a = ws->chain[top - 1u];
        const size_t prev = (top >= 2u) ? ws->chain[top - 2u] : EM_HAC_NONE;
        double cost = 0.0;
        const size_t b = em_hac_nearest(ws, d, a, prev, &cost);
        if ((b == EM_HAC_NONE) || !isfinite(cost)) {
            return MD_E_NUMERIC;
        }
        if (b == prev) {
            top -= 2u;
            em_hac_merge(ws, d, a, b, cost, merges++);
        } else {
            ws->chain[top++] = (uint16_t)b;
        }
    }
    if (merges + 1u < data->n) {
        return MD_E_NUMERIC;
    }
    em_sort_keys(ws->merge_cost, ws->order, merges);
    return MD_OK;
}

static uint16_t em_hac_find(uint16_t *parent, uint16_t x, size_t n)
{
    for (size_t guard = 0u; (guard < n) && (parent[x] != x); ++guard) {
        parent[x] = parent[parent[x]]; /* path halving */
        x = parent[x];
    }
    return x;
}

md_status_t em_hac_cut(em_hac_work_t *ws, size_t g, uint8_t *labels)
{
    if ((ws == NULL) || (labels == NULL) || (g == 0u) || (g > EM_G_MAX) || (ws->n == 0u) || (g > ws->n) ||
        (ws->n > EM_N_MAX)) {
        return MD_E_ARG;
    }
    const size_t n = ws->n;
    for (size_t i = 0u; i < n; ++i) {
        ws->parent[i] = (uint16_t)i;
    }
    for (size_t k = 0u; k + g < n; ++k) {
        const size_t m = ws->order[k];
        const uint16_t ra = em_hac_find(ws->parent, ws->merge_a[m], n);
        const uint16_t rb = em_hac_find(ws->parent, ws->merge_b[m], n);
        ws->parent[rb] = ra;
    }
    uint16_t root_of[EM_G_MAX] = {0u};
    size_t found = 0u;
    for (size_t i = 0u; i < n; ++i) {
        const uint16_t r = em_hac_find(ws->parent, (uint16_t)i, n);
        size_t lab = 0u;
        while ((lab < found) && (root_of[lab] != r)) {
            lab++;
        }
        if (lab == found) {
            if (found == g) {
                return MD_E_NUMERIC; /* more roots than merges allow: corrupt workspace */
            }
            root_of[found++] = r;
        }
        labels[i] = (uint8_t)lab;
    }
    return (found == g) ? MD_OK : MD_E_NUMERIC;
}
