import re
import subprocess
import sys
import time
from datetime import UTC, datetime

import plugin_for_tests
import psutil
import pyarrow.parquet as pq
import pytest
from curves import curves_of
from stopping import start_as_from_a_terminal, stop, wait_for_files, wait_for_fork_server
from suites_for_tests import SARSA, SLOW

from senbench.errors import SenbenchError
from senbench.plugin.manager import registries
from senbench.results.store import SCHEMA, current_cells, finished_status, read_results
from senbench.run.runner import run_suite
from senbench.suite import load_suite


def run(write_suite, tmp_path, text, **kwargs):
    suite = load_suite(write_suite(text), registries())
    return suite, run_suite(suite, tmp_path / "results", **kwargs)


def cell_files(tmp_path, suite="small"):
    return sorted((tmp_path / "results" / suite / "cells").glob("*.parquet"))


def test_each_cell_writes_one_file_with_the_documented_schema(write_suite, tmp_path):
    suite, summary = run(write_suite, tmp_path, SARSA)
    assert summary.ok == 3 and not summary.failed
    files = cell_files(tmp_path)
    assert [f.stem for f in files] == sorted(c.id for c in suite.cells)
    for path in files:
        table = pq.read_table(path)
        assert table.schema.equals(SCHEMA)
        kinds = table["kind"].to_pylist()
        assert kinds.count("cell") == 1
        evals = [s for k, s in zip(kinds, table["step"].to_pylist(), strict=True) if k == "eval"]
        assert evals == [0, 500, 1000, 1500]
        assert set(table["status"].to_pylist()) == {"ok"}
        row = table.slice(0, 1).to_pylist()[0]
        assert row["gymnasium_version"] and row["torch_version"] and row["host"]
        assert row["peak_rss_mb"] > 10 and row["cell_wall_s"] > 0
        assert row["started_at"] <= row["ended_at"]
    assert (tmp_path / "results" / "small" / "suite.yaml").exists()


@pytest.mark.slow
def test_resume_skips_finished_cells_and_ignores_a_stray_temp_file(write_suite, tmp_path):
    suite, _ = run(write_suite, tmp_path, SARSA)
    files = cell_files(tmp_path)
    before = {f: (f.stat().st_mtime_ns, f.read_bytes()) for f in files}
    # A kill mid-write leaves a temp file named after a (dead) writer's pid.
    stray = files[0].parent / f".{files[0].stem}.999999999.tmp"
    stray.write_bytes(b"half a parquet file")
    assert len(read_results(tmp_path / "results" / "small")) > 0  # readers ignore it
    _, summary = run(write_suite, tmp_path, SARSA)
    assert summary.skipped == 3 and summary.outcomes == []
    assert {f: (f.stat().st_mtime_ns, f.read_bytes()) for f in cell_files(tmp_path)} == before
    assert not stray.exists()
    _, summary = run(write_suite, tmp_path, SARSA, force=True)
    assert summary.skipped == 0 and summary.ok == 3


FAILING = """\
name: small
envs:
  mountaincar: {}
methods:
  sarsa-state: {agent: sarsa}
  crash-state: {agent: crash, hyperparams: {after: 700}}
seeds: 1
budget: 1500
eval: {every: 500, episodes: 2}
"""


def test_a_failing_cell_is_recorded_and_the_grid_goes_on(write_suite, tmp_path, test_agents):
    suite, summary = run(write_suite, tmp_path, FAILING)
    assert summary.ok == 1 and len(summary.failed) == 1
    failed = next(c for c in suite.cells if c.method == "crash-state")
    path = tmp_path / "results" / "small" / "cells" / f"{failed.id}.parquet"
    assert finished_status(path) == "failed"
    table = pq.read_table(path).to_pandas()
    assert "crashed on purpose at frame 700" in table["error"].iloc[0]
    assert list(table.loc[table["kind"] == "eval", "step"]) == [0, 500]  # rows before the crash
    # Failed cells are tried again on the next run; finished ones are not.
    _, again = run(write_suite, tmp_path, FAILING)
    assert again.skipped == 1 and [o.label for o in again.outcomes] == [failed.label]


@pytest.mark.slow
def test_two_workers_give_the_same_curves_as_serial(write_suite, tmp_path, test_agents):
    text = SARSA.replace("  mountaincar: {}\n", "  mountaincar: {}\n  pendulum: {budget: 1024}\n")
    text = text.replace("  sarsa-state: {agent: sarsa}\n", """\
  sarsa-state: {agent: sarsa, envs: [mountaincar]}
  ppo-state:
    agent: ppo
    envs: [pendulum]
    hyperparams: {n_envs: 2, n_steps: 128, n_epochs: 2}
""")
    _, serial = run(write_suite, tmp_path, text)
    assert serial.ok == 6
    first = curves_of(tmp_path / "results" / "small")
    _, parallel = run(write_suite, tmp_path, text, workers=2, force=True)
    assert parallel.ok == 6
    assert first.equals(curves_of(tmp_path / "results" / "small"))
    second = read_results(tmp_path / "results" / "small")
    assert set(second["threads"]) == {1}  # the suite's, whatever the number of workers


@pytest.mark.slow
def test_a_cell_that_dies_fails_alone(write_suite, tmp_path, test_agents):
    # cells that kill their own process, next to cells that run on: out-of-memory kills
    # look like this to the runner
    text = FAILING.replace("crash-state: {agent: crash, hyperparams: {after: 700}}",
                           "die-state: {agent: die}").replace("seeds: 1", "seeds: 3")
    text = text.replace("budget: 1500", "budget: 6000")
    suite, summary = run(write_suite, tmp_path, text, workers=2)
    assert summary.ok == 3 and len(summary.failed) == 3
    assert {o.label.split()[0] for o in summary.failed} == {"mountaincar/die-state"}
    assert all(o.error == "the process running this cell exited with code 17 before reporting"
               for o in summary.failed)
    assert len(cell_files(tmp_path)) == 6


def test_a_process_lost_after_writing_its_result_keeps_it(write_suite, tmp_path):
    """A worker killed between writing its cell's file and telling the runner: the runner
    reads the outcome from the file rather than overwrite a finished curve with a failure.
    An earlier run's finished file (a --force rerun that died) is replaced, as a rerun that
    raises replaces it."""
    from datetime import UTC, datetime

    from senbench.run.execute import RunInfo, record_lost_cell

    before = datetime.now(UTC)
    suite, summary = run(write_suite, tmp_path, SARSA)
    cell, directory = suite.cells[0], tmp_path / "results" / "small" / "cells"
    path = directory / f"{cell.id}.parquet"
    finished, info = path.read_bytes(), RunInfo.gather(tmp_path / "encoders")
    own = record_lost_cell(cell, directory, info, "was killed by signal 9", since=before)
    assert (own.status, own.error) == ("ok", None) and path.read_bytes() == finished
    assert own.final_eval == read_results(tmp_path / "results" / "small").query(
        f"cell_id == '{cell.id}' and kind == 'eval'")["return"].iloc[-1]
    rerun = record_lost_cell(cell, directory, info, "was killed by signal 9",
                             since=datetime.now(UTC))
    assert rerun.status == "failed" and rerun.error.endswith("was killed by signal 9")
    assert finished_status(path) == "failed"


def test_a_lost_worker_is_judged_by_what_it_wrote_since_it_started(write_suite, tmp_path,
                                                                   test_agents, monkeypatch):
    """The runner hands record_lost_cell the time the cell's process started, so a file
    the process wrote before dying counts and an older one does not."""
    import senbench.run.processes as processes

    seen = []
    original = processes.record_lost_cell

    def spy(cell, directory, info, how, since=None):
        seen.append(since)
        return original(cell, directory, info, how, since)

    monkeypatch.setattr(processes, "record_lost_cell", spy)
    text = FAILING.replace("crash-state: {agent: crash, hyperparams: {after: 700}}",
                           "die-state: {agent: die}")
    started = datetime.now(UTC)
    _, summary = run(write_suite, tmp_path, text, workers=2)
    assert len(summary.failed) == 1 and len(seen) == 1
    assert started <= seen[0] <= datetime.now(UTC)


@pytest.mark.slow
def test_sigkill_then_rerun_gives_every_cell_exactly_once(write_suite, tmp_path, cli_env):
    suite_file = write_suite(SLOW)
    results = tmp_path / "results"
    command = [sys.executable, "-m", "senbench", "run", str(suite_file), "--workers", "2",
               "--results", str(results)]
    process = subprocess.Popen(command, env=cli_env, start_new_session=True,
                               stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    cells = results / "slow" / "cells"
    wait_for_files(cells, 2, process)
    workers = psutil.Process(process.pid).children(recursive=True)
    process.kill()  # the runner only: its workers notice and stop by themselves
    process.wait()
    _, alive = psutil.wait_procs(workers, timeout=10)
    assert alive == []
    finished = {f: f.read_bytes() for f in cells.glob("*.parquet")}
    assert 2 <= len(finished) < 6
    done = subprocess.run(command, env=cli_env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    assert f"{len(finished)} already done" in done.stdout
    files = sorted(cells.glob("*.parquet"))
    assert len(files) == 6 and not list(cells.glob(".*.tmp"))
    for path, content in finished.items():
        assert path.read_bytes() == content  # not recomputed
    assert all(finished_status(f) == "ok" for f in files)


@pytest.mark.slow
@pytest.mark.parametrize("how", ["ctrl-c", "sigterm"])
def test_ctrl_c_stops_cleanly_leaving_only_finished_cells(write_suite, tmp_path, cli_env, how):
    suite_file = write_suite(SLOW.replace("sleep_s: 0.002", "sleep_s: 0.004"))
    results = tmp_path / "results"
    command = [sys.executable, "-m", "senbench", "run", str(suite_file), "--workers", "2",
               "--results", str(results)]
    process = start_as_from_a_terminal(command, cli_env)
    cells = results / "slow" / "cells"
    wait_for_files(cells, 1, process)
    stop(process, how)
    stdout, stderr = process.communicate(timeout=60)
    assert process.returncode == 130, stdout + stderr
    assert "Traceback" not in stderr and "run the same command again to resume" in stderr, stderr
    files = list(cells.glob("*.parquet"))
    assert 1 <= len(files) < 6
    assert all(finished_status(f) == "ok" for f in files)
    assert not list(cells.glob(".*.tmp"))


def test_ctrl_c_while_the_fork_server_starts_prints_no_traceback(write_suite, tmp_path,
                                                                   cli_env):
    """The fork server imports torch for its first second or two; a Ctrl-C to the terminal's
    process group then printed the server's own KeyboardInterrupt traceback under the
    runner's clean stop."""
    command = [sys.executable, "-m", "senbench", "run", str(write_suite(SLOW)), "--workers",
               "2", "--results", str(tmp_path / "results")]
    process = start_as_from_a_terminal(command, cli_env)
    server = wait_for_fork_server(process)
    time.sleep(0.3)  # into its imports: torch alone takes longer
    assert server.is_running()
    stop(process, "ctrl-c")
    stdout, stderr = process.communicate(timeout=60)
    assert process.returncode == 130, stdout + stderr
    assert "Traceback" not in stderr and "KeyboardInterrupt" not in stderr, stderr


@pytest.mark.slow
@pytest.mark.parametrize("workers", [1, 2])
def test_sys_exit_in_an_agent_fails_that_cell_only(write_suite, tmp_path, test_agents, workers):
    text = FAILING.replace("crash-state: {agent: crash, hyperparams: {after: 700}}",
                           "exit-state: {agent: exit}")
    _, summary = run(write_suite, tmp_path, text, workers=workers)
    assert summary.ok == 1 and len(summary.failed) == 1
    assert "SystemExit: 3" in summary.failed[0].error


@pytest.mark.slow
def test_cells_fail_rather_than_hang_when_a_plugin_cannot_be_imported_by_workers(
        write_suite, tmp_path):
    import types

    from senbench.plugin import manager as plugins

    module = types.ModuleType("a_module_that_is_nowhere")
    module.register_agents = plugin_for_tests.register_agents
    plugins.register_plugin(module, distribution="senbench-notebook")
    try:
        _, summary = run(write_suite, tmp_path, FAILING, workers=2)
    finally:
        plugins.unregister_plugin(module)
    assert summary.ok == 0 and len(summary.failed) == 2
    assert all("exited with code 1" in o.error for o in summary.failed)


def test_results_folder_that_is_a_file_is_a_clear_error(write_suite, tmp_path):
    from senbench.errors import SenbenchError

    (tmp_path / "results").write_text("not a folder")
    with pytest.raises(SenbenchError, match="cannot write results"):
        run(write_suite, tmp_path, SARSA)


def test_without_ray_the_ray_executor_is_a_clear_error_and_nothing_is_written(
        write_suite, tmp_path, monkeypatch):
    suite = load_suite(write_suite(SARSA), registries())
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray now raises ImportError
    with pytest.raises(SenbenchError, match=r"pip install 'senbench\[ray\]'"):
        run_suite(suite, tmp_path / "results", executor="ray")
    assert not (tmp_path / "results").exists()


TWO_METHODS = SARSA.replace("seeds: 3", "seeds: 2").replace(
    "  sarsa-state: {agent: sarsa}\n",
    "  sarsa-state: {agent: sarsa}\n  sarsa-fast: {agent: sarsa, hyperparams: {alpha: 0.5}}\n")
SWEPT = TWO_METHODS + "variants:\n  sarsa-fast:\n    hyperparams.trace_decay: [0.8, 0.9]\n"


@pytest.mark.slow
def test_method_and_seed_options_run_only_that_part_of_the_grid(write_suite, tmp_path,
                                                                   cli_env):
    suite_file = write_suite(TWO_METHODS)
    suite = load_suite(suite_file, registries())
    results = tmp_path / "results"
    command = [sys.executable, "-m", "senbench", "run", str(suite_file), "--results",
               str(results)]
    wrong = subprocess.run([*command, "--method", "sarsa-fats"], env=cli_env,
                           capture_output=True, text=True, timeout=300)
    assert wrong.returncode != 0 and "has no method 'sarsa-fats'" in wrong.stderr
    assert not results.exists()
    done = subprocess.run([*command, "--method", "sarsa-fast", "--seed", "1"], env=cli_env,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "1 finished, 0 failed, 0 already done, of 1 cells (picked from 4)" in done.stdout
    picked = [c.id for c in suite.cells if c.method == "sarsa-fast" and c.seed == 1]
    assert [f.stem for f in cell_files(tmp_path)] == picked
    # The manifest is the whole suite's: report still counts the others as this version's.
    assert current_cells(results / "small") == {c.id for c in suite.cells}
    first = cell_files(tmp_path)[0].read_bytes()

    _, summary = run(write_suite, tmp_path, TWO_METHODS)  # the rest, by resume
    assert summary.skipped == 1 and summary.ok == 3
    assert cell_files(tmp_path)[[c.stem for c in cell_files(tmp_path)].index(picked[0])] \
        .read_bytes() == first


@pytest.mark.parametrize("option, value, message", [
    ("--method", "sarsa", "has no method 'sarsa'; it has: sarsa-fast, sarsa-state"),
    ("--env", "pendulum", "has no env 'pendulum'; it has: mountaincar"),
    ("--seed", "5", "has no seed 5; it has: 0, 1"),
    ("--variant", "hyperparams.trace_decay=0.7", "has no variant "
     "'hyperparams.trace_decay=0.7'; it has: hyperparams.trace_decay=0.8, "
     "hyperparams.trace_decay=0.9"),
])
def test_picking_what_the_suite_lacks_is_a_clear_error(write_suite, option, value, message):
    suite = load_suite(write_suite(SWEPT), registries())
    picked = {option.lstrip("-") + "s": [int(value) if option == "--seed" else value]}
    with pytest.raises(SenbenchError, match=re.escape(message)):
        suite.select(**picked)


def test_variant_and_method_pick_together(write_suite):
    suite = load_suite(write_suite(SWEPT), registries())
    picked = suite.select(methods=["sarsa-fast"], variants=["hyperparams.trace_decay=0.9"])
    assert [(c.method, c.variant, c.seed) for c in picked] == [
        ("sarsa-fast", "hyperparams.trace_decay=0.9", 0),
        ("sarsa-fast", "hyperparams.trace_decay=0.9", 1)]
    assert len(suite.select(seeds=[1])) == 3  # sarsa-state and both variants of sarsa-fast
    with pytest.raises(SenbenchError, match="no cell that is of the picked methods"):
        suite.select(methods=["sarsa-state"], variants=["hyperparams.trace_decay=0.9"])
    unswept = load_suite(write_suite(TWO_METHODS, "unswept.yaml"), registries())
    with pytest.raises(SenbenchError, match="suite 'small' has no variants$"):
        unswept.select(variants=["hyperparams.trace_decay=0.9"])
