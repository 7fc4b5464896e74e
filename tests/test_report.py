import re
import subprocess
import sys

import pandas as pd
import pytest

from senbench.analysis.summary import parse_thresholds, returns_at, summarize, with_thresholds
from senbench.errors import ResultsError
from senbench.plugin.manager import registries
from senbench.results.store import read_results
from senbench.run.runner import run_suite
from senbench.suite import load_suite

SUITE = """\
name: rep
envs:
  mountaincar: {}
methods:
  sarsa-state: {agent: sarsa}
  crash-state: {agent: crash, hyperparams: {after: 5}}
seeds: 2
budget: 1000
eval: {every: 500, episodes: 1}
"""


def test_summary_counts_finished_and_failed_seeds(write_suite, tmp_path, test_agents):
    run_suite(load_suite(write_suite(SUITE), registries()), tmp_path)
    summary = summarize(read_results(tmp_path / "rep")).set_index("method")
    assert summary.loc["sarsa-state", "seeds_ok"] == 2
    assert summary.loc["sarsa-state", "seeds_failed"] == 0
    assert summary.loc["crash-state", "seeds_ok"] == 0
    assert summary.loc["crash-state", "seeds_failed"] == 2
    assert summary.loc["sarsa-state", "initial_mean"] == -200  # untrained: never reaches the flag


@pytest.mark.slow
def test_report_cli_prints_a_table_per_env(write_suite, tmp_path):
    text = SUITE.replace("  crash-state: {agent: crash, hyperparams: {after: 5}}\n", "")
    run_suite(load_suite(write_suite(text), registries()), tmp_path)
    done = subprocess.run([sys.executable, "-m", "senbench", "report", str(tmp_path / "rep"),
                           "--at", "500", "--at", "0"],
                          capture_output=True, text=True, env={"COLUMNS": "200",
                                                               "PATH": "/usr/bin:/bin"})
    assert done.returncode == 0, done.stderr
    assert "mountaincar: evaluation return; threshold -110" in done.stdout
    assert "sarsa-state" in done.stdout and "2 / 0" in done.stdout
    at = done.stdout[done.stdout.index("mountaincar: evaluation return at frames"):]
    header = next(line for line in at.splitlines() if "method" in line)
    assert [c.strip() for c in header.split("┃")[1:-1]] == ["method", "0", "500"]
    assert "-200.0 ± 0.0" in at  # untrained at frame 0: never reaches the flag


def test_returns_at_frames_are_each_seeds_last_evaluation_up_to_there():
    def cell(cell_id, status, curve):
        rows = [{"suite": "s", "cell_id": cell_id, "env": "e", "method": "m", "variant": "",
                 "kind": "cell", "step": None, "return": None, "status": status}]
        return rows + [{"suite": "s", "cell_id": cell_id, "env": "e", "method": "m",
                        "variant": "", "kind": "eval", "step": step, "return": value,
                        "status": None} for step, value in curve]

    results = pd.DataFrame(
        cell("a", "ok", [(0, -10.0), (100, -5.0), (200, -1.0)])
        + cell("b", "ok", [(0, -20.0), (100, -7.0), (200, -3.0)])
        + cell("c", "ok", [(100, -9.0), (200, -9.0)])  # its first evaluation at 100
        + cell("d", "failed", [(0, 500.0), (100, 500.0)]))  # a failed seed does not count
    table = returns_at(results, [0, 150, 200, 250]).set_index("frame")
    assert table.loc[0, "seeds"] == 2 and table.loc[0, "mean"] == -15.0
    assert table.loc[0, "std"] == 5.0
    # at 150: the evaluations at 100, -5, -7 and -9
    assert table.loc[150, "seeds"] == 3 and table.loc[150, "mean"] == pytest.approx(-7.0)
    assert table.loc[150, "std"] == pytest.approx((8 / 3) ** 0.5)
    assert table.loc[200, "mean"] == pytest.approx(-13 / 3)
    assert table.loc[250, "seeds"] == 0 and pd.isna(table.loc[250, "mean"])  # past the end


@pytest.mark.slow
def test_report_on_a_folder_without_results_says_so(tmp_path):
    with pytest.raises(ResultsError, match="no cell results"):
        read_results(tmp_path)
    done = subprocess.run([sys.executable, "-m", "senbench", "report", str(tmp_path / "none")],
                          capture_output=True, text=True)
    assert done.returncode == 2 and "no such results folder" in done.stderr
    assert "Traceback" not in done.stderr


@pytest.mark.slow
def test_results_read_with_one_glob_without_senbench(write_suite, tmp_path):
    text = SUITE.replace("  crash-state: {agent: crash, hyperparams: {after: 5}}\n", "")
    run_suite(load_suite(write_suite(text), registries()), tmp_path)
    glob = str(tmp_path / "rep" / "cells" / "*.parquet")
    script = f"""
import sys, glob
import duckdb, pandas, polars
n_duck = duckdb.execute("select count(*) from '{glob}' where kind = 'cell'").fetchone()[0]
n_polars = polars.read_parquet('{glob}').filter(polars.col('kind') == 'cell').height
frame = pandas.read_parquet(sorted(glob.glob('{glob}')))
n_pandas = int((frame['kind'] == 'cell').sum())
assert not any(m.startswith('senbench') for m in sys.modules), 'senbench was imported'
print(n_duck, n_polars, n_pandas)
"""
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["2", "2", "2"]


@pytest.mark.slow
def test_report_leaves_out_cells_of_an_earlier_version_of_the_suite(write_suite, tmp_path):
    text = SUITE.replace("  crash-state: {agent: crash, hyperparams: {after: 5}}\n", "")
    run_suite(load_suite(write_suite(text), registries()), tmp_path)
    edited = text.replace("sarsa-state: {agent: sarsa}",
                          "sarsa-state: {agent: sarsa, hyperparams: {alpha: 0.5}}")
    run_suite(load_suite(write_suite(edited), registries()), tmp_path)
    assert len(list((tmp_path / "rep" / "cells").glob("*.parquet"))) == 4
    current = read_results(tmp_path / "rep")
    assert current.attrs["stale"] == 2
    assert summarize(current).set_index("method").loc["sarsa-state", "seeds_ok"] == 2
    everything = read_results(tmp_path / "rep", include_stale=True)
    assert summarize(everything).set_index("method").loc["sarsa-state", "seeds_ok"] == 4
    # another budget: its cells are another row, not more seeds of the same one
    shorter = re.sub(r"budget: \d+", "budget: 600", edited)
    run_suite(load_suite(write_suite(shorter), registries()), tmp_path)
    rows = summarize(read_results(tmp_path / "rep", include_stale=True))
    assert rows.set_index("budget")["seeds_ok"].to_dict() == {600: 2, int(re.search(
        r"budget: (\d+)", edited)[1]): 4}


def test_a_foreign_file_in_the_results_folder_is_a_clear_error(tmp_path):
    (tmp_path / "cells").mkdir()
    (tmp_path / "cells" / "notes.parquet").write_text("not parquet")
    with pytest.raises(ResultsError, match="not a senbench cell result"):
        read_results(tmp_path)


@pytest.mark.slow
def test_variant_labels_show_in_brackets(write_suite, tmp_path):
    text = SUITE.replace("  crash-state: {agent: crash, hyperparams: {after: 5}}\n", "")
    text += "variants:\n  sarsa-state:\n    hyperparams.alpha: [0.5, 1.0]\n"
    run_suite(load_suite(write_suite(text), registries()), tmp_path)
    done = subprocess.run([sys.executable, "-m", "senbench", "report", str(tmp_path / "rep")],
                          capture_output=True, text=True, env={"COLUMNS": "200",
                                                               "PATH": "/usr/bin:/bin"})
    assert done.returncode == 0, done.stderr
    assert "sarsa-state [hyperparams.alpha=0.5]" in done.stdout  # not eaten as rich markup
    assert "sarsa-state [hyperparams.alpha=1.0]" in done.stdout


def test_status_counts_finished_failed_and_left_and_estimates_the_time(
        write_suite, tmp_path, test_agents):
    from senbench.run.status import suite_status

    suite = load_suite(write_suite(SUITE.replace("seeds: 2", "seeds: 3")), registries())
    before = suite_status(suite, tmp_path)
    assert [(c.method, c.cells, c.ok, c.failed, c.left_s) for c in before] == [
        ("sarsa-state", 3, 0, 0, None), ("crash-state", 3, 0, 0, None)]
    run_suite(suite, tmp_path, cells=suite.select(seeds=[0, 1]))
    sarsa, crash = suite_status(suite, tmp_path)
    assert (sarsa.ok, sarsa.failed, sarsa.to_run) == (2, 0, 1)
    assert sarsa.mean_wall_s > 0 and sarsa.left_s == pytest.approx(sarsa.mean_wall_s)
    assert (crash.ok, crash.failed, crash.to_run, crash.left_s) == (0, 2, 3, None)


@pytest.mark.slow
def test_status_cli_prints_the_table_and_what_is_left(write_suite, tmp_path):
    text = SUITE.replace("  crash-state: {agent: crash, hyperparams: {after: 5}}\n", "")
    suite_file = write_suite(text)
    suite = load_suite(suite_file, registries())
    run_suite(suite, tmp_path, cells=suite.select(seeds=[0]))
    done = subprocess.run([sys.executable, "-m", "senbench", "status", str(suite_file),
                           "--results", str(tmp_path), "--workers", "2"],
                          capture_output=True, text=True, env={"COLUMNS": "200",
                                                               "PATH": "/usr/bin:/bin"})
    assert done.returncode == 0, done.stderr
    assert "suite 'rep'" in done.stdout and "sarsa-state" in done.stdout
    assert "1 of 2 cells finished; cell time left ≈ " in done.stdout
    assert "on 2 workers" in done.stdout and "not known" not in done.stdout


@pytest.mark.parametrize("specs, expected", [
    (["-150"], {None: -150.0}), (["mountaincar=-150", "pendulum=-300"],
                                 {"mountaincar": -150.0, "pendulum": -300.0})])
def test_thresholds_read_as_written(specs, expected):
    assert parse_thresholds(specs) == expected


@pytest.mark.parametrize("specs, message", [
    (["low"], "give a return"), (["=-150"], "give a return"), (["mountaincar=inf"],
                                                                 "give a return"),
    (["-150", "pendulum=-300"], "not both")])
def test_a_bad_threshold_says_how_to_write_one(specs, message):
    with pytest.raises(ResultsError, match=message):
        parse_thresholds(specs)


@pytest.mark.slow
def test_another_threshold_changes_frames_to_threshold_and_the_title(write_suite, tmp_path):
    text = SUITE.replace("  crash-state: {agent: crash, hyperparams: {after: 5}}\n", "")
    run_suite(load_suite(write_suite(text), registries()), tmp_path)
    results = read_results(tmp_path / "rep")
    # Untrained, every episode times out at -200: at -200 every seed is there from frame 0.
    at_200 = summarize(with_thresholds(results, parse_thresholds(["-200"]))).iloc[0]
    assert at_200["threshold"] == -200 and at_200["reached"] == 2
    assert at_200["steps_iqm"] == 0
    assert summarize(results).iloc[0]["threshold"] == -110
    with pytest.raises(ResultsError, match="do not hold; they hold: mountaincar"):
        with_thresholds(results, {"pendulum": -300.0})
    two_envs = pd.concat([results, results.assign(env="pendulum")])
    with pytest.raises(ResultsError, match="give --threshold ENV=RETURN for each"):
        with_thresholds(two_envs, {None: -150.0})
    done = subprocess.run([sys.executable, "-m", "senbench", "report", str(tmp_path / "rep"),
                           "--threshold", "-200"], capture_output=True, text=True,
                          env={"COLUMNS": "200", "PATH": "/usr/bin:/bin"})
    assert done.returncode == 0, done.stderr
    assert "threshold -200" in done.stdout and "not reached" not in done.stdout


@pytest.mark.slow
def test_report_writes_its_summary_to_csv_or_parquet_and_refuses_other_files(write_suite,
                                                                               tmp_path):
    text = SUITE.replace("  crash-state: {agent: crash, hyperparams: {after: 5}}\n", "")
    run_suite(load_suite(write_suite(text), registries()), tmp_path)
    expected = summarize(read_results(tmp_path / "rep"))

    def report(*extra):
        return subprocess.run([sys.executable, "-m", "senbench", "report",
                               str(tmp_path / "rep"), *extra], capture_output=True, text=True)

    beside = tmp_path / "rep" / "summary.parquet"  # in the results folder: not a cell
    for out, read in ((tmp_path / "s.CSV", pd.read_csv), (beside, pd.read_parquet),
                      (beside, pd.read_parquet)):  # the second time over the first
        done = report("--out", str(out))
        assert done.returncode == 0, done.stderr
        assert f"summary written to {out}" in done.stdout
        table = read(out)
        assert list(table["label"]) == ["sarsa-state"]
        assert list(table.columns[1:]) == list(expected.columns)
        for column in ("seeds_ok", "final_iqm", "final_low", "final_high", "auc_mean"):
            assert table[column].iloc[0] == pytest.approx(expected[column].iloc[0])
    (tmp_path / "d.csv").mkdir()
    (tmp_path / "f").write_text("a file")
    for bad, message in (("s.txt", "a .csv or .parquet file"), ("f/s.csv", "not a folder"),
                         ("d.csv", "is a folder"), ("rep/cells/s.parquet", "beside it")):
        done = report("--out", str(tmp_path / bad))
        assert done.returncode == 2 and message in done.stderr, done.stderr
        assert "mountaincar" not in done.stdout  # refused before any table
        assert "Traceback" not in done.stderr
        assert bad == "d.csv" or not (tmp_path / bad).exists()
    assert not list(tmp_path.rglob(".*.tmp"))
    assert len(read_results(tmp_path / "rep")) == len(read_results(tmp_path / "rep" / "cells"))
