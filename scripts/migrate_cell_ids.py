"""One-off: bring result files to senbench's layered layout (CURVE_VERSION 1).

1. Ids. Before it, a cell's id hashed its whole resolved config, labels (method, variant,
   the env's threshold) included. Now it hashes what determines the curve and the curve
   version (:mod:`senbench.suite.cell`). Every result file under a results root gets its new
   id: the file's name, its ``cell_id`` column and the suite's ``cells.json`` manifest. It
   reads each file's own ``config`` column, so it needs no suite file.
2. Columns. Files written before the evaluation rows recorded the actions
   (``action_share``, ``action_mean``, ``action_std``) get those columns, empty (null): the
   runs that wrote them did not record what the policy did.
3. Labels. Where the results folder holds its suite's ``suite.yaml``, each file's ``config``
   column gets the labels senbench now records with a cell (the labelled frames an encoded
   method's encoder was trained on, and how they were obtained); what the cell computes is
   checked to be the same (its id). So it is also how a label added to a suite after its
   cells ran (a ``references:`` entry, say) reaches them: edit the suite and its results
   folder's ``suite.yaml`` alike, and run it on that folder.

Nothing else in a file changes. It is idempotent: a file already in the current layout is
left alone.

    python scripts/migrate_cell_ids.py results            # what it would do
    python scripts/migrate_cell_ids.py results --apply    # do it
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq

from senbench.plugin.manager import registries
from senbench.results.store import MANIFEST, SCHEMA, write_manifest, write_table
from senbench.suite import Cell, load_suite


def new_id(path: Path) -> str:
    table = pq.read_table(path, columns=["config", "suite"])
    config = json.loads(table["config"][0].as_py())
    return Cell.from_config(config, table["suite"][0].as_py()).id


def set_column(table: pa.Table, name: str, value: str) -> pa.Table:
    index = table.schema.get_field_index(name)
    return table.set_column(index, table.schema.field(index),
                            pa.array([value] * len(table), pa.string()))


def migrate(root: Path, apply: bool) -> int:
    changed = 0
    for cells in sorted(root.glob("**/cells")):
        if not cells.is_dir():
            continue
        mapping = {path.stem: new_id(path) for path in sorted(cells.glob("*.parquet"))}
        targets = list(mapping.values())
        clashes = {t for t in targets if targets.count(t) > 1}
        if clashes:
            sys.exit(f"{cells}: several files compute the same curve ({sorted(clashes)}); "
                     "resolve by hand before migrating")
        suite_file = cells.parent / "suite.yaml"
        suite = load_suite(suite_file, registries()) if suite_file.exists() else None
        by_id = {c.id: c for c in suite.cells} if suite else {}
        for old, new in mapping.items():
            # read with today's schema: columns the file lacks come back null
            table = pq.read_table(cells / f"{old}.parquet", schema=SCHEMA)
            config = table["config"][0].as_py()
            cell = by_id.get(new)
            labelled = None if cell is None else json.dumps(cell.config(), sort_keys=True)
            current = pq.read_schema(cells / f"{old}.parquet").equals(SCHEMA)
            relabel = labelled is not None and labelled != config
            if old == new and current and not relabel:
                continue
            changed += 1
            print(f"{cells / old}.parquet -> {new}.parquet"
                  + ("" if current else ", in today's columns (those it lacks empty)")
                  + (", with the suite's labels" if relabel else ""))
            if apply:
                table = set_column(table, "cell_id", new)
                if relabel:
                    table = set_column(table, "config", labelled)
                write_table(cells, new, table)
                if old != new:
                    (cells / f"{old}.parquet").unlink()
        manifest = cells.parent / MANIFEST
        if manifest.exists():
            old_ids = json.loads(manifest.read_text())["cells"]
            ids = [mapping.get(i, i) for i in old_ids]
            if suite is not None:  # also the cells not run yet, by their new ids
                migrated = {mapping[i] for i in old_ids if i in mapping}
                if len(by_id) != len(old_ids) or not migrated <= set(by_id):
                    sys.exit(f"{suite_file}: expands into other cells than {manifest} lists; "
                             "was the suite edited after its last run?")
                ids = sorted(by_id)
            if apply:
                write_manifest(cells.parent, ids)
    return changed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("root", type=Path, help="a results root, e.g. results")
    parser.add_argument("--apply", action="store_true", help="rename (default: only print)")
    args = parser.parse_args()
    count = migrate(args.root, args.apply)
    print(f"{count} files {'rewritten' if args.apply else 'to rewrite'}")


if __name__ == "__main__":
    main()
