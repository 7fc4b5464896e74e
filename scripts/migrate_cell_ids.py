"""One-off: rename result files to the cell ids of senbench's layered layout (CURVE_VERSION 1).

Before it, a cell's id hashed its whole resolved config, labels (method, variant, the
env's threshold) included. Now it hashes what determines the curve and the curve version
(:mod:`senbench.suite.cell`). This script gives every result file under a results root its
new id: the file's name, its ``cell_id`` column and the suite's ``cells.json`` manifest. It
reads each file's own ``config`` column, so it needs no suite file. Nothing else in a file
changes. It is idempotent: a file already named by its new id is left alone.

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


def migrate(root: Path, apply: bool) -> int:
    renamed = 0
    for cells in sorted(root.glob("**/cells")):
        if not cells.is_dir():
            continue
        mapping: dict[str, str] = {}
        for path in sorted(cells.glob("*.parquet")):
            mapping[path.stem] = new_id(path)
        targets = list(mapping.values())
        clashes = {t for t in targets if targets.count(t) > 1}
        if clashes:
            sys.exit(f"{cells}: several files compute the same curve ({sorted(clashes)}); "
                     "resolve by hand before migrating")
        for old, new in mapping.items():
            if old == new:
                continue
            renamed += 1
            print(f"{cells / old}.parquet -> {new}.parquet")
            if apply:
                table = pq.read_table(cells / f"{old}.parquet", schema=SCHEMA)
                index = table.schema.get_field_index("cell_id")
                table = table.set_column(index, table.schema.field(index),
                                         pa.array([new] * len(table), pa.string()))
                write_table(cells, new, table)
                (cells / f"{old}.parquet").unlink()
        manifest = cells.parent / MANIFEST
        if manifest.exists():
            old_ids = json.loads(manifest.read_text())["cells"]
            ids = [mapping.get(i, i) for i in old_ids]
            suite_file = cells.parent / "suite.yaml"
            if suite_file.exists():  # also the cells not run yet, by their new ids
                suite = load_suite(suite_file, registries())
                expanded = {c.id for c in suite.cells}
                migrated = {mapping[i] for i in old_ids if i in mapping}
                if len(expanded) != len(old_ids) or not migrated <= expanded:
                    sys.exit(f"{suite_file}: expands into other cells than {manifest} lists; "
                             "was the suite edited after its last run?")
                ids = sorted(expanded)
            if apply:
                write_manifest(cells.parent, ids)
    return renamed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("root", type=Path, help="a results root, e.g. results")
    parser.add_argument("--apply", action="store_true", help="rename (default: only print)")
    args = parser.parse_args()
    count = migrate(args.root, args.apply)
    print(f"{count} files {'renamed' if args.apply else 'to rename'}")


if __name__ == "__main__":
    main()
