"""Which waiting cell starts next: in the suite's order, or, under a time limit, the first
that is expected to finish before it (``run --time-limit``); with claims, never one that
another run of the suite holds (see :mod:`senbench.run.claims`).

A cell's expected time is the mean wall time of the finished cells of its env, method and
variant: those already in the results folder, and those that finish during the run, in this
run or in another run of the suite (its cells are passed over, but their times count, also
when the other run was still computing them as this run came to them). A cell
of a combination with none finished yet has no expected time: it starts while time is left,
but only one cell of that combination at a time, until one finishes and gives the time (so
eight workers do not start eight hour-long cells of an unknown method at the deadline's
edge). A cell that would not fit is passed over for a later, shorter one (say SEN-SARSA's
minutes after DQN's hour), so the time left is used rather than lost to a cell cut off at
the end. The time counts from the run's start, state encoders' training included.
"""

from __future__ import annotations

import re
import time
from collections import Counter, deque
from collections.abc import Callable
from pathlib import Path

from senbench.errors import SenbenchError
from senbench.results.store import cell_path, cell_row, finished_status
from senbench.run.claims import CellClaims
from senbench.run.status import suite_status
from senbench.suite import Cell, Suite

MARGIN = 1.1
"""A cell starts if its expected time, times this, fits in the time left."""

_UNITS = {"h": 3600, "m": 60, "s": 1}


def parse_duration(text: str) -> float:
    """Seconds in ``2h30m``, ``150m``, ``90s`` or ``1h``; an error that shows the form."""
    parts = re.fullmatch(r"\s*(?:(\d+(?:\.\d+)?)h)?\s*(?:(\d+(?:\.\d+)?)m)?\s*"
                         r"(?:(\d+(?:\.\d+)?)s)?\s*", text)
    if not text.strip() or parts is None or not any(parts.groups()):
        raise SenbenchError(f"--time-limit {text!r}: write it as 2h30m, 150m or 90s")
    seconds = sum(float(v) * u for v, u in zip(parts.groups(), _UNITS.values(), strict=True)
                  if v)
    if seconds <= 0:
        raise SenbenchError(f"--time-limit {text!r}: must be more than 0")
    return seconds


def _key(cell: Cell) -> tuple[str, str, str]:
    return cell.env, cell.method, cell.variant


class Schedule:
    """The waiting cells; ``next`` hands out the one to start, or None."""

    def __init__(self, todo: list[Cell], limit_s: float | None = None,
                 suite: Suite | None = None, results_root: str | Path | None = None,
                 claims: CellClaims | None = None,
                 passed_over: Callable[[Cell], None] = lambda cell: None):
        self.waiting = deque(todo)
        self.claims = claims
        self._passed_over = passed_over
        self.elsewhere: list[str] = []
        """Cells passed over: another run holds them, or wrote them since this run began."""
        self.limit_s = limit_s
        self.deadline = None if limit_s is None else time.monotonic() + limit_s
        self._walls: dict[tuple[str, str, str], tuple[float, int]] = {}
        """Per combination: the finished cells' total wall seconds, and their count."""
        self._running: Counter[tuple[str, str, str]] = Counter()
        if limit_s is not None and suite is not None and results_root is not None:
            for combo in suite_status(suite, results_root):
                if combo.ok:
                    self._walls[(combo.env, combo.method, combo.variant)] = (combo.ok_wall_s,
                                                                             combo.ok)
        self._counted = set() if claims is None or limit_s is None else {
            c.id for c in todo if finished_status(cell_path(claims.directory, c.id)) == "ok"}
        """Waiting cells another run finished after ``todo`` was made: ``_walls`` holds
        their times."""
        self._held: dict[str, tuple[Cell, int | None]] = {}
        """Cells passed over while another run held them, with their file's mtime (ns) when
        last looked at: each counts its time once its file records ``ok``."""

    def expected_s(self, cell: Cell) -> float | None:
        total, count = self._walls.get(_key(cell), (0.0, 0))
        return total / count if count else None

    def left_s(self) -> float:
        return float("inf") if self.deadline is None else self.deadline - time.monotonic()

    def next(self) -> Cell | None:
        """The cell to start now, locked for this run if the schedule has ``claims``."""
        self._look_at_held()
        while (cell := self._pick()) is not None:
            if self.claims is None or self.claims.take(cell.id):
                self._running[_key(cell)] += 1
                return cell
            self.elsewhere.append(cell.id)
            if self.deadline is not None and not self._learn_from_elsewhere(cell):
                self._held[cell.id] = (cell, self._mtime(cell))
            self._passed_over(cell)
        return None

    def next_batch(self) -> list[Cell]:
        """The cells to start now in one process: the next cell, and, if it runs in a seed
        batch, waiting seeds of its batch key up to the batch's size (empty: none to
        start). The seeds of a batch finish together and each records the batch's wall time,
        so the next cell's fit under a time limit is theirs. An estimate made only from a
        partial batch (fewer seeds, padded) is low for a full one."""
        first = self.next()
        if first is None:
            return []
        batch = [first]
        for cell in list(self.waiting):
            if len(batch) == first.seed_batch:
                break
            if cell.batch_key != first.batch_key:
                continue
            if self.claims is None or self.claims.take(cell.id):
                self.waiting.remove(cell)
                self._running[_key(cell)] += 1
                batch.append(cell)
        return batch

    def _mtime(self, cell: Cell) -> int | None:
        try:
            return cell_path(self.claims.directory, cell.id).stat().st_mtime_ns
        except FileNotFoundError:
            return None

    def _look_at_held(self) -> None:
        """Learn from the held cells whose files changed since last looked at: one stat
        each, a file read only on a change (a cell the other run failed is read once)."""
        if not self._held or not self.waiting or self.deadline is None:
            return
        for cell_id, (cell, seen) in list(self._held.items()):
            stamp = self._mtime(cell)
            if stamp == seen:
                continue
            if self._learn_from_elsewhere(cell):
                del self._held[cell_id]
            else:
                self._held[cell_id] = (cell, stamp)

    def _learn_from_elsewhere(self, cell: Cell) -> bool:
        """A cell another run finished gives its combination's time, as one of this run's
        would: so that a run under a time limit does not start a cell of a combination only
        another run has timed as if it had no time. False while the cell is not finished
        there (still held: ``next`` looks again when its file changes)."""
        if not self.claims.finished_elsewhere(cell.id):
            return False
        if cell.id not in self._counted:
            self._counted.add(cell.id)
            row = cell_row(cell_path(self.claims.directory, cell.id), ["status", "cell_wall_s"])
            if row and row["status"] == "ok" and row["cell_wall_s"]:
                self._add_wall(cell, row["cell_wall_s"])
        return True

    def _add_wall(self, cell: Cell, wall_s: float) -> None:
        total, count = self._walls.get(_key(cell), (0.0, 0))
        self._walls[_key(cell)] = (total + wall_s, count + 1)

    def _pick(self) -> Cell | None:
        if self.deadline is None:
            return self.waiting.popleft() if self.waiting else None
        left = self.left_s()
        if left <= 0:
            return None
        for cell in self.waiting:
            expected = self.expected_s(cell)
            if expected is None and self._running[_key(cell)]:
                continue  # one cell of an unknown combination at a time
            if expected is None or expected * MARGIN <= left:
                self.waiting.remove(cell)
                return cell
        return None

    def finished(self, cell: Cell, status: str, wall_s: float) -> None:
        """Call once the cell's file is written: its lock is let go here."""
        self._running[_key(cell)] -= 1
        if self.claims is not None:
            self.claims.release(cell.id)
        if status == "ok":
            self._add_wall(cell, wall_s)
