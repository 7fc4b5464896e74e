"""``senbench status``: how far a suite has got under a results root, and the cell time
left, estimated from the cells already finished."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from senbench.results.store import cell_path, cell_row, cells_dir
from senbench.run.claims import running_cells
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
    """Cells a run holds now (see :func:`senbench.run.claims.running_cells`): counted in
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


