"""run --time-limit: a cell starts only if its method's finished cells say it will fit."""

import subprocess
import sys
import time

import pytest

from senbench.errors import SenbenchError
from senbench.plugin.manager import registries
from senbench.results.store import cells_dir, finished_status, write_cell
from senbench.run import schedule as schedule_module
from senbench.run.claims import CellClaims
from senbench.run.runner import run_suite
from senbench.run.schedule import Schedule, parse_duration
from senbench.suite import load_suite

# A slow method (≈ 2.4 s a cell: 600 frames of 4 ms) beside a fast one (well under 1 s).
MIXED = """\
name: mixed
envs:
  mountaincar: {}
methods:
  slow-state: {agent: slow, hyperparams: {sleep_s: 0.004}}
  sarsa-state: {agent: sarsa}
seeds: 3
budget: 600
eval: {every: 300, episodes: 1}
"""


@pytest.mark.parametrize("text, seconds", [
    ("2h30m", 9000), ("150m", 9000), ("90s", 90), ("1.5h", 5400), ("1h 5m 3s", 3903)])
def test_durations_read_as_written(text, seconds):
    assert parse_duration(text) == seconds


@pytest.mark.parametrize("text", ["", "90", "ten minutes", "0s", "5m2h"])
def test_a_bad_duration_says_how_to_write_one(text):
    with pytest.raises(SenbenchError, match="2h30m|more than 0"):
        parse_duration(text)


def test_a_cell_that_would_not_fit_is_passed_over_for_one_that_does(
        write_suite, test_agents, monkeypatch):
    suite = load_suite(write_suite(MIXED), registries())
    slow = [c for c in suite.cells if c.method == "slow-state"]
    fast = [c for c in suite.cells if c.method == "sarsa-state"]
    clock = [1000.0]
    monkeypatch.setattr(schedule_module.time, "monotonic", lambda: clock[0])
    plan = Schedule(slow + fast, limit_s=100)
    assert plan.next() is slow[0]  # nothing known yet: it starts while time is left...
    assert plan.next() is fast[0]  # ...but only one cell of a combination with no time
    assert plan.next() is None
    plan.finished(slow[0], "ok", 95.0)
    assert plan.next() is None  # 95 s × 1.1 does not fit in 100 s; fast[0] still runs
    plan.finished(fast[0], "failed", 500.0)  # a failed cell says nothing about the time
    assert plan.next() is fast[1]
    plan.finished(fast[1], "ok", 1.0)
    clock[0] += 50
    assert plan.next() is fast[2]
    clock[0] += 50  # the limit is reached: nothing more starts
    assert plan.next() is None
    assert list(plan.waiting) == slow[1:]
    unlimited = Schedule(slow + fast)
    assert [unlimited.next() for _ in range(6)] == slow + fast and unlimited.next() is None


def slow_cells(write_suite, tmp_path):
    """MIXED's three slow cells, and an empty cells folder for their files."""
    suite = load_suite(write_suite(MIXED), registries())
    cells = tmp_path / "cells"
    cells.mkdir()
    return [c for c in suite.cells if c.method == "slow-state"], cells


def write_done(cells, cell, status, wall_s):
    write_cell(cells, cell.id, [{"cell_id": cell.id, "kind": "cell", "status": status,
                                 "cell_wall_s": wall_s}])


def test_a_cell_another_run_finished_gives_its_combination_time(
        write_suite, test_agents, tmp_path, monkeypatch):
    slow, cells = slow_cells(write_suite, tmp_path)
    monkeypatch.setattr(schedule_module.time, "monotonic", lambda: 1000.0)
    plan = Schedule(slow, limit_s=100, claims=CellClaims(cells))
    # another run of the suite finished the first cell since this run started, in 95 s
    write_done(cells, slow[0], "ok", 95.0)
    assert plan.next() is None  # its time counts: 95 s × 1.1 does not fit in 100 s
    assert plan.elsewhere == [slow[0].id] and list(plan.waiting) == slow[1:]


def test_a_cell_finished_before_the_schedule_was_made_counts_once(
        write_suite, test_agents, tmp_path, monkeypatch):
    suite = load_suite(write_suite(MIXED), registries())
    slow = [c for c in suite.cells if c.method == "slow-state"]
    cells = cells_dir(tmp_path, suite.name)
    cells.mkdir(parents=True)
    for cell, wall in ((slow[0], 10.0), (slow[1], 95.0)):
        write_done(cells, cell, "ok", wall)
    # slow[1] was to run, but another run finished it while this one trained its encoders
    plan = Schedule(slow[1:], limit_s=1000, suite=suite, results_root=tmp_path,
                    claims=CellClaims(cells))
    assert plan.expected_s(slow[2]) == 52.5
    assert plan.next() is slow[2] and plan.elsewhere == [slow[1].id]
    assert plan.expected_s(slow[2]) == 52.5  # not (10 + 95 + 95) / 3
    plan.claims.release_all()


def held_then_written(write_suite, tmp_path, monkeypatch, status):
    """A schedule under a 100 s limit that passed over the first slow cell while another
    run computed it, started the second, and then saw the other run write the first with
    ``status`` in 95 s."""
    slow, cells = slow_cells(write_suite, tmp_path)
    monkeypatch.setattr(schedule_module.time, "monotonic", lambda: 1000.0)
    other = CellClaims(cells)
    assert other.take(slow[0].id)  # another run is computing the first cell
    plan = Schedule(slow, limit_s=100, claims=CellClaims(cells))
    assert plan.next() is slow[1]  # the first is passed over; the method's time is unknown
    write_done(cells, slow[0], status, 95.0)
    other.release(slow[0].id)
    return plan, slow


def test_a_cell_another_run_was_computing_gives_its_time_once_it_is_written(
        write_suite, test_agents, tmp_path, monkeypatch):
    plan, slow = held_then_written(write_suite, tmp_path, monkeypatch, "ok")
    plan.finished(slow[1], "failed", 5.0)  # no time from this run
    assert plan.next() is None  # the other run's 95 s count: 95 s × 1.1 does not fit in 100 s
    assert plan.expected_s(slow[2]) == 95.0 and list(plan.waiting) == [slow[2]]


def test_a_cell_another_run_failed_gives_no_time_and_is_read_once(
        write_suite, test_agents, tmp_path, monkeypatch):
    plan, slow = held_then_written(write_suite, tmp_path, monkeypatch, "failed")
    looked = []
    finished_elsewhere = plan.claims.finished_elsewhere
    monkeypatch.setattr(plan.claims, "finished_elsewhere",
                        lambda cell_id: looked.append(cell_id) or finished_elsewhere(cell_id))
    plan.finished(slow[1], "failed", 5.0)
    assert plan.next() is slow[2]  # a failure says nothing of the time: still unknown
    plan.finished(slow[2], "failed", 5.0)
    plan.waiting.append(slow[2])
    assert plan.next() is slow[2] and looked == [slow[0].id]  # unchanged since: not read again
    plan.claims.release_all()


def test_a_cell_that_had_failed_counts_when_another_run_finishes_it(
        write_suite, test_agents, tmp_path, monkeypatch):
    slow, cells = slow_cells(write_suite, tmp_path)
    write_done(cells, slow[0], "failed", 1.0)
    time.sleep(0.05)
    monkeypatch.setattr(schedule_module.time, "monotonic", lambda: 1000.0)
    plan = Schedule(slow, limit_s=100, claims=CellClaims(cells))  # to run again, as failed
    write_done(cells, slow[0], "ok", 95.0)  # another run got there first
    assert plan.next() is None and plan.expected_s(slow[1]) == 95.0


@pytest.mark.slow
@pytest.mark.parametrize("workers", [1, 2])
def test_a_time_limit_runs_what_fits_and_leaves_the_rest(write_suite, tmp_path, test_agents,
                                                         workers):
    suite = load_suite(write_suite(MIXED), registries())
    run_suite(suite, tmp_path, cells=suite.select(methods=["slow-state"], seeds=[0]))
    started = time.monotonic()
    summary = run_suite(suite, tmp_path, workers=workers, time_limit_s=1.5)
    # A slow cell is known to take ≈ 2.4 s: none starts. The sarsa cells start while time is
    # left (the first with no time known), so at least one runs.
    ran = {o.cell_id for o in summary.outcomes}
    assert not ran & {c.id for c in suite.cells if c.method == "slow-state"}
    assert ran and all(o.status == "ok" for o in summary.outcomes)
    assert summary.not_started == 5 - len(ran) >= 2
    assert time.monotonic() - started < 10
    again = run_suite(suite, tmp_path, workers=workers)
    assert again.not_started == 0 and again.skipped == 1 + len(ran) and not again.failed
    assert all(finished_status(tmp_path / "mixed" / "cells" / f"{c.id}.parquet") == "ok"
               for c in suite.cells)


@pytest.mark.slow
def test_the_cli_exits_75_when_the_time_limit_leaves_cells(write_suite, tmp_path, cli_env):
    suite_file = write_suite(MIXED)
    command = [sys.executable, "-m", "senbench", "run", str(suite_file), "--results",
               str(tmp_path), "--method", "slow-state"]
    first = subprocess.run([*command, "--seed", "0"], env=cli_env, capture_output=True,
                           text=True, timeout=300)
    assert first.returncode == 0, first.stdout + first.stderr
    done = subprocess.run([*command, "--time-limit", "1s"], env=cli_env, capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 75, done.stdout + done.stderr
    assert "time limit 1s: 2 cells not started" in done.stderr
    assert "run the same command again to go on" in done.stderr
    bad = subprocess.run([*command, "--time-limit", "soon"], env=cli_env, capture_output=True,
                         text=True, timeout=300)
    assert bad.returncode == 2 and "write it as 2h30m" in bad.stderr


@pytest.mark.slow
def test_a_failed_cell_makes_the_exit_1_even_with_cells_left(write_suite, tmp_path, cli_env):
    suite_file = write_suite(MIXED.replace(
        "  sarsa-state: {agent: sarsa}\n",
        "  crash-state: {agent: crash, hyperparams: {after: 5}}\n"))
    command = [sys.executable, "-m", "senbench", "run", str(suite_file), "--results",
               str(tmp_path)]
    first = subprocess.run([*command, "--method", "slow-state", "--seed", "0"], env=cli_env,
                           capture_output=True, text=True, timeout=300)
    assert first.returncode == 0, first.stdout + first.stderr
    done = subprocess.run([*command, "--time-limit", "1s"], env=cli_env, capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 1, done.stdout + done.stderr
    # The crash cells fail at once; how many start within the second depends on the machine.
    assert "0 failed" not in done.stdout and "cells not started" in done.stderr
