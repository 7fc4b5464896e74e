"""``senbench compare A B``: one method against another, per env and metric, with the
probability that a run of A does better than a run of B.

A and B are either two methods of one results folder (``--results DIR``; a variant is
named as the report prints it, ``sen-sarsa [encoder.fraction=0.2]``), or two results
folders, whose methods are then paired by name (or, where each folder holds one method
for an env, those two are paired).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from senbench.analysis.stats import (
    censored_improvement,
    censored_improvement_ci,
    improvement_ci,
    iqm,
    probability_of_improvement,
    stratified_ci,
)
from senbench.analysis.summary import METRICS, label, per_cell, with_thresholds
from senbench.errors import ResultsError
from senbench.results.store import read_results

LABELS = {"final": "final return", "steps": "frames to threshold", "auc": "AUC",
          "charged": "frames to threshold + labelled frames"}


@dataclass(frozen=True)
class Side:
    name: str
    """How the table names this side: a method label, or folder: label."""
    cells: pd.DataFrame
    """Finished cells of one method (per_cell rows)."""
    failed: int = 0
    """Its failed cells, left out of every statistic (the table says how many)."""


def _finished_cells(results: pd.DataFrame, folder: Path) -> pd.DataFrame:
    """Finished cells of one suite, labelled; a folder holding several suites, or several
    versions of one method and seed (``--all``), cannot be compared seed for seed."""
    cells = per_cell(results)
    suites = sorted(set(cells["suite"]))
    if len(suites) > 1:
        raise ResultsError(f"{folder} holds several suites ({', '.join(suites)}); name one "
                           "suite's folder, e.g. results/<suite>")
    cells["label"] = [label(m, v) for m, v in zip(cells["method"], cells["variant"], strict=True)]
    failed = cells[cells["status"] != "ok"].groupby(["env", "label"]).size().to_dict()
    cells = cells[cells["status"] == "ok"].copy()
    cells.attrs["failed"] = failed
    if cells.duplicated(["env", "label", "seed"]).any():
        raise ResultsError(f"{folder}: cells of several versions of the suite share a method "
                           "and seed; compare without --all")
    return cells


def pairs_in_one_folder(folder: Path, a: str, b: str, include_stale: bool = False,
                        thresholds: dict | None = None) -> list[tuple[str, Side, Side]]:
    cells = _finished_cells(with_thresholds(read_results(folder, include_stale=include_stale),
                                      thresholds or {}), folder)
    known = sorted(set(cells["label"]))
    for name in (a, b):
        if name not in known:
            raise ResultsError(f"no finished cells of method '{name}' in {folder}; it has: "
                             f"{', '.join(known) or 'none'}")
    pairs, failed = [], cells.attrs["failed"]
    for env, group in cells.groupby("env", sort=True):
        if {a, b} <= set(group["label"]):
            pairs.append((env, Side(a, group[group["label"] == a], failed.get((env, a), 0)),
                          Side(b, group[group["label"] == b], failed.get((env, b), 0))))
    if not pairs:
        raise ResultsError(f"'{a}' and '{b}' never ran on the same env in {folder}")
    return pairs


def pairs_across_folders(a: Path, b: Path, include_stale: bool = False,
                         thresholds: dict | None = None) -> list[tuple[str, Side, Side]]:
    left, right = (read_results(f, include_stale=include_stale) for f in (a, b))
    envs = set(left["env"]) | set(right["env"])
    left = _finished_cells(with_thresholds(left, thresholds or {}, envs), a)
    right = _finished_cells(with_thresholds(right, thresholds or {}, envs), b)
    pairs = []
    for env in sorted(set(left["env"]) & set(right["env"])):
        lg, rg = left[left["env"] == env], right[right["env"] == env]
        common = sorted(set(lg["label"]) & set(rg["label"]))
        if not common and lg["label"].nunique() == 1 and rg["label"].nunique() == 1:
            common = [(lg["label"].iloc[0], rg["label"].iloc[0])]
        else:
            common = [(name, name) for name in common]
        for la, lb in common:
            left_budget = int(lg[lg["label"] == la]["budget"].max())
            right_budget = int(rg[rg["label"] == lb]["budget"].max())
            if left_budget != right_budget:
                raise ResultsError(f"{env}: {a} ran {la} for {left_budget:,} frames, {b} ran "
                                   f"{lb} for {right_budget:,}: frames to threshold and AUC "
                                   "are only comparable at one budget")
            pairs.append((env, Side(f"{a.name}: {la}", lg[lg["label"] == la],
                                    left.attrs["failed"].get((env, la), 0)),
                          Side(f"{b.name}: {lb}", rg[rg["label"] == lb],
                               right.attrs["failed"].get((env, lb), 0))))
    if not pairs:
        raise ResultsError(f"{a} and {b} share no env and method to compare; name two methods "
                         "of one folder instead: senbench compare A B --results DIR")
    return pairs


def compare(a: Side, b: Side) -> pd.DataFrame:
    """Per metric: IQM [CI] of each side and P(A better than B) [CI]; for frames to
    threshold fewer is better (unreached seeds count as the budget)."""
    rows = []
    charged = bool(a.cells["labelled_frames"].any() or b.cells["labelled_frames"].any())
    for prefix, (column, higher_is_better) in METRICS.items():
        if prefix == "charged" and not charged:
            continue  # the same as frames to threshold when neither used labelled frames
        x, y = (side.cells[column].to_numpy(dtype=float) for side in (a, b))
        if prefix == "charged":
            # a seed that never got there needs at least budget + labelled frames: pairs
            # whose order that hides count half. (Frames to threshold alone needs no such
            # care: there every such seed is the budget, and equal values tie anyway.)
            unreached = [~side.cells["reached"].to_numpy(dtype=bool) for side in (a, b)]
            p_better = censored_improvement(x, unreached[0], y, unreached[1])
            low, high = censored_improvement_ci(x, unreached[0], y, unreached[1])
        else:
            sign = 1.0 if higher_is_better else -1.0
            p_better = probability_of_improvement(sign * x, sign * y)
            low, high = improvement_ci(sign * x, sign * y)
        rows.append({
            "metric": prefix, "a_iqm": float(iqm(x)), "a_ci": stratified_ci([x]),
            "b_iqm": float(iqm(y)), "b_ci": stratified_ci([y]),
            "p_better": p_better,
            "p_low": low, "p_high": high, "a_seeds": len(x), "b_seeds": len(y),
        })
    return pd.DataFrame(rows)


def comparison_table(pairs: list[tuple[str, Side, Side]]) -> pd.DataFrame:
    """``compare``'s numbers for every env as one table, as ``compare --out`` writes it: a
    row per env and metric, each CI as two columns."""
    frames = []
    for env, a, b in pairs:
        table = compare(a, b)
        for side in ("a", "b"):
            table[[f"{side}_low", f"{side}_high"]] = table.pop(f"{side}_ci").tolist()
        frames.append(table.assign(env=env, a=a.name, b=b.name))
    table = pd.concat(frames, ignore_index=True)
    first = ["env", "a", "b", "metric"]
    return table[first + [c for c in table.columns if c not in first]]


def pairs_for(a: str, b: str, results: Path | None, include_stale: bool,
              thresholds: dict[str | None, float]) -> list[tuple[str, Side, Side]]:
    """What ``senbench compare A B`` compares: two methods of ``results``, or two folders."""
    if a == b and (results is not None or Path(a).is_dir()):
        raise ResultsError(f"A and B are both {a}: compare two methods, or two folders")
    if results is not None:
        return pairs_in_one_folder(results, a, b, include_stale=include_stale,
                                   thresholds=thresholds)
    if Path(a).is_dir() and Path(b).is_dir():
        return pairs_across_folders(Path(a), Path(b), include_stale=include_stale,
                                    thresholds=thresholds)
    absent = [x for x in (a, b) if "/" in x and not Path(x).exists()]
    said = f"no folder {', '.join(absent)}; " if absent else ""
    raise ResultsError(f"{said}name two results folders, or two methods and the folder that "
                       "holds them: senbench compare sen-sarsa sarsa-state --results "
                       "results/paper-mountaincar")


