#!/usr/bin/env python3
"""Reference AdaBoost fits by scikit-learn for crates/lidar/tests/it/sklearn_adaboost.rs.

Usage: sklearn_adaboost.py CASES.json

The case file is a JSON object mapping case names to objects:
  X              n x d training rows (values that float32 represents exactly)
  y              n labels 0/1
  sample_weight  null, or n non-negative weights
  n_estimators   boosting rounds
  X_test         m x d rows to score

For every case it fits
  AdaBoostClassifier(estimator=DecisionTreeClassifier(max_depth=1), n_estimators=...,
                     random_state=0).fit(X, y, sample_weight=...)
and prints, per case, each stump's split feature (-1 for a leaf without split), threshold
and the classes of its two leaves, estimator_weights_ and estimator_errors_ (of the fitted
stumps only), and decision_function / predict_proba[:, 1] / predict on X_test.
"""

import json
import sys

import numpy as np
import sklearn
from sklearn.ensemble import AdaBoostClassifier
from sklearn.tree import DecisionTreeClassifier


def fit(case):
    X = np.asarray(case["X"], dtype=np.float64)
    y = np.asarray(case["y"], dtype=np.int64)
    if not np.array_equal(X.astype(np.float32).astype(np.float64), X):
        raise ValueError("X must be float32-representable (scikit-learn trees read float32)")
    w = case.get("sample_weight")
    w = None if w is None else np.asarray(w, dtype=np.float64)
    model = AdaBoostClassifier(
        estimator=DecisionTreeClassifier(max_depth=1),
        n_estimators=int(case["n_estimators"]),
        random_state=0,
    ).fit(X, y, sample_weight=w)
    stumps = []
    for est in model.estimators_:
        tree = est.tree_
        if tree.node_count == 1:
            cls = int(np.argmax(tree.value[0][0]))
            stumps.append({"feature": -1, "threshold": 0.0, "below": cls, "above": cls})
        else:
            left, right = tree.children_left[0], tree.children_right[0]
            stumps.append(
                {
                    "feature": int(tree.feature[0]),
                    "threshold": float(tree.threshold[0]),
                    "below": int(est.classes_[np.argmax(tree.value[left][0])]),
                    "above": int(est.classes_[np.argmax(tree.value[right][0])]),
                }
            )
    k = len(model.estimators_)
    Xt = np.asarray(case["X_test"], dtype=np.float64)
    return {
        "stumps": stumps,
        "alphas": model.estimator_weights_[:k].tolist(),
        "errors": model.estimator_errors_[:k].tolist(),
        "decision": model.decision_function(Xt).tolist(),
        "proba": model.predict_proba(Xt)[:, 1].tolist(),
        "predict": [int(v) for v in model.predict(Xt)],
    }


def main(paths):
    if len(paths) != 1:
        sys.exit(__doc__)
    with open(paths[0]) as f:
        cases = json.load(f)
    json.dump({name: fit(case) for name, case in cases.items()}, sys.stdout)
    print()
    print(
        f"sklearn_adaboost.py: {len(cases)} case(s), scikit-learn {sklearn.__version__}, "
        f"numpy {np.__version__}",
        file=sys.stderr,
    )


if __name__ == "__main__":
    main(sys.argv[1:])
