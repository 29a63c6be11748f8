"""scikit-learn's calibration curve and Brier score of forecasts, for tests/cli/sklearn_calibration.rs.

Reads a JSON file {"cases": [{"name", "p", "y", "bins"}]} and prints, per case, what
`sklearn.calibration.calibration_curve(strategy="uniform")` and `sklearn.metrics.brier_score_loss`
give, with the bin counts found the way calibration_curve sorts forecasts into bins.
"""

import json
import sys

import numpy as np
from sklearn.calibration import calibration_curve
from sklearn.metrics import brier_score_loss

cases = json.load(open(sys.argv[1]))["cases"]
out = []
for case in cases:
    p = np.asarray(case["p"], dtype=float)
    y = np.asarray(case["y"], dtype=float).astype(int)
    bins = case["bins"]
    prob_true, prob_pred = calibration_curve(y, p, n_bins=bins, strategy="uniform")
    # The bin of each forecast exactly as calibration_curve computes it.
    edges = np.linspace(0.0, 1.0, bins + 1)
    ids = np.searchsorted(edges[1:-1], p)
    counts = np.bincount(ids, minlength=bins)
    counts = counts[counts > 0]
    out.append({
        "name": case["name"],
        "prob_true": prob_true.tolist(),
        "prob_pred": prob_pred.tolist(),
        "counts": counts.tolist(),
        "brier": float(brier_score_loss(y, p)),
    })
print(json.dumps(out))
print(f"{len(out)} cases", file=sys.stderr)
