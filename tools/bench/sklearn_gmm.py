#!/usr/bin/env python3
"""scikit-learn's GaussianMixture on the same spike features as one MHTC step.

    sklearn_gmm.py FEATURES.txt [--runs N]

FEATURES.txt: one spike per line, its 2-D PCA features (md-bench --features).
One "fit" = GaussianMixture(n_components=G, covariance_type='full') for
G = 1..4 and the choice of the lowest BIC, the scikit-learn counterpart of one
MHTC step's G = 1..4 model selection. Prints the median and min wall time over
N fits (time is reported, never judged), the chosen G, and the BLAS/OpenMP
thread pools in use (threadpoolctl), one `key value` pair per line.
"""
import argparse
import statistics
import sys
import time

import numpy as np
from sklearn.mixture import GaussianMixture


def fit_bic(y: np.ndarray, seed: int) -> int:
    best_g, best_bic = 0, float("inf")
    for g in range(1, 5):
        gm = GaussianMixture(n_components=g, covariance_type="full", random_state=seed).fit(y)
        bic = gm.bic(y)
        if bic < best_bic:
            best_g, best_bic = g, bic
    return best_g


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("features")
    ap.add_argument("--runs", type=int, default=21)
    args = ap.parse_args()
    y = np.loadtxt(args.features, ndmin=2)
    if y.shape[0] < 5 or y.shape[1] != 2:
        print(f"sklearn_gmm: need n x 2 features, got {y.shape}", file=sys.stderr)
        return 1
    fit_bic(y, 0)  # warm-up: imports, first-call costs
    times, gs = [], []
    for r in range(args.runs):
        t0 = time.perf_counter()
        gs.append(fit_bic(y, r))
        times.append((time.perf_counter() - t0) * 1e3)
    print(f"n_spikes {y.shape[0]}")
    print(f"median_ms {statistics.median(times):.3f}")
    print(f"min_ms {min(times):.3f}")
    print(f"runs {args.runs}")
    print(f"best_g {statistics.mode(gs)}")
    try:
        from threadpoolctl import threadpool_info

        pools = ";".join(f"{p.get('internal_api')}:{p.get('architecture', '-')}:{p.get('num_threads')}"
                         for p in threadpool_info())
        print(f"threadpools {pools or 'none'}")
    except ImportError:
        print("threadpools unknown")
    return 0


if __name__ == "__main__":
    sys.exit(main())
