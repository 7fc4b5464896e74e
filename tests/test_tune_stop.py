"""senbench tune stopped mid-trial, by Ctrl-C or by SIGTERM (what a batch scheduler sends):
the running trial is marked failed at once, not left RUNNING until the next process starts,
and the command says how to go on."""

import os
import signal
import subprocess
import sys
import time

import optuna
import pytest

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
@pytest.mark.parametrize("stop", ["ctrl-c", "sigterm"])
def test_a_stopped_study_fails_its_running_trial_at_once(write_suite, tmp_path, cli_env, stop):
    suite_file = write_suite(SLOW_TUNE)
    results = tmp_path / "results"
    command = [sys.executable, "-m", "senbench", "tune", str(suite_file), "--trials", "2",
               "--seeds", "2", "--workers", "1", "--results", str(results)]
    process = subprocess.Popen(command, env=cli_env, start_new_session=True,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    trial = results / "slow" / "tune" / "slow-state-mountaincar-auc" / "trial-0" / "cells"
    deadline = time.time() + 90
    while not list(trial.glob("*.parquet")):  # its first seed has finished, the second runs
        assert process.poll() is None, process.communicate()
        assert time.time() < deadline, "the trial's first seed did not finish"
        time.sleep(0.05)
    time.sleep(0.5)
    if stop == "ctrl-c":
        os.killpg(process.pid, signal.SIGINT)
    else:
        process.terminate()
    stdout, stderr = process.communicate(timeout=60)
    assert process.returncode == 130, stdout + stderr
    assert "Traceback" not in stderr and "run the same command again" in stderr, stderr
    study = optuna.load_study(study_name="slow-state-mountaincar-auc",
                              storage=f"sqlite:///{results / 'slow' / 'tune.db'}")
    assert [t.state.name for t in study.trials] == ["FAIL"]
    assert "trial 0: stopped, marked failed" in stderr
    assert len(list(trial.glob("*.parquet"))) == 1  # the second seed's cell writes nothing
    assert not list(trial.glob(".*.tmp"))
