"""``senbench run --executor ray``: cells as Ray tasks on a local instance of 2 CPUs."""

import os
import subprocess
import sys
import time
import types
from pathlib import Path

import pandas as pd
import psutil
import pytest
from stopping import start_as_from_a_terminal, stop, wait_for_files
from suites_for_tests import SEN_SARSA, SLOW

from senbench.cli.progress import GridProgress
from senbench.errors import SenbenchError
from senbench.plugin import manager as plugins
from senbench.plugin.manager import registries
from senbench.results.store import finished_status, read_results
from senbench.run.runner import run_suite
from senbench.suite import load_suite

ray = pytest.importorskip("ray", reason="Ray is not installed: pip install 'senbench[ray]'")

TESTS = Path(__file__).parent

# SARSA on the state and on a tiny encoder's estimate (the encoder is trained once by the
# driver and shipped to the workers), 2 seeds each.
TINY = """\
name: tiny
envs:
  mountaincar: {}
methods:
  sarsa-state:
    agent: sarsa
""" + SEN_SARSA + """seeds: 2
budget: 2000
eval: {every: 500, episodes: 2}
"""


def curves(folder: Path) -> pd.DataFrame:
    rows = read_results(folder)
    rows = rows[rows["kind"] != "cell"]
    return rows.sort_values(["cell_id", "kind", "step"])[
        ["cell_id", "method", "seed", "kind", "step", "return", "length"]].reset_index(drop=True)


# The CLI tests come first, before the module's shared instance exists: the CLI starts a
# local instance of its own for the run and stops it.
@pytest.mark.slow
def test_a_grid_on_ray_matches_the_serial_run_cell_for_cell_and_resumes(tmp_path,
                                                                        monkeypatch):
    (tmp_path / "tiny.yaml").write_text(TINY)
    suite = load_suite(tmp_path / "tiny.yaml", registries())
    serial = run_suite(suite, tmp_path / "serial")
    assert serial.ok == 4

    command = [sys.executable, "-m", "senbench", "run", str(tmp_path / "tiny.yaml"),
               "--executor", "ray", "--workers", "2", "--results", str(tmp_path / "ray")]
    env = {**os.environ, "SENBENCH_RAY_NODE_CACHE": str(tmp_path / "node")}
    done = subprocess.run(command, capture_output=True, text=True, env=env)
    assert done.returncode == 0, done.stderr
    assert "4 finished, 0 failed" in done.stdout
    # the same seeds give the same curves, evaluation by evaluation, episode by episode
    pd.testing.assert_frame_equal(curves(tmp_path / "serial" / "tiny"),
                                  curves(tmp_path / "ray" / "tiny"))
    assert set(read_results(tmp_path / "ray" / "tiny")["status"]) == {"ok"}
    # the encoder was trained once, by the driver, and the workers were sent its weights:
    # they loaded them, and trained nothing (training would leave its curves and traces)
    (trained,) = [p for p in (tmp_path / "ray" / "encoders").iterdir() if p.is_dir()]
    (sent,) = [p for p in (tmp_path / "node").iterdir() if p.is_dir()]
    assert sent.name == trained.name
    assert sorted(p.name for p in sent.iterdir()) == ["model.pt", "spec.json"]

    # resume (in this process, through the API): a lost cell is the only one run again, on a
    # local instance started and stopped for the run
    cells = sorted((tmp_path / "ray" / "tiny" / "cells").glob("*.parquet"))
    cells[0].unlink()
    monkeypatch.setenv("SENBENCH_RAY_NODE_CACHE", str(tmp_path / "node"))
    again = run_suite(suite, tmp_path / "ray", executor="ray", workers=2)
    assert (again.skipped, again.ok, again.failed) == (3, 1, [])
    assert not ray.is_initialized()
    pd.testing.assert_frame_equal(curves(tmp_path / "serial" / "tiny"),
                                  curves(tmp_path / "ray" / "tiny"))



@pytest.mark.slow
@pytest.mark.parametrize("how", ["ctrl-c", "sigterm"])
def test_stopping_a_ray_run_stops_its_tasks_leaving_only_finished_cells(tmp_path, cli_env,
                                                                          how):
    (tmp_path / "slow.yaml").write_text(SLOW.replace("sleep_s: 0.002", "sleep_s: 0.004"))
    cells = tmp_path / "results" / "slow" / "cells"
    command = [sys.executable, "-m", "senbench", "run", str(tmp_path / "slow.yaml"),
               "--executor", "ray", "--workers", "2", "--results", str(tmp_path / "results")]
    process = start_as_from_a_terminal(command, cli_env)
    wait_for_files(cells, 1, process, timeout=120)
    ray_processes = psutil.Process(process.pid).children(recursive=True)
    stop(process, how)
    stdout, stderr = process.communicate(timeout=60)
    assert process.returncode == 130, stdout + stderr
    assert "run the same command again to resume" in stderr, stderr
    files = list(cells.glob("*.parquet"))
    assert 1 <= len(files) < 6
    assert all(finished_status(f) == "ok" for f in files)
    assert not list(cells.glob(".*.tmp"))
    # the local instance went with the run: no worker is left computing a cell
    _, alive = psutil.wait_procs(ray_processes, timeout=20)
    assert not alive, [p.cmdline() for p in alive]


@pytest.fixture(scope="module")
def local_ray():
    """One local instance for the tests below; its workers import tests/plugin_for_tests.py."""
    ray.init(address="local", num_cpus=2, include_dashboard=False, log_to_driver=False,
             object_store_memory=128 * 1024**2,
             runtime_env={"env_vars": {"PYTHONPATH": str(TESTS)}})
    yield
    ray.shutdown()


DIES = """\
name: dies
envs:
  mountaincar: {{}}
methods:
  die-state:
    agent: die-times
    hyperparams: {{times: {times}, after: {after}, counter: "{counter}"}}
  sarsa-state: {{agent: sarsa}}
seeds: 1
budget: 600
eval: {{every: 300, episodes: 1}}
"""


def dies(tmp_path, times, after=10**9):
    counter = tmp_path / "attempts"
    (tmp_path / "s.yaml").write_text(DIES.format(times=times, after=after, counter=counter))
    return load_suite(tmp_path / "s.yaml", registries()), counter


def attempts(counter: Path) -> int:
    return len(counter.read_text().splitlines())


@pytest.mark.slow
def test_a_cell_whose_worker_is_killed_is_retried(local_ray, test_agents, tmp_path):
    suite, counter = dies(tmp_path, times=1)
    summary = run_suite(suite, tmp_path / "results", executor="ray", retries=1)
    assert attempts(counter) == 2  # the first attempt killed its worker; Ray ran it again
    assert summary.ok == 2 and not summary.failed
    rows = read_results(tmp_path / "results" / "dies")
    assert set(rows["status"]) == {"ok"}
    assert rows[rows["kind"] == "eval"].groupby("method")["step"].max().to_dict() == {
        "die-state": 600, "sarsa-state": 600}


@pytest.mark.slow
def test_a_cell_that_dies_every_time_is_recorded_failed_after_its_retries(
        local_ray, test_agents, tmp_path):
    suite, counter = dies(tmp_path, times=99)
    summary = run_suite(suite, tmp_path / "results", executor="ray", retries=2)
    assert attempts(counter) == 3  # bounded: once, then 2 retries
    assert summary.ok == 1
    (failed,) = summary.failed
    assert failed.label.startswith("mountaincar/die-state")
    assert "was lost on Ray" in failed.error and "retried up to 2 times" in failed.error
    rows = read_results(tmp_path / "results" / "dies")
    lost = rows[rows["method"] == "die-state"]
    assert list(lost["status"]) == ["failed"] and list(lost["kind"]) == ["cell"]  # no curve
    # the failed cell is tried again on the next run; the finished one is not
    again = run_suite(suite, tmp_path / "results", executor="ray", retries=0)
    assert again.skipped == 1 and len(again.failed) == 1
    assert attempts(counter) == 4


@pytest.mark.slow
def test_an_agent_error_is_a_failed_cell_not_a_retry(local_ray, test_agents, tmp_path):
    suite, counter = dies(tmp_path, times=0, after=10)
    summary = run_suite(suite, tmp_path / "results", executor="ray", retries=3)
    (failed,) = summary.failed
    assert "crashed on purpose at frame 10" in failed.error
    assert attempts(counter) == 1


@pytest.mark.slow
def test_an_error_before_the_cell_runs_is_recorded_with_its_cause(local_ray, tmp_path):
    (tmp_path / "s.yaml").write_text(TINY.replace("seeds: 2", "seeds: 1"))
    suite = load_suite(tmp_path / "s.yaml", registries())
    # a plugin registered here that the workers cannot import
    module = types.ModuleType("senbench_plugin_only_on_the_driver")
    plugins.register_plugin(module, distribution="notebook")
    try:
        summary = run_suite(suite, tmp_path / "results", executor="ray", retries=2)
    finally:
        plugins.unregister_plugin(module)
    assert len(summary.failed) == 2
    assert all("raised on Ray: ModuleNotFoundError" in o.error and
               "senbench_plugin_only_on_the_driver" in o.error for o in summary.failed)


@pytest.mark.slow
def test_cells_needing_more_cpus_than_any_node_are_refused_not_left_pending(local_ray,
                                                                           tmp_path):
    (tmp_path / "s.yaml").write_text(TINY + "threads: 4\n")
    suite = load_suite(tmp_path / "s.yaml", registries())
    with pytest.raises(SenbenchError, match="need 4 CPUs .* largest Ray node has 2"):
        run_suite(suite, tmp_path / "results", executor="ray")
    assert not list((tmp_path / "results" / "tiny" / "cells").glob("*.parquet"))


class StopAtFirstStart(GridProgress):
    """Ctrl-C as soon as a cell has started."""

    def started(self, cell_id, label, budget):
        raise KeyboardInterrupt


@pytest.mark.slow
def test_an_interrupt_cancels_the_tasks_on_a_cluster_it_did_not_start(local_ray, test_agents,
                                                                      tmp_path):
    # On a cluster it joined, the runner cannot rely on shutting Ray down: it must cancel.
    (tmp_path / "slow.yaml").write_text(SLOW.replace("sleep_s: 0.002", "sleep_s: 0.05"))
    suite = load_suite(tmp_path / "slow.yaml", registries())  # 30 s a cell
    summary = run_suite(suite, tmp_path / "results", executor="ray",
                        progress=StopAtFirstStart(None))
    assert summary.interrupted
    deadline = time.time() + 15
    while ray.available_resources().get("CPU", 0) < 2:  # the cancelled cells free their CPUs
        assert time.time() < deadline, ray.available_resources()
        time.sleep(0.2)
    assert not list((tmp_path / "results" / "slow" / "cells").glob("*.parquet"))


@pytest.mark.slow
def test_address_without_the_ray_executor_is_refused(tmp_path):
    (tmp_path / "s.yaml").write_text(TINY)
    done = subprocess.run([sys.executable, "-m", "senbench", "run", str(tmp_path / "s.yaml"),
                           "--address", "auto", "--results", str(tmp_path / "r")],
                          capture_output=True, text=True)
    assert done.returncode == 2
    assert "--executor ray" in done.stderr
    assert not (tmp_path / "r").exists()

