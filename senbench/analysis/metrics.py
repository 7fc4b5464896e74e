"""Per-cell metrics of an evaluation curve.

- initial return: the evaluation return at frame 0, before any learning;
- final return: mean evaluation return over the last ``FINAL_WINDOW`` evaluations;
- steps-to-threshold: the first evaluation step from which the trailing mean of
  ``THRESHOLD_WINDOW`` evaluations stays at or above the threshold until the end of the
  budget; NaN when never reached (a value, not an error);
- AUC: the curve's mean return over the whole budget (trapezoid rule over frames), one
  number for data efficiency.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

FINAL_WINDOW = 3
THRESHOLD_WINDOW = 3


def final_return(returns: np.ndarray, window: int = FINAL_WINDOW) -> float:
    returns = np.asarray(returns, dtype=float)
    return float(np.mean(returns[-window:])) if len(returns) else float("nan")


def steps_to_threshold(steps: np.ndarray, returns: np.ndarray, threshold: float,
                       window: int = THRESHOLD_WINDOW) -> float:
    steps = np.asarray(steps, dtype=float)
    if not np.isfinite(threshold):
        return float("nan")
    returns = pd.Series(np.asarray(returns, dtype=float))
    trailing = returns.rolling(window, min_periods=1).mean().to_numpy().copy()
    # a NaN return (a diverged agent) is never "at or above"; a window holding one neither
    trailing[returns.isna().rolling(window, min_periods=1).max().to_numpy() > 0] = np.nan
    below = np.flatnonzero(~(trailing >= threshold))
    first = 0 if len(below) == 0 else below[-1] + 1
    return float(steps[first]) if first < len(steps) else float("nan")


def auc(steps: np.ndarray, returns: np.ndarray) -> float:
    steps = np.asarray(steps, dtype=float)
    returns = np.asarray(returns, dtype=float)
    if len(steps) < 2 or steps[-1] == steps[0]:
        return float(returns[0]) if len(returns) else float("nan")
    return float(np.trapezoid(returns, steps) / (steps[-1] - steps[0]))


def cell_metrics(results: pd.DataFrame) -> pd.DataFrame:
    """One row per cell: identity, status, the three metrics of its evaluation curve, and
    the mean return of its training episodes (``train_return``)."""
    cells = results[results["kind"] == "cell"]
    evals = results[results["kind"] == "eval"].sort_values("step")
    curves = dict(list(evals.groupby(["suite", "cell_id"])))
    episodes = results[results["kind"] == "episode"]
    training = episodes.groupby(["suite", "cell_id"])["return"].mean().to_dict()
    rows = []
    for _, cell in cells.iterrows():
        cell_id = cell["cell_id"]
        curve = curves.get((cell["suite"], cell_id), evals.iloc[:0])
        steps, returns = curve["step"].to_numpy(), curve["return"].to_numpy()
        ok = cell["status"] == "ok" and len(curve) > 0
        rows.append({
            "suite": cell["suite"], "cell_id": cell_id, "env": cell["env"],
            "method": cell["method"],
            "variant": cell["variant"], "seed": cell["seed"], "status": cell["status"],
            "threshold": cell["threshold"], "budget": cell["budget"],
            "initial_return": float(returns[0]) if ok else np.nan,
            "final_return": final_return(returns) if ok else np.nan,
            "steps_to_threshold": steps_to_threshold(steps, returns, cell["threshold"])
            if ok else np.nan,
            "auc": auc(steps, returns) if ok else np.nan,
            # what the agent earned while learning, exploration included
            "train_return": float(training.get((cell["suite"], cell_id), np.nan))
            if ok else np.nan,
            "wall_s": cell["cell_wall_s"],
        })
    frame = pd.DataFrame(rows)
    if frame.empty:
        return frame
    # In seed order: the bootstrap resamples positions, so an order that followed the cells'
    # ids (hashes) would move the intervals whenever the ids change.
    order = ["suite", "env", "method", "variant", "seed"]
    return frame.sort_values(order, kind="stable").reset_index(drop=True)
