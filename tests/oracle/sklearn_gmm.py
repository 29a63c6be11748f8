#!/usr/bin/env python3
"""Reference Gaussian-mixture fits by scikit-learn for tests/sklearn_gmm.rs.

Usage: sklearn_gmm.py CASE.json [CASE.json ...]

Each case file is a JSON object:
  data             n x d list of rows
  weights          null, or n non-negative integers (row i is repeated weights[i] times:
                   scikit-learn has no sample weights, a weight w means w identical rows)
  means_init       k x d
  weights_init     k (summing to 1)
  precisions_init  k x d x d (inverses of the initial covariances)
  reg_covar, tol, max_iter

For every case it runs
  GaussianMixture(n_components=k, covariance_type="full", reg_covar=..., tol=..., max_iter=...,
                  n_init=1, means_init=..., weights_init=..., precisions_init=...).fit(X)
and prints weights_, means_, covariances_, n_iter_, converged_, lower_bound_, lower_bounds_
(scikit-learn >= 1.7) and score (the mean log-likelihood of the fitted mixture). With one case
file the printed JSON is that result; with several it maps each file's name to its result.
"""

import json
import os
import sys
import warnings

import numpy as np
import sklearn
from sklearn.exceptions import ConvergenceWarning
from sklearn.mixture import GaussianMixture


def fit(case):
    X = np.asarray(case["data"], dtype=np.float64)
    if case.get("weights") is not None:
        w = np.asarray(case["weights"], dtype=np.float64)
        if np.any(w < 0) or np.any(w != np.round(w)):
            raise ValueError("weights must be non-negative integers")
        X = np.repeat(X, w.astype(np.int64), axis=0)
    means = np.asarray(case["means_init"], dtype=np.float64)
    k = means.shape[0]
    gm = GaussianMixture(
        n_components=k,
        covariance_type="full",
        reg_covar=float(case["reg_covar"]),
        tol=float(case["tol"]),
        max_iter=int(case["max_iter"]),
        n_init=1,
        means_init=means,
        weights_init=np.asarray(case["weights_init"], dtype=np.float64),
        precisions_init=np.asarray(case["precisions_init"], dtype=np.float64),
        random_state=0,
    )
    with warnings.catch_warnings():
        # The unused k-means initialisation and a start that does not converge warn.
        warnings.simplefilter("ignore", ConvergenceWarning)
        gm.fit(X)
    return {
        "weights_": gm.weights_.tolist(),
        "means_": gm.means_.tolist(),
        "covariances_": gm.covariances_.tolist(),
        "n_iter_": int(gm.n_iter_),
        "converged_": bool(gm.converged_),
        "lower_bound_": float(gm.lower_bound_),
        "lower_bounds_": [float(v) for v in getattr(gm, "lower_bounds_", [])],
        "score": float(gm.score(X)),
        "rows": int(X.shape[0]),
        "sklearn": sklearn.__version__,
        "numpy": np.__version__,
    }


def main(paths):
    if not paths:
        sys.exit(__doc__)
    results = {}
    for path in paths:
        with open(path) as f:
            results[os.path.basename(path)] = fit(json.load(f))
    out = next(iter(results.values())) if len(paths) == 1 else results
    json.dump(out, sys.stdout)
    print()
    print(
        f"sklearn_gmm.py: {len(paths)} case(s), scikit-learn {sklearn.__version__}, "
        f"numpy {np.__version__}",
        file=sys.stderr,
    )


if __name__ == "__main__":
    main(sys.argv[1:])
