"""Copying finished cells of other suites instead of running them again (``run --reuse``).

Two cells whose resolved configs agree in everything but the labels ``method`` and
``variant`` compute the same curve: the runner seeds everything from the config, and the
same suite and seed give the same curves on CPU. A sweep that contains a main suite's
setting (the d = 20% encoder of a d-sweep beside the paper suite, say) can then copy those
cells from the main suite's results rather than spend their hours again. The copy keeps
every row and the record of the run that computed it (times, host, commit, versions); only
the cell's identity (id, suite, method, variant, config, hyperparams source) becomes this
suite's.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq

from senbench.errors import SenbenchError
from senbench.results import SCHEMA, write_table
from senbench.suite import Cell

LABELS = ("method", "variant")
"""Config keys that name a cell without changing its curve."""


def curve_key(config: dict[str, Any]) -> str:
    """The config without its labels: equal keys, equal curves."""
    return json.dumps({k: v for k, v in config.items() if k not in LABELS}, sort_keys=True,
                      separators=(",", ":"))


@dataclass(frozen=True)
class Reused:
    cell: Cell
    source: Path
    final_eval: float | None


def finished_cells(folders: list[Path]) -> dict[str, Path]:
    """The finished (``ok``) cell files under suite results folders, by curve key. A folder
    that holds no suite's results is an error, before anything is written."""
    found: dict[str, Path] = {}
    for folder in folders:
        cells = Path(folder) / "cells"
        if not cells.is_dir():
            raise SenbenchError(f"--reuse {folder}: not a suite's results folder (it has no "
                                "cells/ folder); name one that `senbench run` wrote, e.g. "
                                "results/paper-mountaincar")
        for path in sorted(cells.glob("*.parquet")):
            try:
                if not pq.read_schema(path).equals(SCHEMA):
                    continue  # written by a senbench whose results had other columns
                table = pq.read_table(path, columns=["kind", "status", "config"])
            except (pa.ArrowInvalid, OSError):
                continue  # unreadable: not a finished cell
            for kind, status, config in zip(*(table[c].to_pylist() for c in
                                              ("kind", "status", "config")), strict=True):
                if kind == "cell" and status == "ok":
                    found.setdefault(curve_key(json.loads(config)), path)
    return found


def copy_cell(cell: Cell, source: Path, directory: Path) -> Reused:
    """Write ``source``'s rows as ``cell``'s result file (atomically, as a run would)."""
    table = pq.read_table(source)
    identity = {"cell_id": cell.id, "suite": cell.suite, "method": cell.method,
                "variant": cell.variant, "config": json.dumps(cell.config, sort_keys=True),
                "hyperparams_source": cell.hyperparams_source}
    for name, value in identity.items():
        index = table.schema.get_field_index(name)
        table = table.set_column(index, table.schema.field(index),
                                 pa.array([value] * len(table), pa.string()))
    write_table(directory, cell.id, table)
    evals = [r for k, r in zip(table["kind"].to_pylist(), table["return"].to_pylist(),
                               strict=True) if k == "eval"]
    return Reused(cell, source, evals[-1] if evals else None)


def reuse_cells(todo: list[Cell], directory: Path, found: dict[str, Path]
                ) -> tuple[list[Cell], list[Reused]]:
    """Copy into ``directory`` every cell of ``todo`` that ``found`` (from
    :func:`finished_cells`) holds; the cells still to run, and those copied."""
    left, reused = [], []
    for cell in todo:
        source = found.get(curve_key(cell.config))
        if source is None or source.parent.resolve() == directory.resolve():
            left.append(cell)
        else:
            reused.append(copy_cell(cell, source, directory))
    return left, reused
