"""senbench tune stopped mid-trial, by Ctrl-C or by SIGTERM (what a batch scheduler sends):
the running trial is marked failed at once, not left RUNNING until the next process starts,
and the command says how to go on."""

import sys
import time

import optuna
import pytest
from stopping import start_as_from_a_terminal, stop, wait_for_files

SLOW_TUNE = """\
name: slow
envs:
  mountaincar: {}
methods:
  slow-state: {agent: slow}
seeds: 1
budget: 1000
eval: {every: 500, episodes: 1}
tune:
  slow-state:
    sleep_s: {low: 0.01, high: 0.011}
"""


@pytest.mark.slow
@pytest.mark.parametrize("how", ["ctrl-c", "sigterm"])
def test_a_stopped_study_fails_its_running_trial_at_once(write_suite, tmp_path, cli_env, how):
    suite_file = write_suite(SLOW_TUNE)
    results = tmp_path / "results"
    command = [sys.executable, "-m", "senbench", "tune", str(suite_file), "--trials", "2",
               "--seeds", "2", "--workers", "1", "--results", str(results)]
    process = start_as_from_a_terminal(command, cli_env)
    trial = results / "slow" / "tune" / "slow-state-mountaincar-auc" / "trial-0" / "cells"
    wait_for_files(trial, 1, process)  # its first seed has finished, the second runs
    time.sleep(0.5)
    stop(process, how)
    stdout, stderr = process.communicate(timeout=60)
    assert process.returncode == 130, stdout + stderr
    assert "Traceback" not in stderr and "run the same command again" in stderr, stderr
    study = optuna.load_study(study_name="slow-state-mountaincar-auc",
                              storage=f"sqlite:///{results / 'slow' / 'tune.db'}")
    assert [t.state.name for t in study.trials] == ["FAIL"]
    assert "trial 0: stopped, marked failed" in stderr
    assert len(list(trial.glob("*.parquet"))) == 1  # the second seed's cell writes nothing
    assert not list(trial.glob(".*.tmp"))
