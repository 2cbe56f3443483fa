/// @file em_hac.h
/// Hierarchical agglomerative clustering that seeds the ML baseline (thesis
/// §3.5: "seed clusters ... from a standard hierarchical agglomerative
/// technique", following Fraley & Raftery 1998).
///
/// Linkage: Ward's (merge cost n_a n_b / (n_a + n_b) · |c_a - c_b|^2), found by
/// the nearest-neighbour-chain algorithm. Ward's linkage is reducible, so the
/// chain yields the same dendrogram as the greedy algorithm while keeping only
/// centroids and sizes: O(n) memory (no n × n distance matrix, which would be
/// 2 MB of doubles at n = 512) and O(n^2 d) time. No recursion: the chain is an
/// explicit array. The merges are sorted by cost afterwards; a cut at G groups
/// replays the n - G cheapest merges with a union-find.
#ifndef EM_HAC_H
#define EM_HAC_H

#include "cluster/em_model.h"

/// Caller-owned workspace (about 26 KB at EM_N_MAX = 512, d = 3).
typedef struct {
    size_t n;                             ///< points of the last em_hac_ward call
    double centroid[EM_N_MAX][EM_D_MAX];  ///< centroid of the cluster held in each slot
    double size[EM_N_MAX];                ///< members of each slot's cluster (0 = inactive)
    uint16_t chain[EM_N_MAX];             ///< the nearest-neighbour chain (a stack)
    uint16_t merge_a[EM_N_MAX];           ///< slot pairs merged, in order found
    uint16_t merge_b[EM_N_MAX];
    double merge_cost[EM_N_MAX];  ///< sorted ascending after em_hac_ward
    uint16_t order[EM_N_MAX];     ///< merge indices in ascending cost
    uint16_t parent[EM_N_MAX];    ///< union-find forest of em_hac_cut
} em_hac_work_t;

/// Builds the Ward dendrogram of the n ≥ 1 points into ws. O(n^2 d).
/// MD_E_ARG on bad input, MD_E_NUMERIC if a distance is not finite.
md_status_t em_hac_ward(const em_data_t *data, em_hac_work_t *ws);

/// Labels 0..g-1 (one per point) of the dendrogram cut at g groups,
/// numbered in order of first appearance. Requires 1 ≤ g ≤ min(n, EM_G_MAX). O(n α(n)).
md_status_t em_hac_cut(em_hac_work_t *ws, size_t g, uint8_t *labels);

#endif
