"""Several runs of one suite share its grid: a cell one run holds, another passes over."""

import os
import signal
import subprocess
import sys
import threading

from senbench.claims import CellClaims, lock_path, running_cells
from senbench.plugins import registries
from senbench.results import cell_path, finished_status, write_cell
from senbench.runner import run_suite
from senbench.suite import load_suite

SLOW = """\
name: shared
envs:
  mountaincar: {}
methods:
  slow-state: {agent: slow, hyperparams: {sleep_s: 0.002}}
seeds: 4
budget: 400
eval: {every: 200, episodes: 1}
"""


def test_a_held_cell_is_refused_until_its_holder_lets_go(tmp_path):
    one, other = CellClaims(tmp_path), CellClaims(tmp_path)
    assert one.take("a") and not other.take("a")
    assert running_cells(tmp_path) == {"a"}  # this process holds it, and it is alive
    one.release("a")
    assert not lock_path(tmp_path, "a").exists() and running_cells(tmp_path) == set()
    assert other.take("a")
    other.release_all()


def test_a_cell_finished_meanwhile_is_refused_unless_forced(tmp_path):
    cells = tmp_path / "cells"
    cells.mkdir()
    write_cell(cells, "done", [{"cell_id": "done", "kind": "cell", "status": "ok"}])
    assert not CellClaims(cells).take("done")
    forced = CellClaims(cells, force=True)
    assert forced.take("done")
    forced.release_all()


def test_a_killed_holder_holds_nothing(tmp_path):
    holder = subprocess.Popen(
        [sys.executable, "-c",
         "import sys, time; from pathlib import Path; from senbench.claims import CellClaims;"
         f"assert CellClaims(Path({str(tmp_path)!r})).take('a'); print('held', flush=True);"
         "time.sleep(60)"],
        stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        assert running_cells(tmp_path) == {"a"}
        assert not CellClaims(tmp_path).take("a")
        os.kill(holder.pid, signal.SIGKILL)
        holder.wait(timeout=10)
        assert lock_path(tmp_path, "a").exists()  # left behind, but it stops nobody
        assert running_cells(tmp_path) == set()
        claims = CellClaims(tmp_path)
        assert claims.take("a")
        claims.release_all()
    finally:
        holder.kill()


def test_two_runs_of_one_suite_compute_each_cell_once(write_suite, tmp_path, test_agents):
    suite = load_suite(write_suite(SLOW), registries())
    start = threading.Barrier(2)
    summaries = [None, None]

    def run(i: int) -> None:
        start.wait()
        summaries[i] = run_suite(suite, tmp_path / "results")

    threads = [threading.Thread(target=run, args=(i,)) for i in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=120)
    ran = [{o.cell_id for o in s.outcomes} for s in summaries]
    assert not ran[0] & ran[1]  # without the locks, both runs compute every cell
    assert ran[0] | ran[1] == {c.id for c in suite.cells}
    assert all(o.status == "ok" for s in summaries for o in s.outcomes)
    assert summaries[0].elsewhere or summaries[1].elsewhere
    assert not list((tmp_path / "results" / "shared" / "cells").glob(".*.lock"))


def test_the_cli_leaves_a_held_cell_exits_75_and_status_shows_it_running(
        write_suite, tmp_path, cli_env, test_agents):
    suite_file = write_suite(SLOW)
    suite = load_suite(suite_file, registries())
    held = suite.cells[1]
    cells = tmp_path / "shared" / "cells"
    cells.mkdir(parents=True)
    claims = CellClaims(cells)  # another run, in this process, holds one cell
    assert claims.take(held.id)
    command = [sys.executable, "-m", "senbench"]
    where = ["--results", str(tmp_path)]
    try:
        status = subprocess.run([*command, "status", str(suite_file), *where], env=cli_env,
                                capture_output=True, text=True, timeout=300)
        assert status.returncode == 0, status.stdout + status.stderr
        row = next(line for line in status.stdout.splitlines() if "slow-state" in line)
        cells_, finished, failed, to_run, running = [c.strip() for c in row.split("│")][3:8]
        assert (cells_, finished, failed, to_run, running) == ("4", "0", "", "4", "1")
        done = subprocess.run([*command, "run", str(suite_file), *where], env=cli_env,
                              capture_output=True, text=True, timeout=300)
        assert done.returncode == 75, done.stdout + done.stderr
        assert "3 finished" in done.stdout
        assert "1 cells were left to another run of this suite that held them; 1 of them had " \
               "not finished" in " ".join(done.stderr.split())
        assert finished_status(cell_path(cells, held.id)) is None
    finally:
        claims.release_all()
    again = subprocess.run([*command, "run", str(suite_file), *where], env=cli_env,
                           capture_output=True, text=True, timeout=300)
    assert again.returncode == 0, again.stdout + again.stderr
    assert "1 finished" in again.stdout and "3 already done" in again.stdout
