"""report, compare and plot curves on crafted results whose statistics are worked by hand."""

import json
import os
import subprocess
import sys

import pandas as pd
import pytest
from rich.console import Console

from senbench.analysis.compare import Side, compare, pairs_in_one_folder
from senbench.analysis.summary import per_cell, summarize
from senbench.cli.plots import learning_curves
from senbench.results.store import read_results, write_cell

# Each seed's curve: -200 at frame 0, then flat at its value v until the budget (4,000), so
# final return = v; with threshold -110 the trailing mean of 3 stays above it from frame
# 3,000 when -110 <= v < -65, and never otherwise (then it counts as the budget).
FINALS = {"a": [-100.0, -105.0, -108.0, -120.0], "b": [-150.0, -140.0, -130.0, -100.0]}


def write_fake(root, suite, methods, budget=4000):
    directory = root / suite / "cells"
    directory.mkdir(parents=True)
    ids = []
    for method in methods:
        for seed, value in enumerate(FINALS[method]):
            cell_id = f"{method}{seed:015d}"
            ids.append(cell_id)
            common = {"cell_id": cell_id, "suite": suite, "env": "mountaincar",
                      "method": method, "variant": "", "seed": seed, "threshold": -110.0,
                      "budget": budget}
            rows = [{**common, "kind": "eval", "step": step,
                     "return": -200.0 if step == 0 else value}
                    for step in range(0, 4001, 1000)]
            rows.append({**common, "kind": "cell", "status": "ok", "cell_wall_s": 1.0})
            write_cell(directory, cell_id, rows)
    (root / suite / "cells.json").write_text(json.dumps({"cells": ids}))
    return root / suite


def test_probability_of_improvement_per_metric_worked_by_hand(tmp_path):
    cells = per_cell(read_results(write_fake(tmp_path, "cmp", ["a", "b"])))
    assert list(cells[cells["method"] == "a"]["steps_to_threshold"]) == [3000, 3000, 3000, 4000]
    table = compare(Side("a", cells[cells["method"] == "a"]),
                    Side("b", cells[cells["method"] == "b"])).set_index("metric")
    # final: -100 beats 3 and ties 1 (3.5); -105, -108, -120 beat 3 each: 12.5 of 16 pairs
    assert table.loc["final", "p_better"] == pytest.approx(12.5 / 16)
    # frames (fewer is better): each 3,000 of a beats three 4,000s, ties one 3,000 (3.5 x 3);
    # a's 4,000 ties three 4,000s (1.5): 12 of 16
    assert table.loc["steps", "p_better"] == pytest.approx(12 / 16)
    assert table.loc["final", "a_iqm"] == pytest.approx((-105 - 108) / 2)  # middle half of 4
    assert table.loc["final", "p_low"] <= table.loc["final", "p_better"] <= table.loc[
        "final", "p_high"]


def test_cells_the_suite_lists_without_a_result_are_counted_and_a_bad_list_is_an_error(
        tmp_path):
    from senbench.errors import ResultsError

    folder = write_fake(tmp_path, "cmp", ["a"])
    manifest = folder / "cells.json"
    ids = json.loads(manifest.read_text())["cells"]
    manifest.write_text(json.dumps({"cells": ids + ["not-run-yet-0", "not-run-yet-1"]}))
    results = read_results(folder)
    assert results.attrs["missing"] == 2 and results.attrs["stale"] == 0
    manifest.write_text('{"cells": ["a0')  # cut short: never read as "no list"
    with pytest.raises(ResultsError, match="cells.json: not a cell list senbench wrote"):
        read_results(folder)
    assert read_results(folder, include_stale=True)["cell_id"].nunique() == 4  # --all


def test_compare_refuses_a_method_against_itself_and_names_a_missing_folder(tmp_path):
    from senbench.analysis.compare import pairs_for
    from senbench.errors import ResultsError

    folder = write_fake(tmp_path, "cmp", ["a", "b"])
    with pytest.raises(ResultsError, match="A and B are both a"):
        pairs_for("a", "a", folder, False, {})
    with pytest.raises(ResultsError, match=f"no folder {tmp_path}/gone; name two"):
        pairs_for(str(folder), f"{tmp_path}/gone", None, False, {})


def test_compare_says_how_many_failed_cells_it_left_out(tmp_path):
    from senbench.cli.views import show_comparison

    folder = write_fake(tmp_path, "cmp", ["a", "b"])
    common = {"cell_id": "a-failed", "suite": "cmp", "env": "mountaincar", "method": "a",
              "variant": "", "seed": 9, "threshold": -110.0, "budget": 4000}
    write_cell(folder / "cells", "a-failed", [{**common, "kind": "cell", "status": "failed",
                                               "error": "boom", "cell_wall_s": 1.0}])
    manifest = folder / "cells.json"
    manifest.write_text(json.dumps({"cells": json.loads(manifest.read_text())["cells"]
                                    + ["a-failed"]}))
    [(env, a, b)] = pairs_in_one_folder(folder, "a", "b")
    assert (len(a.cells), a.failed, b.failed) == (4, 1, 0)
    console = Console(record=True, width=200)
    show_comparison([(env, a, b)], console)
    assert "A = a (4 seeds, 1 failed and left out) vs B = b (4 seeds)" in console.export_text()


def test_a_cell_recorded_in_two_folders_is_not_read_as_one_curve(tmp_path):
    from senbench.errors import ResultsError

    first = write_fake(tmp_path / "trial-1", "cmp", ["a"])
    write_fake(tmp_path / "trial-7", "cmp", ["a"])  # a trial that drew the same settings
    assert read_results(first)["cell_id"].nunique() == 4  # each folder on its own is fine
    with pytest.raises(ResultsError, match="is recorded 2 times, in several folders"):
        read_results(tmp_path)


def test_report_summary_has_iqm_intervals_and_mean_std(tmp_path):
    summary = summarize(read_results(write_fake(tmp_path, "cmp", ["a", "b"])))
    a = summary.set_index("method").loc["a"]
    assert a["final_iqm"] == pytest.approx(-106.5)
    assert a["final_mean"] == pytest.approx(sum(FINALS["a"]) / 4)
    assert a["final_low"] <= a["final_iqm"] <= a["final_high"]
    assert a["reached"] == 3 and a["steps_iqm"] == pytest.approx(3000)


def cli(*args):
    env = {**os.environ, "COLUMNS": "200"}
    return subprocess.run([sys.executable, "-m", "senbench", *args], capture_output=True,
                          text=True, env=env)


@pytest.mark.slow
def test_compare_cli_two_methods_two_folders_and_mistakes(tmp_path):
    folder = write_fake(tmp_path, "cmp", ["a", "b"])
    done = cli("compare", "a", "b", "--results", str(folder))
    assert done.returncode == 0, done.stderr
    assert "P(A better)" in done.stdout and "0.78" in done.stdout and "0.75" in done.stdout

    left, right = write_fake(tmp_path / "l", "one", ["a"]), write_fake(tmp_path / "r", "two", ["b"])
    done = cli("compare", str(left), str(right))
    assert done.returncode == 0, done.stderr
    assert "one: a" in done.stdout and "two: b" in done.stdout and "0.78" in done.stdout

    done = cli("compare", "a", "c", "--results", str(folder))
    assert done.returncode == 2
    assert "no finished cells of method 'c'" in done.stderr and "it has: a, b" in done.stderr
    done = cli("compare", "a", "b")
    assert done.returncode == 2 and "--results" in done.stderr
    write_fake(tmp_path / "l", "three", ["b"])
    done = cli("compare", "a", "b", "--results", str(tmp_path / "l"))
    assert done.returncode == 2 and "holds several suites (one, three)" in done.stderr


@pytest.mark.slow
def test_folders_run_at_different_budgets_are_not_compared(tmp_path):
    left = write_fake(tmp_path / "l", "one", ["a"])
    right = write_fake(tmp_path / "r", "two", ["b"], budget=8000)
    done = cli("compare", str(left), str(right))
    assert done.returncode == 2
    assert "for 4,000 frames" in done.stderr and "for 8,000" in done.stderr


@pytest.mark.slow
def test_plot_curves_draws_every_method_on_the_shared_frames(tmp_path):
    folder = write_fake(tmp_path, "cmp", ["a", "b"])
    curves = learning_curves(read_results(folder))
    assert list(curves["mountaincar"]) == ["a", "b"]
    assert curves["mountaincar"]["a"].shape == (4, 5)
    done = cli("plot", "curves", str(folder))
    assert done.returncode == 0, done.stderr
    png = folder / "curves.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000
    done = cli("plot", "curves", str(tmp_path / "missing"))
    assert done.returncode == 2


def test_compare_two_folders_at_another_threshold(write_suite, tmp_path):
    from senbench.analysis.compare import pairs_across_folders
    from senbench.cli.views import show_comparison
    from senbench.errors import ResultsError
    from senbench.plugin.manager import registries
    from senbench.run.runner import run_suite
    from senbench.suite import load_suite

    text = ("name: {name}\nenvs:\n  mountaincar: {{}}\nmethods:\n  sarsa-state: {{agent: "
            "sarsa}}\nseeds: 2\nbudget: 1000\neval: {{every: 500, episodes: 1}}\n")
    for name in ("a", "b"):
        run_suite(load_suite(write_suite(text.format(name=name), f"{name}.yaml"),
                             registries()), tmp_path)
    # Untrained episodes time out at -200: at -200 every seed is there from frame 0.
    [(env, a, b)] = pairs_across_folders(tmp_path / "a", tmp_path / "b",
                                         thresholds={"mountaincar": -200.0})
    assert env == "mountaincar" and set(a.cells["steps_to_threshold"]) == {0.0}
    console = Console(record=True, width=200)
    show_comparison([(env, a, b)], console)
    assert "threshold -200" in console.export_text()
    with pytest.raises(ResultsError, match="names env pendulum"):
        pairs_across_folders(tmp_path / "a", tmp_path / "b", thresholds={"pendulum": -300.0})


@pytest.mark.slow
def test_compare_writes_its_numbers_to_a_table_file(tmp_path):
    folder = write_fake(tmp_path, "cmp", ["a", "b"])
    out = tmp_path / "p.csv"
    done = cli("compare", "a", "b", "--results", str(folder), "--out", str(out))
    assert done.returncode == 0, done.stderr
    table = pd.read_csv(out).set_index("metric")
    assert list(table.columns[:3]) == ["env", "a", "b"]
    assert table.loc["final", "p_better"] == pytest.approx(12.5 / 16)  # as worked above
    assert table.loc["final", "a_iqm"] == pytest.approx(-106.5)
    assert table.loc["final", "a_low"] <= -106.5 <= table.loc["final", "a_high"]
    assert set(table.index) == {"final", "steps", "auc"}
    done = cli("compare", "a", "b", "--results", str(folder), "--out", str(tmp_path / "p.txt"))
    assert done.returncode == 2 and "name a .csv or .parquet file" in done.stderr
    assert "P(A better)" not in done.stdout  # refused before comparing
