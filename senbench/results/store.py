"""Results: one tidy Parquet file per cell, written atomically, read back by glob.

A file ``<results>/<suite>/cells/<cell_id>.parquet`` holds one row per evaluation point
(``kind = "eval"``), one per training episode (``"episode"``) and exactly one summary row
(``"cell"``). Every row carries the cell's identity and metadata as plain columns, so
``SELECT * FROM 'results/quickstart/cells/*.parquet'`` needs no senbench import.
A file is written to a hidden temp name and renamed into place: a killed run leaves either
the whole file or none, and readers never see a temp file (it does not end in .parquet).
"""

from __future__ import annotations

import json
import os
import re
import socket
from pathlib import Path
from typing import Any

import pandas as pd
import psutil
import pyarrow as pa
import pyarrow.parquet as pq

from senbench.errors import ResultsError
from senbench.results.atomic import atomic_file

SCHEMA = pa.schema(
    [
        ("cell_id", pa.string()),
        ("suite", pa.string()),
        ("env", pa.string()),
        ("method", pa.string()),
        ("variant", pa.string()),
        ("agent", pa.string()),
        ("observation", pa.string()),
        ("seed", pa.int64()),
        ("kind", pa.string()),
        ("step", pa.int64()),
        ("return", pa.float64()),
        ("return_std", pa.float64()),
        ("length", pa.float64()),
        ("wall_s", pa.float64()),
        ("threshold", pa.float64()),
        ("budget", pa.int64()),
        ("status", pa.string()),
        ("error", pa.string()),
        ("config", pa.string()),
        ("hyperparams_source", pa.string()),
        ("encoder_id", pa.string()),
        ("senbench_version", pa.string()),
        ("torch_version", pa.string()),
        ("gymnasium_version", pa.string()),
        ("sb3_version", pa.string()),
        ("numpy_version", pa.string()),
        ("git_commit", pa.string()),
        ("host", pa.string()),
        ("threads", pa.int64()),
        ("started_at", pa.timestamp("us", tz="UTC")),
        ("ended_at", pa.timestamp("us", tz="UTC")),
        ("cell_wall_s", pa.float64()),
        ("peak_rss_mb", pa.float64()),
        # evaluation rows: what the policy did (senbench.run.evaluation); null elsewhere
        ("action_share", pa.list_(pa.float64())),
        ("action_mean", pa.list_(pa.float64())),
        ("action_std", pa.list_(pa.float64())),
        # seeds that shared the cell's encoder passes (senbench.run.batch); null: alone,
        # in results written before the option
        ("seed_batch", pa.int64()),
        # the processor (senbench.run.provenance.cpu_description); null in older results
        ("cpu", pa.string()),
    ]
)


def readable_schema(schema: pa.Schema) -> bool:
    """Whether a file of this schema reads as :data:`SCHEMA`: each of its columns is one of
    SCHEMA's, of the same type. A column added since (``seed_batch``, ``cpu``) reads as null."""
    fields = {field.name: field.type for field in SCHEMA}
    return all(fields.get(field.name) == field.type for field in schema)


def cells_dir(results_root: str | Path, suite_name: str) -> Path:
    return Path(results_root) / suite_name / "cells"


def cell_path(directory: Path, cell_id: str) -> Path:
    return directory / f"{cell_id}.parquet"


def write_cell(directory: Path, cell_id: str, rows: list[dict[str, Any]]) -> Path:
    """Write a cell's rows atomically: temp file, fsync, rename."""
    return write_table(directory, cell_id, pa.Table.from_pylist(rows, schema=SCHEMA))


def write_table(directory: Path, cell_id: str, table: pa.Table) -> Path:
    """Write a cell's table (of :data:`SCHEMA`) atomically: temp file, fsync, rename."""
    if not table.schema.equals(SCHEMA):
        raise ValueError(f"cell {cell_id}: its table does not have the results schema")
    directory.mkdir(parents=True, exist_ok=True)
    final = cell_path(directory, cell_id)
    with atomic_file(final, stem=cell_id, tag=writer_tag(), durable=True) as tmp:
        pq.write_table(table, tmp)
    return final


MANIFEST = "cells.json"
"""In a suite's results folder: the ids of the cells its current definition expands into.
A suite edited between runs leaves the files of its former cells beside the new ones;
readers use the manifest to leave those out."""


def write_manifest(suite_dir: Path, cell_ids: list[str]) -> None:
    with atomic_file(suite_dir / MANIFEST) as tmp:
        tmp.write_text(json.dumps({"cells": sorted(cell_ids)}, indent=0))


def current_cells(suite_dir: Path) -> set[str] | None:
    """The cell ids of the suite's current definition, or None where no run wrote them (a
    tuning trial's folder). A manifest that cannot be read is an error: read as missing,
    it would let cells of an earlier suite count as current."""
    path = suite_dir / MANIFEST
    try:
        return set(json.loads(path.read_text())["cells"])
    except FileNotFoundError:
        return None
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ResultsError(f"{path}: not a cell list senbench wrote ({type(exc).__name__}: "
                           f"{exc}); run the suite again to rewrite it (finished cells are "
                           "kept), or delete it to read every cell there") from None


def cell_row(path: Path, columns: list[str]) -> dict[str, Any] | None:
    """``columns`` of a cell file's summary row (``kind = "cell"``), or None if there is no
    readable file or no such row."""
    try:
        table = pq.read_table(path, columns=["kind", *columns])
    except (FileNotFoundError, pa.ArrowInvalid, OSError):
        return None
    for row in table.to_pylist():
        if row["kind"] == "cell":
            return row
    return None


def last_eval_return(path: Path) -> float | None:
    """The return of a cell file's last evaluation, or None if it has none."""
    try:
        table = pq.read_table(path, columns=["kind", "return"])
    except (FileNotFoundError, pa.ArrowInvalid, OSError):
        return None
    returns = [r["return"] for r in table.to_pylist() if r["kind"] == "eval"]
    return returns[-1] if returns else None


def finished_status(path: Path) -> str | None:
    """The status recorded in a cell file, or None if there is no readable file."""
    row = cell_row(path, ["status"])
    return None if row is None else row["status"]


def writer_tag(host: str | None = None) -> str:
    """``<pid>-<host>`` in a temp file's name: whose it is, on which machine. The host name
    keeps letters, digits and ``-``; any other character becomes ``_`` and its code point in
    hex, ``_2e_`` for ``.``, so that two names never give the same tag."""
    name = socket.gethostname() if host is None else host
    return f"{os.getpid()}-" + re.sub(r"[^A-Za-z0-9-]", lambda m: f"_{ord(m[0]):x}_", name)


_TEMP = re.compile(r"\.[^.]+\.(\d+)(?:-([A-Za-z0-9_-]*))?\.tmp")


def remove_stray_temp_files(directory: Path) -> int:
    """Delete the cell temp files left by writers that are no longer alive (a killed run).
    A file named after another host's writer is left alone (this host cannot see whether
    that writer is alive, and several machines may share the folder), and so is one not
    named as a cell's temp file."""
    here = {writer_tag().partition("-")[2],  # and the tag earlier builds wrote for this host:
            re.sub(r"[^A-Za-z0-9-]", "_", socket.gethostname())}
    removed = 0
    for tmp in directory.glob(".*.tmp"):
        match = _TEMP.fullmatch(tmp.name)
        if match is None or (match[2] is not None and match[2] not in here):
            continue  # not a cell's temp file, or another host's
        pid = int(match[1])
        if pid == os.getpid() or not process_alive(pid):
            tmp.unlink(missing_ok=True)
            removed += 1
    return removed


def process_alive(pid: int) -> bool:
    """A killed writer can linger as a zombie until its parent reaps it: that is dead."""
    try:
        return psutil.Process(pid).status() != psutil.STATUS_ZOMBIE
    except psutil.Error:
        return False


def find_cell_files(path: str | Path) -> list[Path]:
    """Cell files under a results folder: a suite folder, its cells/ folder, or a root
    holding several suites."""
    root = Path(path)
    if not root.exists():
        raise ResultsError(f"{root}: no such results folder")
    if root.is_file():
        return [root]
    # the cells/ folders below first: other Parquet files beside them (an exported
    # summary) are not cells; a folder without any is itself a cells folder
    files = sorted(root.glob("**/cells/*.parquet")) or sorted(root.glob("*.parquet"))
    if not files:
        raise ResultsError(f"{root}: holds no cell results (*.parquet); run a suite first")
    return files


def read_results(path: str | Path, include_stale: bool = False) -> pd.DataFrame:
    """All rows of the cells under ``path`` as one DataFrame. Cells that a suite's current
    definition no longer has (see MANIFEST) are left out unless ``include_stale``; the
    frame's ``attrs["stale"]`` counts them, and ``attrs["missing"]`` the cells of the
    current definitions with no result yet."""
    files = find_cell_files(path)
    stale = missing = 0
    if not include_stale:
        keep, by_suite = [], {}
        for f in files:
            by_suite.setdefault(f.parent.parent, []).append(f)
        for suite_dir, mine in by_suite.items():
            ids = current_cells(suite_dir)
            keep += [f for f in mine if ids is None or f.stem in ids]
            missing += len((ids or set()) - {f.stem for f in mine})
        stale = len(files) - len(keep)
        files = keep
        if not files:
            raise ResultsError(f"{path}: every cell result is of an earlier version of the "
                               "suite; run the suite, or pass --all")
    tables = []
    for f in files:
        try:
            tables.append(pq.read_table(f, schema=SCHEMA))
        except (pa.ArrowInvalid, OSError) as exc:
            raise ResultsError(f"{f}: not a senbench cell result ({exc}); move it out of "
                               "the results folder") from None
    frame = pa.concat_tables(tables).to_pandas()
    cells = frame[frame["kind"] == "cell"]
    twice = cells[cells.duplicated(["suite", "cell_id"], keep=False)]
    if len(twice):  # one curve would be read as the two files' rows interleaved
        suite, cell_id = twice.iloc[0][["suite", "cell_id"]]
        raise ResultsError(f"{path}: cell {cell_id} of suite {suite} is recorded "
                           f"{int((twice['cell_id'] == cell_id).sum())} times, in several "
                           "folders under it (a tuning study's trials that drew the same "
                           "settings, or copies); read one of those folders")
    frame.attrs["stale"], frame.attrs["missing"] = stale, missing
    return frame
