"""Several runs of one suite share its grid: a cell one run holds, another passes over."""

import os
import signal
import subprocess
import sys

import pytest
from suites_for_tests import SLOW

from senbench.cli.progress import GridProgress
from senbench.plugin.manager import registries
from senbench.results.store import cell_path, finished_status, write_cell
from senbench.run import claims as claims_module
from senbench.run.claims import CellClaims, lock_path, running_cells
from senbench.run.runner import run_suite
from senbench.suite import load_suite


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
    # written by another run since these runs started, even failed: theirs, not to redo
    write_cell(cells, "other", [{"cell_id": "other", "kind": "cell", "status": "failed"}])
    assert not forced.take("other")
    later = CellClaims(cells)  # a run started after it: a failed cell runs again
    assert later.take("other")
    later.release_all()


def test_a_killed_holder_holds_nothing(tmp_path):
    holder = subprocess.Popen(
        [sys.executable, "-c",
         "import sys, time; from pathlib import Path; from senbench.run.claims import CellClaims;"
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


def test_a_lock_is_taken_on_the_file_its_holder_did_not_remove(tmp_path, monkeypatch):
    holder, late, third = CellClaims(tmp_path), CellClaims(tmp_path), CellClaims(tmp_path)
    assert holder.take("a")
    real_flock = claims_module.fcntl.flock
    calls = []

    def flock_after_the_holder_let_go(fd, operation):
        calls.append(fd)
        if len(calls) == 1:
            holder.release("a")  # between late's open and its lock: late's file is gone
        return real_flock(fd, operation)

    monkeypatch.setattr(claims_module.fcntl, "flock", flock_after_the_holder_let_go)
    assert late.take("a")
    monkeypatch.setattr(claims_module.fcntl, "flock", real_flock)
    assert len(calls) == 2  # it locked the removed file, saw so, and locked the new one
    assert not third.take("a")  # without that check, late would hold a file nobody sees
    late.release_all()


def test_an_interrupted_run_lets_go_of_every_cell(write_suite, tmp_path, test_agents):
    suite = load_suite(write_suite(SLOW), registries())

    class Interrupting(GridProgress):
        def started(self, cell_id, label, budget):
            raise KeyboardInterrupt  # Ctrl-C once the first cell is locked

    summary = run_suite(suite, tmp_path, progress=Interrupting(None))
    assert summary.interrupted
    cells = tmp_path / "slow" / "cells"
    assert not list(cells.glob(".*.lock"))
    claims = CellClaims(cells)
    assert all(claims.take(c.id) for c in suite.cells)
    claims.release_all()


def _run_twice_at_once(command: list[str], env: dict) -> list[subprocess.CompletedProcess]:
    runs = [subprocess.Popen(command, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             text=True) for _ in range(2)]
    done = []
    for run in runs:
        out, err = run.communicate(timeout=300)
        done.append(subprocess.CompletedProcess(command, run.returncode, out, err))
    return done


def _done(run: subprocess.CompletedProcess) -> set[str]:
    return {line.split(",")[0].split(" (")[0].removeprefix("done ").strip()
            for line in run.stderr.splitlines() if line.startswith("done ")}


@pytest.mark.slow
@pytest.mark.parametrize("force", [False, True])
def test_two_runs_of_one_suite_at_once_compute_each_cell_once(write_suite, tmp_path, cli_env,
                                                              test_agents, force):
    suite_file = write_suite(SLOW)
    command = [sys.executable, "-m", "senbench", "run", str(suite_file), "--results",
               str(tmp_path)]
    if force:  # a finished grid, redone by two runs: each cell once, not twice
        first = subprocess.run(command, env=cli_env, capture_output=True, text=True,
                               timeout=300)
        assert first.returncode == 0, first.stdout + first.stderr
        command.append("--force")
    runs = _run_twice_at_once(command, cli_env)
    for run in runs:
        assert run.returncode == 0, run.stdout + run.stderr
    ran = [_done(run) for run in runs]
    assert not ran[0] & ran[1]  # without the locks, both runs compute every cell
    labels = {c.label for c in load_suite(suite_file, registries()).cells}
    assert ran[0] | ran[1] == labels
    assert any("left to another run" in run.stderr for run in runs)
    passed = [line for run in runs for line in run.stderr.splitlines()
              if line.startswith("elsewhere ")]
    assert passed and all("another run of this suite holds it" in line for line in passed)
    cells = tmp_path / "slow" / "cells"
    assert not list(cells.glob(".*.lock"))
    assert all(finished_status(path) == "ok" for path in cells.glob("*.parquet"))


@pytest.mark.slow
def test_the_cli_passes_over_a_held_cell_and_status_shows_it_running(
        write_suite, tmp_path, cli_env, test_agents):
    suite_file = write_suite(SLOW)
    suite = load_suite(suite_file, registries())
    held = suite.cells[1]
    cells = tmp_path / "slow" / "cells"
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
        assert (cells_, finished, failed, to_run, running) == ("6", "0", "", "6", "1")
        done = subprocess.run([*command, "run", str(suite_file), *where], env=cli_env,
                              capture_output=True, text=True, timeout=300)
        assert done.returncode == 0, done.stdout + done.stderr  # the holder will finish it
        assert "5 finished" in done.stdout
        assert "1 cells were left to another run of this suite; 1 are still running there" \
            in " ".join(done.stderr.split())
        assert finished_status(cell_path(cells, held.id)) is None
    finally:
        claims.release_all()  # the holder stops without writing the cell
    again = subprocess.run([*command, "run", str(suite_file), *where], env=cli_env,
                           capture_output=True, text=True, timeout=300)
    assert again.returncode == 0, again.stdout + again.stderr
    assert "1 finished" in again.stdout and "5 already done" in again.stdout


@pytest.mark.slow
def test_a_cell_another_run_left_unfinished_makes_the_exit_75(write_suite, tmp_path,
                                                              test_agents, monkeypatch):
    suite = load_suite(write_suite(SLOW), registries())
    cells = tmp_path / "slow" / "cells"
    cells.mkdir(parents=True)
    refused = suite.cells[2].id
    real_take = CellClaims.take
    monkeypatch.setattr(CellClaims, "take",  # held by a run that then stops without it
                        lambda self, cell_id: cell_id != refused and real_take(self, cell_id))
    summary = run_suite(suite, tmp_path)
    assert summary.elsewhere == [refused]
    assert (summary.elsewhere_running, summary.elsewhere_unfinished) == (0, 1)
