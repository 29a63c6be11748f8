"""chronomap: world models that know time.

Learn from sparse, irregular observations how states of a robot's world change with daily and
weekly rhythms (FreMEn, PerGaM, Warped Hypertime, ...), predict them for any time with
calibrated probabilities, and turn predictions into decisions.

>>> import numpy as np, chronomap
>>> t = np.arange(0, 14 * 86400, 600.0)                  # two weeks, every 10 minutes
>>> open_by_day = ((t % 86400) / 3600 >= 8) & ((t % 86400) / 3600 < 18)
>>> door = chronomap.Fremen(order=2).observe(t, open_by_day.astype(float))
>>> round(float(door.predict(15 * 86400 + 12 * 3600)), 2) > 0.8   # noon, the day after
True

Everything numeric runs in Rust (the crates of the `chronomap` command line); this package
only translates arrays and errors. Files written here are read by the command line and the
service, and the other way round.
"""

from __future__ import annotations

from chronomap import _native
from chronomap._native import (
    CopaMap,
    Fft,
    Fremen,
    Hist,
    Hypertime,
    HypertimeEvents,
    Mean,
    PerGaM,
    Persistence,
    Stm,
    TemporalModel,
    load,
    load_copa_map,
    loads,
    model,
    psbt_synthesize,
    read_events,
    read_pairs,
    read_rate_samples,
    read_test_set,
)

from chronomap.client import Client, ServiceError, read_token
from chronomap.grid import Grid, load_grid, read_map
from chronomap.topo import EdgeModels, load_edge_models

__version__: str = _native.__version__

__all__ = [
    "Client",
    "CopaMap",
    "EdgeModels",
    "Fft",
    "Fremen",
    "Grid",
    "Hist",
    "Hypertime",
    "HypertimeEvents",
    "Mean",
    "PerGaM",
    "Persistence",
    "Stm",
    "ServiceError",
    "TemporalModel",
    "evaluate",
    "load",
    "load_copa_map",
    "load_edge_models",
    "load_grid",
    "loads",
    "model",
    "psbt_synthesize",
    "read_events",
    "read_map",
    "read_pairs",
    "read_rate_samples",
    "read_test_set",
    "read_token",
]


def evaluate(train, tests, models, *, as_frame=False, periods="week", holdout=0.25,
             max_order=10, criterion="brier", recent_days=(7, 14, 28, 56), days_off=None):
    """The experiment of ``chronomap eval`` (the FreMEn benchmarks) on arrays.

    Every model in ``models`` (specs such as ``"fremen:2"`` or ``"auto"``) is fitted on
    ``train`` and scored on every test set; the numbers are those ``chronomap eval`` prints.

    Parameters
    ----------
    train : (times, values)
        Training observations, times in seconds (float64), values in [0, 1].
    tests : sequence of (times, values)
        Test sets.
    models : sequence of str
        Model specs.
    as_frame : bool
        Return a ``pandas.DataFrame`` (needs pandas) instead of a dict of arrays.
    periods, holdout, max_order, criterion : optional
        How orders and families are chosen (``chronomap eval --periods``, ``--holdout``,
        ``--max-order``, ``--criterion``), as for ``TemporalModel``.
    recent_days : sequence of int, or None
        Memories in days of ``auto``'s drift candidates (``chronomap eval --recent-days``):
        for each, the mean and histograms of the last that many days only; whole days from 1
        to 3650. ``None`` or ``()`` for none (the stack without drift candidates). Other
        values raise ``ValueError`` naming ``recent_days``.
    days_off : str or path, optional
        A calendar of days off (``chronomap eval --days-off``: one ``YYYY-MM-DD`` per line):
        training observations on them are left out, test times on them are predicted as the
        Sunday before.

    Returns
    -------
    dict of arrays, or pandas.DataFrame
        One row per model: ``model`` (the spec as given), ``fitted`` (as fitted, orders
        resolved), ``mse_1`` .. ``mse_n`` (Brier score per test set), ``mean_mse``,
        ``binary_error_1`` .. ``binary_error_n``, ``mean_binary_error``, ``ece_1`` ..
        ``ece_n`` (expected calibration error, 10 equal-width bins) and ``mean_ece``; then the
        calibration of all test sets together: ``ece``, the Brier score's decomposition
        (Murphy 1973) ``reliability``, ``resolution``, ``uncertainty`` and ``within_bins``
        (they add up to the pooled Brier score as ``reliability - resolution + uncertainty +
        within_bins``), ``mean_prediction`` and ``base_rate``.
    """
    if isinstance(models, str):
        models = [models]
    table = _native.evaluate_table(train, list(tests), list(models), periods=periods,
                                   holdout=holdout, max_order=max_order, criterion=criterion,
                                   recent_days=recent_days,
                                   days_off=None if days_off is None else str(days_off))
    import numpy as np

    table["model"] = np.array(table["model"], dtype=object)
    table["fitted"] = np.array(table["fitted"], dtype=object)
    if as_frame:
        try:
            import pandas as pd
        except ImportError as e:  # pragma: no cover - depends on the environment
            raise ImportError("evaluate(..., as_frame=True) needs pandas: pip install pandas") from e
        return pd.DataFrame(table)
    return table
