"""Checking that committed results still reproduce: run the first frames of finished cells
again with the code installed now and compare their curves row for row.

A cell's curve is a function of its id (what it computes) and the code; the code is named
by the ``git_commit`` column, but a long run spans commits, and a run from a working tree
with uncommitted changes (``-dirty``) names no code at all. ``senbench verify`` answers the
question a reader of committed results asks: does today's code give this curve? It runs
each cell's first ``frames`` frames (its schedules still span its budget, so the prefix is
the one the full run had) and compares every training episode and evaluation that ends
before the last of them: frame, return, length and the evaluation's spread, exactly.
A difference says which processors the two ran on: the math libraries' kernels, chosen per
processor, round differently, and a learner grows that into another curve.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd

from senbench.errors import SenbenchError
from senbench.results.store import cell_path, finished_status
from senbench.run.batch import execute_cells
from senbench.run.execute import RunInfo
from senbench.run.processes import set_threads
from senbench.run.provenance import cpu_description
from senbench.suite.cell import Cell

COMPARED = ("kind", "step", "return", "length", "return_std")
"""The columns of a curve row that must be equal (an episode's ``return_std`` is null)."""


@dataclass(frozen=True)
class Verdict:
    cell: Cell
    outcome: str
    """``same``, ``different``, ``failed`` (the rerun raised) or ``not run`` (no finished
    result to compare with)."""
    frames: int
    """Frames run again."""
    compared: int
    """Rows (episodes and evaluations) compared."""
    detail: str
    """The first difference, the rerun's error, or empty."""
    git_commit: str | None = None
    """The code the committed cell names."""


def verify_cells(cells: list[Cell], directory: Path, frames: int, info: RunInfo,
                 done=lambda verdict: None) -> list[Verdict]:
    """Run the first ``frames`` frames of each of ``cells`` that ``directory`` (a suite's
    ``cells`` folder) holds finished, one after another, and compare them with it."""
    if frames < 1:
        raise SenbenchError(f"--frames {frames}: run at least one frame again")
    verdicts = []
    for cell in cells:
        verdict = verify_cell(cell, directory, frames, info)
        done(verdict)
        verdicts.append(verdict)
    return verdicts


def verify_cell(cell: Cell, directory: Path, frames: int, info: RunInfo) -> Verdict:
    path = cell_path(directory, cell.id)
    status = finished_status(path)
    if status != "ok":
        why = "no result file" if status is None else f"its committed run {status}"
        return Verdict(cell, "not run", 0, 0, why)
    committed = pd.read_parquet(path)
    frames = min(frames, cell.budget)
    set_threads(cell.threads)
    [(rows, outcome)] = execute_cells([cell], info, stop_at=frames)
    commit = committed["git_commit"].iloc[0]
    if outcome.status != "ok":
        return Verdict(cell, "failed", frames, 0, outcome.error or "", commit)
    ran = max((r["step"] for r in rows if r["kind"] == "cell"), default=0)
    mine = _curve(pd.DataFrame(rows), ran)
    theirs = _curve(committed, ran)
    difference = first_difference(mine, theirs)
    if difference is not None:
        difference += _processors(committed, cpu_description())
    return Verdict(cell, "same" if difference is None else "different", frames,
                   min(len(mine), len(theirs)), difference or "", commit)


def committed_cpu(committed: pd.DataFrame) -> str | None:
    """The processor a result file's cell ran on; None where the file predates the
    column."""
    then = committed["cpu"].iloc[0] if "cpu" in committed.columns else None
    return None if then is None or (isinstance(then, float) and math.isnan(then)) else then


def _processors(committed: pd.DataFrame, now: str | None) -> str:
    """Whether the committed cell ran on another processor, whose math kernels may round
    differently (see senbench.run.provenance.cpu_description)."""
    then = committed_cpu(committed)
    if then is None:
        return "; the committed run's processor is not recorded"
    return "" if then == now else f"; committed on {then}, now on {now}"


def _curve(table: pd.DataFrame, before: int) -> list[tuple[Any, ...]]:
    """The episode and evaluation rows that end before frame ``before``, in order."""
    rows = table[table["kind"].isin(("episode", "eval")) & (table["step"] < before)]
    return [tuple(_plain(v) for v in row) for row in rows[list(COMPARED)].itertuples(index=False)]


def _plain(value: Any) -> Any:
    if isinstance(value, float) and math.isnan(value):
        return None  # a null read back from Parquet
    return value.item() if hasattr(value, "item") else value


def first_difference(mine: list[tuple], theirs: list[tuple]) -> str | None:
    """Where the rerun's rows first part from the committed ones, said in words; None when
    they are the same."""
    for index, (a, b) in enumerate(zip(mine, theirs, strict=False)):
        if a != b:
            return (f"{a[0]} ending at frame {b[1]:,}: committed return {b[2]}, length "
                    f"{b[3]}; now {a[0]} ending at frame {a[1]:,}, return {a[2]}, length "
                    f"{a[3]} (row {index + 1})")
    if len(mine) != len(theirs):
        more, fewer = ("now", "committed") if len(mine) > len(theirs) else ("committed", "now")
        return (f"{more} has {abs(len(mine) - len(theirs))} more rows in the same frames "
                f"than {fewer} ({len(mine)} now, {len(theirs)} committed)")
    return None
