"""Rich progress for a grid: one bar for the grid, a live line per running cell (frames,
frames/s, latest evaluation return), and a line per finished cell that stays in the log."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

from rich.console import Console
from rich.markup import escape
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
)

from senbench.run.execute import CellOutcome
from senbench.run.summary import RunSummary

LOG_EVERY_S = 300.0
"""Without a terminal (a batch job's log), a running cell's line is printed this often."""


class GridProgress:
    """Shows progress on ``console``; with ``None`` it shows nothing (library use, tests).

    On a terminal the running cells' lines are live; into a file or pipe (a batch job's log,
    ``nohup``) live lines are not drawn, so each running cell prints a plain line every
    ``log_every_s`` seconds instead, and an hour-long cell does not leave the log silent."""

    def __init__(self, console: Console | None, log_every_s: float = LOG_EVERY_S,
                 clock: Callable[[], float] = time.monotonic):
        self.console = console
        self._progress: Progress | None = None
        self._grid = None
        self._cells: dict[str, int] = {}
        self._done: set[str] = set()
        self._labels: dict[str, tuple[str, int]] = {}
        self._logged: dict[str, float] = {}
        self._log_every_s = log_every_s
        self._clock = clock

    @contextmanager
    def grid(self, total: int, skipped: int) -> Iterator[None]:
        if self.console is None:
            yield
            return
        self._progress = Progress(
            TextColumn("{task.description}"),
            BarColumn(),
            MofNCompleteColumn(),
            TextColumn("{task.fields[rate]}"),
            TextColumn("{task.fields[last_eval]}"),
            TimeElapsedColumn(),
            console=self.console,
        )
        if skipped:
            self.console.print(f"resuming: {skipped} of {total} cells already finished")
        self._grid = self._progress.add_task("grid", total=total, completed=skipped, rate="",
                                             last_eval="")
        with self._progress:
            yield
        self._progress = None

    def log(self, message: str) -> None:
        if self.console is not None:
            self.console.print(message, highlight=False)

    def warn(self, message: str) -> None:
        if self.console is not None:
            self.console.print(f"[yellow]warning:[/] {message}", highlight=False)

    def started(self, cell_id: str, label: str, budget: int) -> None:
        if self._progress is None or cell_id in self._done or cell_id in self._cells:
            return
        self._cells[cell_id] = self._progress.add_task(f"  {escape(label)}", total=budget, rate="",
                                                       last_eval="")
        self._labels[cell_id] = (label, budget)
        self._logged[cell_id] = self._clock()

    def update(self, cell_id: str, steps: int, rate: float, last_eval: float | None,
               eval_step: int | None = None, train_return: float | None = None) -> None:
        task = self._cells.get(cell_id)
        if self._progress is None or task is None:
            return
        shown = "" if last_eval is None else f"eval {last_eval:.1f}"
        self._progress.update(task, completed=steps, rate=f"{rate:,.0f} frames/s",
                              last_eval=shown)
        now = self._clock()
        if not self._progress.console.is_terminal and \
                now - self._logged.get(cell_id, now) >= self._log_every_s:
            self._logged[cell_id] = now
            label, budget = self._labels[cell_id]
            self._progress.console.print(
                f"  {escape(label)}: {steps:,} of {budget:,} frames, {rate:,.0f} frames/s"
                + (f", {shown}" if shown else ""), highlight=False)

    def copied(self, label: str, source: Path, final_eval: float | None) -> None:
        """A cell copied from another suite's results (``run --reuse``), not run."""
        if self._progress is None:
            return
        self._progress.advance(self._grid)
        final = "" if final_eval is None else f", final eval {final_eval:.1f}"
        self._progress.console.print(f"[cyan]copied[/] {escape(label)}{final} from "
                                     f"{escape(str(source))}", highlight=False)

    def passed_over(self, label: str) -> None:
        """A cell left to another run of the suite, which holds it or has written it."""
        if self._progress is None:
            return
        self._progress.advance(self._grid)
        self._progress.console.print(f"[cyan]elsewhere[/] {escape(label)}: another run of this "
                                     "suite holds it or has written it", highlight=False)

    def finished(self, outcome: CellOutcome) -> None:
        self._done.add(outcome.cell_id)
        self._labels.pop(outcome.cell_id, None)
        self._logged.pop(outcome.cell_id, None)
        if self._progress is None:
            return
        task = self._cells.pop(outcome.cell_id, None)
        if task is not None:
            self._progress.remove_task(task)
        self._progress.advance(self._grid)
        if outcome.status == "ok":
            final = "" if outcome.final_eval is None else f", final eval {outcome.final_eval:.1f}"
            self._progress.console.print(
                f"[green]done[/] {escape(outcome.label)}{final} ({outcome.wall_s:.1f} s)")
        else:
            first_line = (outcome.error or "").strip().splitlines()[-1:] or [""]
            self._progress.console.print(
                f"[red]failed[/] {escape(outcome.label)}: {escape(first_line[0])}",
                highlight=False)


def print_summary(summary: RunSummary, suite_name: str, folder: Path, suite_cells: int,
                  time_limit: str | None, out: Console, err: Console) -> None:
    """What a run did, on ``out``; its failures and what is left to do, on ``err``."""
    picked = f" (picked from {suite_cells})" if summary.total < suite_cells else ""
    out.print(
        f"suite '{suite_name}': {summary.ok} finished, {len(summary.failed)} failed, "
        f"{summary.skipped} already done, "
        + (f"{summary.reused} copied from --reuse, " if summary.reused else "")
        + f"of {summary.total} cells{picked} → {folder}"
    )
    for outcome in summary.failed:
        last = (outcome.error or "").strip().splitlines()[-1:] or [""]
        err.print(f"[red]failed[/] {escape(outcome.label)} ({outcome.cell_id}): "
                  f"{escape(last[0])}", highlight=False)
    if summary.interrupted:
        left = summary.total - summary.skipped - summary.reused - len(summary.outcomes)
        err.print(f"interrupted: {left} cells not run; run the same command again to resume")
        return
    if summary.elsewhere:
        err.print(f"{len(summary.elsewhere)} cells were left to another run of this suite"
                  + (f"; {summary.elsewhere_running} are still running there"
                     if summary.elsewhere_running else "")
                  + (f"; {summary.elsewhere_unfinished} did not finish there (failed, or "
                     "that run was stopped): run the same command again to run them"
                     if summary.elsewhere_unfinished else ""))
    if summary.not_started:
        err.print(f"time limit {time_limit}: {summary.not_started} cells not started (the "
                  "limit was reached, or no waiting cell was expected to end within it at the "
                  "mean of the finished cells of its env, method and variant); run the same "
                  "command again to go on")
