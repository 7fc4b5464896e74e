"""A label added to a suite after its cells ran (a published reference for a control)
reaches the committed cells through scripts/migrate_cell_ids.py: their labels change, what
they computed does not."""

import importlib.util
from pathlib import Path

import pandas as pd
from suites_for_tests import SARSA

from senbench.analysis.summary import summarize
from senbench.plugin.manager import registries
from senbench.results.store import read_results
from senbench.run.runner import run_suite
from senbench.suite import load_suite

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "migrate_cell_ids.py"
REFERENCE = """
references:
  sarsa-state:
    mountaincar: {value: -150.0, spread: 10.0, source: "a published table"}
"""


def migrate_module():
    spec = importlib.util.spec_from_file_location("migrate_cell_ids", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_a_reference_added_later_reaches_the_committed_cells(write_suite, tmp_path):
    results = tmp_path / "results"
    run_suite(load_suite(write_suite(SARSA), registries()), results)
    folder = results / "small"
    before = {p.name: pd.read_parquet(p) for p in (folder / "cells").glob("*.parquet")}
    assert "reference" not in before[next(iter(before))]["config"].iloc[0]

    (folder / "suite.yaml").write_text(SARSA + REFERENCE)
    migrate = migrate_module()
    assert migrate.migrate(folder, apply=False) == 3  # a dry run says, and writes nothing
    assert {p.name: pd.read_parquet(p)["config"].iloc[0]
            for p in (folder / "cells").glob("*.parquet")} == {
        name: frame["config"].iloc[0] for name, frame in before.items()}
    assert migrate.migrate(folder, apply=True) == 3
    assert migrate.migrate(folder, apply=True) == 0  # done once, nothing left to do

    for name, old in before.items():
        new = pd.read_parquet(folder / "cells" / name)  # the same id, so the same file name
        assert '"reference": {"source": "a published table"' in new["config"].iloc[0]
        same = [c for c in old.columns if c != "config"]
        pd.testing.assert_frame_equal(new[same], old[same])  # the curve is untouched
    summary = summarize(read_results(folder))
    assert summary["reference"].tolist() == [-150.0]
    assert summary["reference_source"].tolist() == ["a published table"]
