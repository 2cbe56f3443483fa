/// @file em_seed.c
/// Seed partitions of thesis §3.3.4 (see em_seed.h).
#include "cluster/em_seed.h"

#include <math.h>
#include <string.h>

#include "numeric/linalg.h"

#define EM_SEED_JACOBI_SWEEPS 30u

typedef struct {
    double chol[EM_J_MAX][EM_D_MAX * EM_D_MAX];
} em_seed_factors_t;

static md_status_t em_seed_factor(const em_target_t *targets, size_t n_targets, size_t d, em_seed_factors_t *f)
{
    for (size_t j = 0u; j < n_targets; ++j) {
        memcpy(f->chol[j], targets[j].cluster_cov, d * d * sizeof(double));
        if ((linalg_cholesky(f->chol[j], d) != MD_OK) || !linalg_all_finite(targets[j].mean, d)) {
            return MD_E_NUMERIC;
        }
    }
    return MD_OK;
}

/* Assigns each point to the nearest (eq. 3.16) prior cluster of `mask`;
 * labels are the ranks of the chosen clusters within the mask. Σ d^2 into *total. */
static md_status_t em_seed_assign(const em_data_t *data, const em_target_t *targets, size_t n_targets,
                                  const em_seed_factors_t *f, uint32_t mask, uint8_t *labels, double *total)
{
    double sum = 0.0;
    for (size_t i = 0u; i < data->n; ++i) {
        const double *y = &data->y[i * data->d];
        double best = INFINITY;
        uint8_t rank = 0u;
        uint8_t best_rank = 0u;
        for (size_t j = 0u; j < n_targets; ++j) {
            if ((mask & (1u << j)) == 0u) {
                continue;
            }
            double work[EM_D_MAX];
            double d2 = 0.0;
            const md_status_t st = linalg_mahalanobis2(f->chol[j], data->d, y, targets[j].mean, work, &d2);
            if (st != MD_OK) {
                return st;
            }
            if (d2 < best) {
                best = d2;
                best_rank = rank;
            }
            rank++;
        }
        if (labels != NULL) {
            labels[i] = best_rank;
        }
        sum += best;
    }
    *total = sum;
    return MD_OK;
}

static unsigned em_popcount(uint32_t m)
{
    unsigned c = 0u;
    for (unsigned b = 0u; b < 32u; ++b) {
        c += (m >> b) & 1u;
    }
    return c;
}

/* §3.3.4.2: the subset of g prior clusters with the least summed d^2, into *best_mask. */
static md_status_t em_seed_best_subset(const em_data_t *data, const em_target_t *targets, size_t n_targets,
                                       const em_seed_factors_t *f, size_t g, uint32_t *best_mask)
{
    uint32_t best_m = 0u;
    double best = INFINITY;
    for (uint32_t mask = 1u; mask < (1u << n_targets); ++mask) {
        if (em_popcount(mask) != g) {
            continue;
        }
        double total = 0.0;
        const md_status_t st = em_seed_assign(data, targets, n_targets, f, mask, NULL, &total);
        if (st != MD_OK) {
            return st;
        }
        if ((best_m == 0u) || (total < best)) {
            best = total;
            best_m = mask;
        }
    }
    *best_mask = best_m;
    return MD_OK;
}

/* Mean Euclidean point-to-centroid distance of group `lab`; 0 if < 2 points. */
static double em_seed_spread(const em_data_t *data, const uint8_t *labels, uint8_t lab)
{
    const size_t d = data->d;
    double c[EM_D_MAX] = {0.0};
    double n = 0.0;
    for (size_t i = 0u; i < data->n; ++i) {
        if (labels[i] == lab) {
            n += 1.0;
            for (size_t j = 0u; j < d; ++j) {
                c[j] += data->y[i * d + j];
            }
        }
    }
    if (n < 2.0) {
        return 0.0;
    }
    double s = 0.0;
    for (size_t i = 0u; i < data->n; ++i) {
        if (labels[i] == lab) {
            double r2 = 0.0;
            for (size_t j = 0u; j < d; ++j) {
                const double r = data->y[i * d + j] - c[j] / n;
                r2 += r * r;
            }
            s += sqrt(r2);
        }
    }
    return s / n;
}

/* Unit principal axis of the points of group `lab`; returns the member count. */
static size_t em_seed_axis(const em_data_t *data, const uint8_t *labels, uint8_t lab, double *axis)
{
    const size_t d = data->d;
    double c[EM_D_MAX] = {0.0};
    double cov[EM_D_MAX * EM_D_MAX] = {0.0};
    size_t n = 0u;
    for (size_t i = 0u; i < data->n; ++i) {
        if (labels[i] == lab) {
            n++;
            for (size_t j = 0u; j < d; ++j) {
                c[j] += data->y[i * d + j];
            }
        }
    }
    for (size_t j = 0u; (n > 0u) && (j < d); ++j) {
        c[j] /= (double)n;
    }
    for (size_t i = 0u; i < data->n; ++i) {
        for (size_t a = 0u; (labels[i] == lab) && (a < d); ++a) {
            for (size_t b = 0u; b < d; ++b) {
                cov[a * d + b] += (data->y[i * d + a] - c[a]) * (data->y[i * d + b] - c[b]);
            }
        }
    }
    double vals[EM_D_MAX];
    double vecs[EM_D_MAX * EM_D_MAX];
    if ((n < 2u) || (linalg_sym_eigen(cov, d, vals, vecs, EM_SEED_JACOBI_SWEEPS) != MD_OK) || !(vals[0] > 0.0)) {
        return 0u;
    }
    for (size_t j = 0u; j < d; ++j) {
        axis[j] = vecs[j * d]; /* column 0: the largest eigenvalue */
    }
    return n;
}

md_status_t em_seed_split(const em_data_t *data, uint8_t *labels, uint8_t victim, uint8_t new_label, em_seed_work_t *ws)
{
    if ((data == NULL) || (labels == NULL) || (ws == NULL) || (data->y == NULL) || (data->n > EM_N_MAX) ||
        (data->d == 0u) || (data->d > EM_D_MAX)) {
        return MD_E_ARG;
    }
    double axis[EM_D_MAX];
    const size_t n = em_seed_axis(data, labels, victim, axis);
    if (n < 2u) {
        return MD_E_DEGENERATE;
    }
    size_t m = 0u;
    for (size_t i = 0u; i < data->n; ++i) {
        if (labels[i] == victim) {
            double proj = 0.0;
            for (size_t j = 0u; j < data->d; ++j) {
                proj += axis[j] * data->y[i * data->d + j];
            }
            ws->key[m] = proj;
            ws->idx[m] = (uint16_t)i;
            m++;
        }
    }
    em_sort_keys(ws->key, ws->idx, m);
    /* footnote 10: the cut stays inside the middle 90 % of the sorted points */
    const size_t trim = (size_t)floor(0.5 * (1.0 - EM_SEED_MIDDLE_FRACTION) * (double)m);
    const size_t lo = (m - 1u > 2u * trim) ? trim : 0u;
    const size_t hi = (m - 1u > 2u * trim) ? (m - 1u - trim) : (m - 1u);
    size_t cut = lo;
    for (size_t k = lo; k < hi; ++k) {
        if ((ws->key[k + 1u] - ws->key[k]) > (ws->key[cut + 1u] - ws->key[cut])) {
            cut = k;
        }
    }
    for (size_t k = cut + 1u; k < m; ++k) {
        labels[ws->idx[k]] = new_label;
    }
    return MD_OK;
}

/* §3.3.4.3: split the widest group until there are g groups. */
static md_status_t em_seed_grow(const em_data_t *data, size_t have, size_t g, em_seed_work_t *ws, uint8_t *labels)
{
    for (size_t k = have; k < g; ++k) {
        uint8_t widest = 0u;
        double best = 0.0;
        for (size_t c = 0u; c < k; ++c) {
            const double s = em_seed_spread(data, labels, (uint8_t)c);
            if (s > best) {
                best = s;
                widest = (uint8_t)c;
            }
        }
        if (!(best > 0.0)) {
            return MD_E_DEGENERATE;
        }
        const md_status_t st = em_seed_split(data, labels, widest, (uint8_t)k, ws);
        if (st != MD_OK) {
            return st;
        }
    }
    return MD_OK;
}

/* Renumbers the used labels 0..k-1 (a prior cluster no point chose leaves a
 * hole that splitting then fills); returns k. */
static size_t em_seed_compact(uint8_t *labels, size_t n)
{
    uint8_t map[32];
    uint32_t seen = 0u;
    for (size_t i = 0u; i < n; ++i) {
        seen |= 1u << labels[i];
    }
    size_t k = 0u;
    for (size_t b = 0u; b < 32u; ++b) {
        map[b] = (uint8_t)k;
        k += (seen >> b) & 1u;
    }
    for (size_t i = 0u; i < n; ++i) {
        labels[i] = map[labels[i]];
    }
    return k;
}

static bool em_seed_nonempty(const uint8_t *labels, size_t n, size_t g)
{
    uint32_t seen = 0u;
    for (size_t i = 0u; i < n; ++i) {
        seen |= 1u << labels[i];
    }
    return seen == ((1u << g) - 1u);
}

md_status_t em_seed_from_targets(const em_data_t *data, const em_target_t *targets, size_t n_targets, size_t g,
                                 em_seed_work_t *ws, uint8_t *labels)
{
    if ((data == NULL) || (data->y == NULL) || (ws == NULL) || (labels == NULL) || (g == 0u) || (g > EM_G_MAX) ||
        (n_targets > EM_J_MAX) || ((targets == NULL) && (n_targets > 0u)) || (data->n > EM_N_MAX) || (data->d == 0u) ||
        (data->d > EM_D_MAX)) {
        return MD_E_ARG;
    }
    if (data->n < g) {
        return MD_E_DEGENERATE;
    }
    em_seed_factors_t f;
    if (em_seed_factor(targets, n_targets, data->d, &f) != MD_OK) {
        return MD_E_NUMERIC;
    }
    size_t have = 1u;
    if (n_targets == 0u) {
        memset(labels, 0, data->n); /* one group, then split (§3.3.4.3 with J = 0) */
    } else {
        uint32_t mask = (1u << n_targets) - 1u; /* all */
        double total = 0.0;
        md_status_t st = (g < n_targets) ? em_seed_best_subset(data, targets, n_targets, &f, g, &mask) : MD_OK;
        if (st == MD_OK) {
            st = em_seed_assign(data, targets, n_targets, &f, mask, labels, &total);
        }
        if (st != MD_OK) {
            return st;
        }
        have = em_seed_compact(labels, data->n);
    }
    const md_status_t st = em_seed_grow(data, have, g, ws, labels);
    if (st != MD_OK) {
        return st;
    }
    return em_seed_nonempty(labels, data->n, g) ? MD_OK : MD_E_DEGENERATE;
}
