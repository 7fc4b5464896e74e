"""Taking finished cells of other suites instead of running them again (``run --reuse``).

A cell's id is a hash of what it computes, not of its names (:mod:`senbench.suite.cell`), so
a cell of this suite that another suite's results folder already holds, finished, is found
by its id: ``<folder>/cells/<id>.parquet``. A sweep that contains a main suite's setting
(the d = 20% encoder of a d-sweep beside the paper suite, say) takes those cells from the
main suite's results rather than spend their hours again. The copy keeps every row and the
record of the run that computed it (times, host, commit, versions); only the labels (suite,
method, variant, threshold, hyperparams source, config) become this suite's. The cell's
encoder comes along into this results root's cache when the source lies under another root.
"""

from __future__ import annotations

import json
import shutil
from dataclasses import dataclass
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq

from senbench.errors import SenbenchError
from senbench.results.atomic import atomic_folder
from senbench.results.store import SCHEMA, readable_schema, write_table
from senbench.suite import Cell


@dataclass(frozen=True)
class Reused:
    cell: Cell
    source: Path
    final_eval: float | None
    git_commit: str | None
    senbench_version: str | None


def _finished_table(path: Path) -> pa.Table | None:
    """A cell file's table if it holds a finished cell of today's schema whose config has
    the id in its name (so a file of an older senbench, with ids of another scheme, never
    stands in for a cell it did not compute)."""
    try:
        if not readable_schema(pq.read_schema(path)):
            return None  # written by a senbench whose results had other columns
        table = pq.read_table(path, schema=SCHEMA)  # a column added since: null
    except (pa.ArrowInvalid, OSError):
        return None  # unreadable, or gone: not a finished cell
    for kind, status, config in zip(*(table[c].to_pylist() for c in
                                      ("kind", "status", "config")), strict=True):
        if kind == "cell":
            if status != "ok" or Cell.from_config(json.loads(config), "").id != path.stem:
                return None
            return table
    return None


def finished_cells(folders: list[Path], exclude: Path | None = None) -> dict[str, Path]:
    """The cell files under suite results folders, by cell id; the first folder that holds
    an id wins (whether it is finished is checked when it is taken). A folder that holds no
    suite's results is an error, before anything is written. ``exclude``: this suite's own
    cells folder."""
    found: dict[str, Path] = {}
    for folder in folders:
        cells = Path(folder) / "cells"
        if not cells.is_dir():
            raise SenbenchError(f"--reuse {folder}: not a suite's results folder (it has no "
                                "cells/ folder); name one that `senbench run` wrote, e.g. "
                                "results/paper-mountaincar")
        if exclude is not None and cells.resolve() == Path(exclude).resolve():
            continue
        for path in sorted(cells.glob("*.parquet")):
            found.setdefault(path.stem, path)
    return found


def copy_cell(cell: Cell, source: Path, directory: Path, encoder_cache: Path) -> Reused | None:
    """Write ``source``'s rows as ``cell``'s result file (atomically, as a run would), and
    its encoder into ``encoder_cache`` if missing there. None if ``source`` does not hold
    this cell, finished (failed, rewritten or removed since it was found)."""
    table = _finished_table(source) if source.stem == cell.id else None
    if table is None:
        return None
    first = table.slice(0, 1).to_pylist()[0]
    if first["encoder_id"]:
        _copy_encoder(source.parent.parent.parent / "encoders" / first["encoder_id"],
                      Path(encoder_cache) / first["encoder_id"])
    labels = {"suite": cell.suite, "method": cell.method, "variant": cell.variant,
              "config": json.dumps(cell.config(), sort_keys=True),
              "hyperparams_source": cell.hyperparams_source}
    for name, value in labels.items():
        index = table.schema.get_field_index(name)
        table = table.set_column(index, table.schema.field(index),
                                 pa.array([value] * len(table), pa.string()))
    index = table.schema.get_field_index("threshold")
    table = table.set_column(index, table.schema.field(index),
                             pa.array([cell.threshold] * len(table), pa.float64()))
    write_table(directory, cell.id, table)
    evals = [r for k, r in zip(table["kind"].to_pylist(), table["return"].to_pylist(),
                               strict=True) if k == "eval"]
    return Reused(cell, source, evals[-1] if evals else None, first["git_commit"],
                  first["senbench_version"])


def _copy_encoder(source: Path, target: Path) -> None:
    """Copy an encoder's folder into a cache that lacks it, whole or not at all."""
    if not source.is_dir() or source.resolve() == target.resolve():
        return
    with atomic_folder(target) as tmp:
        if tmp is not None:
            shutil.copytree(source, tmp, dirs_exist_ok=True)
