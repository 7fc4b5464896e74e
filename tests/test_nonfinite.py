"""No silent NaNs: a cell whose observations, actions, rewards or returns become NaN or
infinite fails, with a message naming what, where, and the likely cause."""

import gymnasium
import numpy as np
import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

from senbench.cli.app import app
from senbench.errors import NonFiniteError
from senbench.plugin.manager import registries
from senbench.run.evaluation import CellRecorder, Evaluator
from senbench.run.runner import run_suite
from senbench.suite import load_suite


class GoesBad(gymnasium.Env):
    """Observations (or rewards) turn NaN (or infinite) after ``after`` steps."""

    observation_space = gymnasium.spaces.Box(-np.inf, np.inf, (2,), np.float32)
    action_space = gymnasium.spaces.Discrete(2)

    def __init__(self, after: int, observation: float = 0.0, reward: float = 0.0):
        self.after, self.bad_obs, self.bad_reward, self.t = after, observation, reward, 0

    def reset(self, *, seed=None, options=None):
        self.t = 0
        return np.zeros(2, np.float32), {}

    def step(self, action):
        self.t += 1
        late = self.t >= self.after
        obs = np.full(2, self.bad_obs if late else 0.0, np.float32)
        return obs, (self.bad_reward if late else -1.0), False, self.t >= 10, {}


def test_nan_observations_fail_the_evaluation_naming_the_cause():
    with pytest.raises(NonFiniteError) as info:
        Evaluator(GoesBad(3, observation=np.nan), 1, 0)(lambda obs: 0)
    assert str(info.value).startswith(
        "the observation is nan at step 3 of evaluation episode 1: the agent's observations "
        "contain NaN or infinity — is the env's observation space unbounded")


def test_infinite_rewards_fail_the_evaluation():
    with pytest.raises(NonFiniteError, match="the reward is infinite at step 4 of evaluation "
                       "episode 1: the env's reward is NaN or infinite"):
        Evaluator(GoesBad(5, reward=-np.inf), 1, 0)(lambda obs: 0)
    Evaluator(GoesBad(11, observation=np.nan), 1, 0)(lambda obs: 0)  # never reached: fine


def test_the_recorder_names_the_frame():
    recorder = CellRecorder(10_000, 1000, lambda: {"return": 0.0})
    recorder.step(0)
    with pytest.raises(NonFiniteError, match="^episode return is nan at frame 1,234: "):
        recorder.episode(1234, float("nan"), 200)
    recorder.evaluate = lambda: Evaluator(GoesBad(2, observation=np.nan), 1, 0)(lambda o: 0)
    with pytest.raises(NonFiniteError, match="^evaluation at frame 1,000: the observation is "
                       "nan at step 2 of evaluation episode 1"):
        recorder.step(1000)
    recorder.evaluate = lambda: {"return": float("nan")}
    with pytest.raises(NonFiniteError, match="^evaluation return is nan at frame 2,000"):
        recorder.step(2000)


NAN = """\
name: nan
envs:
  mountaincar: {}
  pendulum: {}
methods:
  nan-return: {agent: nan, envs: [mountaincar]}
  nan-action: {agent: nan, envs: [pendulum], hyperparams: {what: action}}
seeds: 1
budget: 600
eval: {every: 300, episodes: 1}
"""


@pytest.mark.slow
def test_a_cell_gone_nan_is_recorded_failed_with_why_and_reported(write_suite, tmp_path,
                                                                  test_agents):
    suite = load_suite(write_suite(NAN), registries())
    summary = run_suite(suite, tmp_path)
    assert summary.ok == 0 and len(summary.failed) == 2
    errors = {o.label.split()[0]: o.error for o in summary.failed}
    assert errors["mountaincar/nan-return"] == (
        "NonFiniteError: episode return is nan at frame 300: the env's rewards, or the "
        "agent's sum of them, are NaN or infinite — are the env's observations or rewards "
        "unbounded, or did the agent's learning diverge?")
    assert errors["pendulum/nan-action"].startswith(
        "NonFiniteError: evaluation at frame 300: the agent's action is nan at step 0 of "
        "evaluation episode 1: the agent's policy outputs NaN")
    for cell in suite.cells:
        table = pq.read_table(tmp_path / "nan" / "cells" / f"{cell.id}.parquet").to_pandas()
        assert set(table["status"]) == {"failed"}
        assert list(table.loc[table["kind"] == "eval", "step"]) == [0]  # rows before it
    report = CliRunner().invoke(app, ["report", str(tmp_path / "nan")])
    assert "0 / 1" in report.output, report.output  # seeds ok / failed
