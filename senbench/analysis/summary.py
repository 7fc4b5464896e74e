"""``senbench report``: a table per env, one row per method (and variant), over seeds."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd

from senbench.analysis.metrics import cell_metrics
from senbench.analysis.stats import iqm, stratified_ci
from senbench.errors import ResultsError

METRICS = {  # summary prefix → (per-cell column, higher is better)
    "final": ("final_return", True),
    "steps": ("steps_to_threshold", False),
    "auc": ("auc", True),
    "charged": ("charged_frames", False),
}
"""``charged``: frames to threshold plus the labelled frames the method's encoder was
trained on before its first online frame (0 for state and pixel learners)."""


def parse_thresholds(specs: list[str]) -> dict[str | None, float]:
    """``--threshold`` values: ``-150`` (results of one env) or ``mountaincar=-150``."""
    thresholds: dict[str | None, float] = {}
    for spec in specs:
        env, _, value = spec.rpartition("=")
        try:
            number = float(value)
        except ValueError:
            number = float("nan")
        if not np.isfinite(number) or (_ and not env):
            raise ResultsError(f"--threshold {spec!r}: give a return, e.g. -150, or an env "
                               "and a return, e.g. mountaincar=-150")
        thresholds[env or None] = number
    if None in thresholds and len(thresholds) > 1:
        raise ResultsError("--threshold: give one return for every env, or ENV=RETURN for "
                           "each, not both")
    return thresholds


def with_thresholds(results: pd.DataFrame, thresholds: dict[str | None, float],
                    envs: set[str] | None = None) -> pd.DataFrame:
    """``results`` with the threshold of each named env (``None``: the only env) replaced,
    so that frames to threshold, the report's title and the plots' dashed line use it.
    ``envs``: the envs the names are checked against (default: those of ``results``; two
    folders compared give the envs of both)."""
    if not thresholds:
        return results
    envs = sorted(envs if envs is not None else set(results["env"]))
    if None in thresholds:
        if len(envs) > 1:
            raise ResultsError(f"these results hold envs {', '.join(envs)}: give --threshold "
                               "ENV=RETURN for each one to change")
        thresholds = {envs[0]: thresholds[None]}
    unknown = sorted(set(thresholds) - set(envs))
    if unknown:
        raise ResultsError(f"--threshold names env {', '.join(unknown)}, which these results "
                           f"do not hold; they hold: {', '.join(envs)}")
    results = results.copy()
    for env, value in thresholds.items():
        results.loc[results["env"] == env, "threshold"] = value
    return results


def label(method: str, variant: str) -> str:
    """A method as the report names it: ``sen-sarsa [encoder.fraction=0.2]``."""
    return method + (f" [{variant}]" if variant else "")


def per_cell(results: pd.DataFrame) -> pd.DataFrame:
    """``cell_metrics`` with ``steps_to_threshold`` of a seed that never reached the
    threshold set to the budget (censored: it needs at least that many frames), so that
    every finished seed counts, and ``reached`` saying which did."""
    cells = cell_metrics(results)
    cells["reached"] = cells["steps_to_threshold"].notna()
    ok = cells["status"] == "ok"
    cells.loc[ok & ~cells["reached"], "steps_to_threshold"] = cells["budget"].astype(float)
    rows = results[results["kind"] == "cell"]
    configs = dict(zip(zip(rows["suite"], rows["cell_id"], strict=True),
                       rows["config"] if "config" in rows else [None] * len(rows),
                       strict=True))
    labels = [cell_labels(configs.get(key)) for key in zip(cells["suite"], cells["cell_id"],
                                                       strict=True)]
    for column in ("labelled_frames", "labelled_by", "reference"):
        cells[column] = [entry[column] for entry in labels]
    cells["charged_frames"] = cells["steps_to_threshold"] + cells["labelled_frames"]
    return cells


def cell_labels(config: str | None) -> dict:
    """A cell's labelled frames (and how they were obtained) and its published reference,
    from the config its result file records."""
    parsed = json.loads(config) if isinstance(config, str) and config else {}
    labelled = parsed.get("labelled", {})
    return {"labelled_frames": int(labelled.get("frames", 0)),
            "labelled_by": labelled.get("by", ""), "reference": parsed.get("reference")}


def summarize(results: pd.DataFrame) -> pd.DataFrame:
    """Per env × method × variant, over finished seeds: for final return, frames to
    threshold and AUC, the IQM with its 95% bootstrap interval and the mean ± std; how many
    seeds finished and failed, and how many reached the threshold. Cells of another budget
    (an earlier version of the suite, read with ``include_stale``) make a row of their own:
    their seeds are other runs, their frames to threshold and AUC other scales."""
    cells = per_cell(results)
    rows = []
    keys = ["suite", "env", "method", "variant", "budget"]
    for (suite, env, method, variant, budget), group in cells.groupby(keys, sort=True):
        ok = group[group["status"] == "ok"]
        row = {
            "suite": suite, "env": env, "method": method, "variant": variant,
            "threshold": group["threshold"].iloc[0], "budget": int(budget),
            "seeds_ok": len(ok), "seeds_failed": int((group["status"] != "ok").sum()),
            "reached": int(ok["reached"].sum()),
            "initial_mean": _mean(ok["initial_return"]),
            "initial_std": _std(ok["initial_return"]),
            "labelled_frames": int(group["labelled_frames"].max()),
            "labelled_by": group["labelled_by"].iloc[0],
            **_control(ok, group["reference"].iloc[0]),
        }
        for prefix, (column, _) in METRICS.items():
            values = ok[column].to_numpy(dtype=float)
            low, high = stratified_ci([values]) if len(values) else (np.nan, np.nan)
            row.update({f"{prefix}_iqm": float(iqm(values)) if len(values) else np.nan,
                        f"{prefix}_low": low, f"{prefix}_high": high,
                        f"{prefix}_mean": _mean(ok[column]), f"{prefix}_std": _std(ok[column])})
        rows.append(row)
    return pd.DataFrame(rows)


def _control(ok: pd.DataFrame, reference: dict | None) -> dict:
    """A positive control's verdict, one-sided: it fails when the 95% interval of our
    seeds' final-return IQM lies wholly below the published value (the code path falls
    short of it by more than the seed spread), and passes otherwise — a learner that beats
    its reference has shown that it works."""
    if not reference:
        return {"reference": np.nan, "reference_spread": np.nan, "reference_source": "",
                "control": ""}
    finals = ok["final_return"].to_numpy(dtype=float)
    value = float(reference["value"])
    if not len(finals):
        verdict = "no finished seed"
    else:
        high = stratified_ci([finals])[1]
        high = finals.max() if np.isnan(high) else high  # one seed: no interval
        verdict = "pass" if value <= high else "fail"
    return {"reference": value, "reference_spread": float(reference.get("spread", 0.0)),
            "reference_source": reference.get("source", ""), "control": verdict}


def summary_table(summary: pd.DataFrame) -> pd.DataFrame:
    """``summarize``'s table as ``report --out`` writes it: ``label``, as the report prints
    it, first."""
    table = summary.copy()
    table.insert(0, "label", [label(m, v) for m, v in zip(table["method"], table["variant"],
                                                          strict=True)])
    return table


def _mean(values: pd.Series) -> float:
    return float(values.mean()) if len(values) else float("nan")


def _std(values: pd.Series) -> float:
    return float(values.std(ddof=0)) if len(values) else float("nan")


def returns_at(results: pd.DataFrame, frames: list[int]) -> pd.DataFrame:
    """Per env × method × variant and frame: the mean and std over finished seeds of each
    seed's evaluation return at that frame (its last evaluation at or before it; none for a
    frame before its first evaluation or past its last), and how many seeds had one."""
    rows = []
    for key, curves in _finished_curves(results):
        for frame in frames:
            values = np.array([_at(curve, frame) for curve in curves], dtype=float)
            values = values[~np.isnan(values)]
            rows.append(dict(zip(KEYS, key, strict=True), frame=frame, seeds=len(values),
                             mean=float(values.mean()) if len(values) else np.nan,
                             std=float(values.std()) if len(values) else np.nan))
    return pd.DataFrame(rows, columns=[*KEYS, "frame", "seeds", "mean", "std"])


KEYS = ["suite", "env", "method", "variant"]


def _finished_curves(results: pd.DataFrame):
    """(env × method × variant key, the evaluation curves of its finished cells), each
    curve sorted by frame."""
    ok_cells = results[(results["kind"] == "cell") & (results["status"] == "ok")]
    keep = set(zip(ok_cells["suite"], ok_cells["cell_id"], strict=True))
    evals = results[results["kind"] == "eval"].sort_values("step")
    for key, group in evals.groupby(KEYS, sort=True):
        yield key, [curve for (suite, cell_id), curve in group.groupby(["suite", "cell_id"])
                    if (suite, cell_id) in keep]


def _index_at(curve: pd.DataFrame, frame: int | None) -> int | None:
    """The position of a curve's last evaluation at or before ``frame`` (None: its last),
    or None for a frame before its first evaluation or past its last."""
    steps = curve["step"].to_numpy()
    if not len(steps) or (frame is not None and (frame < steps[0] or frame > steps[-1])):
        return None
    return len(steps) - 1 if frame is None else int(np.searchsorted(steps, frame, "right")) - 1


def _at(curve: pd.DataFrame, frame: int) -> float:
    index = _index_at(curve, frame)
    return float("nan") if index is None else float(curve["return"].to_numpy()[index])


def actions_at(results: pd.DataFrame, frames: list[int] | None = None) -> pd.DataFrame:
    """Per env × method × variant and frame (default: each cell's last evaluation), what the
    policy did: each finished seed's evaluation action stats at that frame (its last
    evaluation at or before it), averaged over those seeds — for discrete actions the share
    of each action, for continuous ones each dimension's mean and spread. A cell whose
    results predate action recording has none (``seeds`` counts the seeds that had them)."""
    columns = ["action_share", "action_mean", "action_std"]
    rows = []
    for key, curves in _finished_curves(results):
        for frame in frames or [None]:
            picked = [_row_at(curve, frame) for curve in curves]
            picked = [row for row in picked if row is not None]
            row = dict(zip(KEYS, key, strict=True), frame=frame, seeds=len(picked))
            for column in columns:
                vectors = [np.asarray(r[column], dtype=float) for r in picked
                           if r[column] is not None]
                same = vectors and len({len(v) for v in vectors}) == 1
                row[column] = np.mean(vectors, axis=0).tolist() if same else None
            rows.append(row)
    return pd.DataFrame(rows, columns=[*KEYS, "frame", "seeds", *columns])


def _row_at(curve: pd.DataFrame, frame: int | None) -> pd.Series | None:
    """A curve's evaluation row at ``frame`` (its last at or before it; None: the last),
    or None where it has none or the row recorded no actions."""
    index = _index_at(curve, frame)
    if index is None:
        return None
    row = curve.iloc[index]
    recorded = any(_present(row[c]) for c in ("action_share", "action_mean"))
    return row if recorded else None


def _present(value) -> bool:
    return value is not None and not (isinstance(value, float) and np.isnan(value))
