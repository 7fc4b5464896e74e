"""``senbench status``: how far a suite has got under a results root, and the cell time
left, estimated from the cells already finished."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from rich.console import Console
from rich.markup import escape
from rich.table import Table

from senbench.claims import running_cells
from senbench.report import label
from senbench.results import cell_path, cell_row, cells_dir
from senbench.suite import Suite


@dataclass
class Combination:
    """One env × method × variant of a suite, over its seeds."""

    env: str
    method: str
    variant: str
    cells: int = 0
    ok: int = 0
    failed: int = 0
    running: int = 0
    """Cells a run holds now (see :func:`senbench.claims.running_cells`): counted in
    ``to_run`` too, or in ``ok`` when ``--force`` redoes a finished cell."""
    ok_wall_s: float = 0.0

    @property
    def to_run(self) -> int:
        return self.cells - self.ok

    @property
    def mean_wall_s(self) -> float | None:
        return self.ok_wall_s / self.ok if self.ok else None

    @property
    def left_s(self) -> float | None:
        """Cell time the cells still to run need, at the mean of those finished."""
        if not self.to_run:
            return 0.0
        return None if self.mean_wall_s is None else self.to_run * self.mean_wall_s


def suite_status(suite: Suite, results_root: str | Path) -> list[Combination]:
    """Per combination, in the suite's order: its cells, how many finished, failed (a
    failed cell runs again) or are running, and the finished cells' wall time."""
    directory = cells_dir(results_root, suite.name)
    running = running_cells(directory) if directory.is_dir() else set()
    combos: dict[tuple[str, str, str], Combination] = {}
    for cell in suite.cells:
        key = (cell.env, cell.method, cell.variant)
        combo = combos.setdefault(key, Combination(*key))
        combo.cells += 1
        combo.running += cell.id in running
        row = cell_row(cell_path(directory, cell.id), ["status", "cell_wall_s"])
        if row is None:
            continue
        if row["status"] == "ok":
            combo.ok += 1
            combo.ok_wall_s += row["cell_wall_s"] or 0.0
        else:
            combo.failed += 1
    return list(combos.values())


def duration(seconds: float) -> str:
    if seconds < 59.5:
        return f"{seconds:.0f} s"
    minutes = round(seconds / 60)
    return f"{minutes // 60} h {minutes % 60:02d} min" if minutes >= 60 else f"{minutes} min"


def render(combos: list[Combination], title: str, workers: int, console: Console) -> None:
    """The table of ``combos`` and a line with the cells and the cell time left."""
    table = Table(title=title)
    for name in ("env", "method", "cells", "finished", "failed", "to run", "running",
                 "mean cell", "cell time left"):
        table.add_column(name, justify="left" if name in ("env", "method") else "right")
    for c in combos:
        mean, left = c.mean_wall_s, c.left_s
        table.add_row(escape(c.env), escape(label(c.method, c.variant)),
                      str(c.cells), str(c.ok), str(c.failed) if c.failed else "",
                      str(c.to_run) if c.to_run else "", str(c.running) if c.running else "",
                      "" if mean is None else duration(mean),
                      "?" if left is None else ("" if not left else duration(left)))
    console.print(table)
    known = sum(c.left_s for c in combos if c.left_s is not None)
    unknown = sum(c.to_run for c in combos if c.left_s is None)
    finished = sum(c.ok for c in combos)
    total = sum(c.cells for c in combos)
    line = f"{finished} of {total} cells finished"
    if finished < total:
        if known or not unknown:
            line += f"; cell time left ≈ {duration(known)}"
            if workers > 1:
                line += f" (≈ {duration(known / workers)} on {workers} workers)"
            if unknown:
                line += f", plus {unknown} cells"
        else:
            line += f"; {unknown} cells left"
        if unknown:
            line += " of methods with none finished yet (their time is not known)"
        line += ". Running cells count as to run"
    console.print(line + ".")
