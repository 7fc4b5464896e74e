"""run --reuse: a cell another suite finished, the same in all but its names, is copied."""

import json
import subprocess
import sys

import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from curves import curves_of
from suites_for_tests import SEN_SARSA

from senbench.errors import SenbenchError
from senbench.plugin.manager import registries
from senbench.results.store import SCHEMA, current_cells, finished_status, read_results
from senbench.run.claims import CellClaims
from senbench.run.reuse import copy_cell, finished_cells
from senbench.run.runner import run_suite
from senbench.suite import load_suite

MAIN = """\
name: main
envs:
  mountaincar: {}
methods:
  sarsa-state: {agent: sarsa, hyperparams: {alpha: 0.5}}
seeds: 2
budget: 1500
eval: {every: 500, episodes: 2}
"""

# The same setting, named otherwise and swept: its alpha = 0.5 cells are main's cells.
SWEEP = """\
name: sweep
envs:
  mountaincar: {}
methods:
  sarsa-swept: {agent: sarsa}
variants:
  sarsa-swept:
    hyperparams.alpha: [0.25, 0.5]
seeds: 2
budget: 1500
eval: {every: 500, episodes: 2}
"""


def load(write_suite, text, name):
    return load_suite(write_suite(text, name), registries())


@pytest.mark.slow
def test_a_cell_the_same_but_for_its_names_is_copied_and_equals_running_it(
        write_suite, tmp_path):
    main = load(write_suite, MAIN, "main.yaml")
    sweep = load(write_suite, SWEEP, "sweep.yaml")
    run_suite(main, tmp_path / "results")
    summary = run_suite(sweep, tmp_path / "results", reuse=[tmp_path / "results" / "main"])
    assert summary.reused == 2 and summary.ok == 2 and not summary.failed

    copied = [c for c in sweep.cells if c.variant == "hyperparams.alpha=0.5"]
    files = {c.id: tmp_path / "results" / "sweep" / "cells" / f"{c.id}.parquet"
             for c in copied}
    for cell in copied:
        table = pq.read_table(files[cell.id])
        assert table.schema.equals(SCHEMA) and finished_status(files[cell.id]) == "ok"
        row = table.slice(0, 1).to_pylist()[0]
        assert (row["cell_id"], row["suite"], row["method"], row["variant"]) == (
            cell.id, "sweep", "sarsa-swept", "hyperparams.alpha=0.5")
        assert json.loads(row["config"]) == cell.config()
    frame = read_results(tmp_path / "results" / "sweep")
    assert len(frame["cell_id"].unique()) == 4
    assert current_cells(tmp_path / "results" / "sweep") == {c.id for c in sweep.cells}

    # Running the sweep without --reuse gives the copied curves value for value.
    ran = run_suite(sweep, tmp_path / "ran")
    assert ran.reused == 0 and ran.ok == 4
    assert curves_of(tmp_path / "results" / "sweep").equals(curves_of(tmp_path / "ran" / "sweep"))


def test_a_cell_another_run_holds_is_neither_copied_nor_run(write_suite, tmp_path):
    main = load(write_suite, MAIN, "main.yaml")
    sweep = load(write_suite, SWEEP, "sweep.yaml")
    run_suite(main, tmp_path / "results")
    held, free = [c for c in sweep.cells if c.variant == "hyperparams.alpha=0.5"]
    cells = tmp_path / "results" / "sweep" / "cells"
    cells.mkdir(parents=True)
    other = CellClaims(cells)  # another run of the sweep, computing or copying it
    assert other.take(held.id)
    try:
        summary = run_suite(sweep, tmp_path / "results", reuse=[tmp_path / "results" / "main"],
                            cells=[held, free])
    finally:
        other.release_all()
    assert summary.reused == 1 and summary.elsewhere == [held.id]
    assert finished_status(cells / f"{free.id}.parquet") == "ok"
    assert not (cells / f"{held.id}.parquet").exists()


@pytest.mark.slow
def test_a_cell_that_differs_in_anything_else_is_run(write_suite, tmp_path):
    main = load(write_suite, MAIN.replace("budget: 1500", "budget: 1000"), "main.yaml")
    run_suite(main, tmp_path / "results")
    sweep = load(write_suite, SWEEP, "sweep.yaml")
    summary = run_suite(sweep, tmp_path / "results", reuse=[tmp_path / "results" / "main"])
    assert summary.reused == 0 and summary.ok == 4


@pytest.mark.parametrize("force", [False, True])
def test_a_wrong_reuse_folder_or_force_is_a_clear_error_and_nothing_is_written(
        write_suite, tmp_path, force):
    sweep = load(write_suite, SWEEP, "sweep.yaml")
    if force:
        (tmp_path / "results" / "main" / "cells").mkdir(parents=True)
        folder, message = tmp_path / "results" / "main", "use one of the two"
    else:
        folder, message = tmp_path / "nowhere", "not a suite's results folder"
    with pytest.raises(SenbenchError, match=message):
        run_suite(sweep, tmp_path / "results", reuse=[folder], force=force)
    assert not (tmp_path / "results" / "sweep").exists()


def test_a_source_rewritten_after_the_scan_is_not_copied(write_suite, tmp_path):
    run_suite(load(write_suite, MAIN, "main.yaml"), tmp_path / "results")
    sweep = load(write_suite, SWEEP, "sweep.yaml")
    found = finished_cells([tmp_path / "results" / "main"])
    cell = next(c for c in sweep.cells if c.variant == "hyperparams.alpha=0.5")
    source = found[cell.id]
    set_column(pq.read_table(source), "status", "failed", source)  # as a failed --force rerun
    assert copy_cell(cell, source, tmp_path / "out", tmp_path / "enc") is None
    assert not (tmp_path / "out").exists()


def test_its_own_folder_named_first_hides_nothing(write_suite, tmp_path):
    run_suite(load(write_suite, MAIN, "main.yaml"), tmp_path / "results")
    sweep = load(write_suite, SWEEP, "sweep.yaml")
    run_suite(sweep, tmp_path / "results", cells=sweep.select(seeds=[0]))
    summary = run_suite(sweep, tmp_path / "results", reuse=[
        tmp_path / "results" / "sweep", tmp_path / "results" / "main"])
    assert summary.skipped == 2 and summary.reused == 1 and summary.ok == 1


@pytest.mark.slow
def test_a_copied_cells_encoder_comes_into_this_results_root(write_suite, tmp_path):
    text = f"name: main\nenvs:\n  mountaincar: {{}}\nmethods:\n{SEN_SARSA}seeds: 1\n" \
        "budget: 600\neval: {every: 300, episodes: 1}\n"
    run_suite(load(write_suite, text, "main.yaml"), tmp_path / "a")
    renamed = load(write_suite, text.replace("name: main", "name: other")
                   .replace("sen-sarsa:", "sen-renamed:"), "other.yaml")
    summary = run_suite(renamed, tmp_path / "b", reuse=[tmp_path / "a" / "main"])
    assert summary.reused == 1
    [encoder] = [p.name for p in (tmp_path / "a" / "encoders").iterdir()
                 if not p.name.startswith(".")]
    copied = tmp_path / "b" / "encoders" / encoder
    assert sorted(p.name for p in copied.iterdir()) == sorted(
        p.name for p in (tmp_path / "a" / "encoders" / encoder).iterdir())
    assert not list((tmp_path / "b" / "encoders").glob(".*tmp"))


def set_column(table, name, value, path):
    index = table.schema.get_field_index(name)
    table = table.set_column(index, table.schema.field(index),
                             pa.array([value] * len(table), pa.string()))
    pq.write_table(table, path)


@pytest.mark.slow
def test_the_cli_says_how_many_cells_it_copied(write_suite, tmp_path, cli_env):
    run_suite(load(write_suite, MAIN, "main.yaml"), tmp_path / "results")
    older = sorted((tmp_path / "results" / "main" / "cells").glob("*.parquet"))[0]
    set_column(pq.read_table(older), "git_commit", "0" * 40, older)  # as by an older commit
    done = subprocess.run(
        [sys.executable, "-m", "senbench", "run", str(write_suite(SWEEP, "sweep.yaml")),
         "--results", str(tmp_path / "results"), "--reuse", str(tmp_path / "results" / "main"),
         "--variant", "hyperparams.alpha=0.5"],
        env=cli_env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    assert ("0 finished, 0 failed, 0 already done, 2 copied from --reuse, of 2 cells "
            "(picked from 4)") in done.stdout
    assert done.stderr.count("copied sarsa") == 0  # labels print whole, variant included
    assert done.stderr.count("copied mountaincar/sarsa-swept[hyperparams.alpha=0.5] seed") == 2
    assert "1 copied cells were computed by another senbench commit" in done.stderr


def test_a_file_written_before_a_column_was_added_is_copied_with_it_null(write_suite,
                                                                        tmp_path):
    """Results committed before ``seed_batch`` existed stay reusable (the -plus suites
    reuse the paper suites' cells)."""
    main = load(write_suite, MAIN.replace("seeds: 2", "seeds: 1"), "main.yaml")
    run_suite(main, tmp_path / "results")
    path = tmp_path / "results" / "main" / "cells" / f"{main.cells[0].id}.parquet"
    pq.write_table(pq.read_table(path).drop_columns(["seed_batch"]), path)  # an older file
    summary = run_suite(main, tmp_path / "again", reuse=[tmp_path / "results" / "main"])
    assert summary.reused == 1
    copied = pq.read_table(tmp_path / "again" / "main" / "cells" / path.name)
    assert copied.schema.equals(SCHEMA) and copied["seed_batch"].null_count == len(copied)
    assert read_results(tmp_path / "results" / "main")["seed_batch"].isna().all()
