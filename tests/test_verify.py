"""senbench verify: a finished cell's first frames run again and compared with its file."""

import pandas as pd
from suites_for_tests import SARSA
from typer.testing import CliRunner

from senbench.cli.app import app
from senbench.plugin.manager import registries
from senbench.run.execute import RunInfo, execute_cell
from senbench.run.provenance import cpu_description
from senbench.run.runner import run_suite
from senbench.suite import load_suite


def ran(write_suite, tmp_path, seeds=None):
    path = write_suite(SARSA)
    suite = load_suite(path, registries())
    cells = None if seeds is None else suite.select(seeds=seeds)
    run_suite(suite, tmp_path / "results", cells=cells)
    return path, suite


def verify(path, tmp_path, *extra):
    return CliRunner().invoke(app, ["verify", str(path), "--frames", "1000",
                                    "--results", str(tmp_path / "results"), *extra])


def test_a_cell_stopped_early_runs_the_first_part_of_its_curve(write_suite, tmp_path):
    _, suite = ran(write_suite, tmp_path, seeds=[0])
    cell = suite.cells[0]
    rows, outcome = execute_cell(cell, RunInfo.gather(tmp_path / "results" / "encoders"),
                                 stop_at=1000)
    assert outcome.status == "ok"
    assert [r["step"] for r in rows if r["kind"] == "cell"] == [1000]
    full = pd.read_parquet(tmp_path / "results" / "small" / "cells" / f"{cell.id}.parquet")
    curve = ["kind", "step", "return", "length"]
    prefix = full[full["kind"].isin(["episode", "eval"]) & (full["step"] <= 1000)][curve]
    now = pd.DataFrame(rows)
    now = now[now["kind"].isin(["episode", "eval"])][curve]
    assert len(now) >= 7  # 5 episodes of 200 frames and 3 evaluations
    assert set(full["cpu"]) == {cpu_description()}  # where it ran, to tell a reader
    pd.testing.assert_frame_equal(now.reset_index(drop=True), prefix.reset_index(drop=True))


def test_results_that_reproduce_are_same_and_exit_0(write_suite, tmp_path):
    path, _ = ran(write_suite, tmp_path)
    result = verify(path, tmp_path)
    assert result.exit_code == 0, result.output
    assert "3 same, 0 different or failed" in result.output
    assert not list((tmp_path / "results").rglob("*.tmp*"))


def test_a_curve_that_moved_is_different_names_where_and_exits_1(write_suite, tmp_path):
    path, suite = ran(write_suite, tmp_path)
    cell = suite.select(seeds=[1])[0]
    file = tmp_path / "results" / "small" / "cells" / f"{cell.id}.parquet"
    table = pd.read_parquet(file)
    third = table.index[table["kind"] == "episode"][2]
    table.loc[third, "return"] -= 1.0  # as if the code had changed what episode 3 did
    table.to_parquet(file)
    result = verify(path, tmp_path)
    assert result.exit_code == 1, result.output
    assert "2 same, 1 different or failed" in result.output
    step = int(table.loc[third, "step"])
    assert f"episode ending at frame {step:,}" in result.output
    assert "different" in result.output


def test_a_cell_with_no_result_is_not_run_and_the_rest_are_checked(write_suite, tmp_path):
    path, _ = ran(write_suite, tmp_path, seeds=[0])
    result = verify(path, tmp_path)
    assert result.exit_code == 0, result.output
    assert "1 same, 0 different or failed, 2 with no finished result" in result.output
    assert "no result file" in result.output


def test_picking_a_seed_the_suite_lacks_is_a_clear_error(write_suite, tmp_path):
    path, _ = ran(write_suite, tmp_path, seeds=[0])
    result = verify(path, tmp_path, "--seed", "7")
    assert result.exit_code == 2
    assert "has no seed 7" in result.output


def test_a_difference_says_the_committed_processor_is_not_recorded(write_suite, tmp_path):
    path, suite = ran(write_suite, tmp_path, seeds=[0])
    file = tmp_path / "results" / "small" / "cells" / f"{suite.cells[0].id}.parquet"
    table = pd.read_parquet(file).drop(columns=["cpu"])  # a file older than the column
    table.loc[table.index[table["kind"] == "episode"][0], "length"] = 199.0
    table.to_parquet(file)
    result = verify(path, tmp_path, "--seed", "0")
    assert result.exit_code == 1, result.output
    assert "processor is not recorded" in result.output
