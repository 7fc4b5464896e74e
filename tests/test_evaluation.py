"""The evaluation protocol records what the policy did, and can evaluate ε-greedily."""

import json

import numpy as np
import pytest

from senbench.errors import SuiteError
from senbench.observe.observations import make_env
from senbench.plugin.manager import registries
from senbench.run.evaluation import Evaluator
from senbench.suite import load_suite

SUITE = """\
name: s
envs:
  mountaincar: {}
methods:
  sarsa-state: {agent: sarsa}
seeds: 1
budget: 1000
eval: {every: 500, episodes: 2%s}
"""


def evaluator(env: str, epsilon: float = 0.0, episodes: int = 2) -> Evaluator:
    spec = registries().envs.get(env)
    return Evaluator(make_env(spec, "state", 50, {}, None, None), episodes, 0, epsilon)


def test_a_greedy_evaluation_records_the_share_of_each_discrete_action():
    result = evaluator("mountaincar")(lambda obs: 2)
    assert result["action_share"] == [0.0, 0.0, 1.0]
    assert result["action_mean"] is None and result["length"] == 50.0


def test_a_continuous_policy_records_each_dimensions_mean_and_spread():
    flip = iter(np.tile([-1.0, 1.0], 1000))
    result = evaluator("pendulum")(lambda obs: np.array([next(flip)], dtype=np.float32))
    assert result["action_share"] is None
    assert result["action_mean"] == pytest.approx([0.0]) and result["action_std"] == [1.0]


def test_epsilon_greedy_evaluation_takes_random_actions_reproducibly():
    once = evaluator("mountaincar", epsilon=0.5)(lambda obs: 2)
    again = evaluator("mountaincar", epsilon=0.5)(lambda obs: 2)
    assert once == again  # seeded per episode: the same evaluation twice
    share = once["action_share"]
    # half the steps random over 3 actions: action 2 about 1/2 + 1/6, the others 1/6 each
    assert 0.5 < share[2] < 0.85 and share[0] > 0.05 and share[1] > 0.05
    assert evaluator("mountaincar", epsilon=1.0)(lambda obs: 2)["action_share"][2] < 0.6


def test_eval_epsilon_is_validated_recorded_and_left_out_of_ids_at_zero(write_suite):
    plain = load_suite(write_suite(SUITE % ""), registries()).cells[0]
    zero = load_suite(write_suite(SUITE % ", epsilon: 0.0"), registries()).cells[0]
    greedy5 = load_suite(write_suite(SUITE % ", epsilon: 0.05"), registries()).cells[0]
    assert plain.id == zero.id  # a new option at its neutral value moves no id
    assert greedy5.id != plain.id and greedy5.config()["eval"]["epsilon"] == 0.05
    assert json.loads(json.dumps(plain.config()))["eval"] == {"every": 500, "episodes": 2}
    with pytest.raises(SuiteError, match=r"suite.yaml:8: eval.epsilon: .*less than or equal"):
        load_suite(write_suite(SUITE % ", epsilon: 1.5"), registries())


@pytest.mark.slow
def test_report_shows_the_actions_of_each_method(write_suite, tmp_path):
    import os
    import subprocess
    import sys

    suite = write_suite(SUITE % "")
    run = subprocess.run([sys.executable, "-m", "senbench", "run", str(suite), "--results",
                          str(tmp_path / "r")], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    done = subprocess.run([sys.executable, "-m", "senbench", "report", str(tmp_path / "r/s"),
                           "--actions", "--at", "500"], capture_output=True, text=True,
                          env={**os.environ, "COLUMNS": "200"})
    assert done.returncode == 0, done.stderr
    assert "actions in evaluation episodes" in done.stdout
    assert "0: " in done.stdout and "last" in done.stdout and "500" in done.stdout


def test_epsilon_greedy_evaluation_draws_from_no_generator_training_uses():
    """controls-eval-epsilon pairs its evaluations with controls-pixels' greedy ones on this:
    with ε > 0 the agent still learns exactly as with greedy evaluation, so each evaluation
    plays the same network. SB3's DQN explores with numpy's global generator and samples
    with torch's; a DQN's greedy act and the evaluation's random actions touch neither."""
    import random

    import torch

    from senbench.plugin.specs import AgentContext

    spec, dqn = registries().envs.get("mountaincar"), registries().agents.get("dqn")
    ctx = AgentContext(dqn.config(), spec, lambda: make_env(spec, "state", 50, {}, None, None),
                       0, 1)
    agent = dqn.make(ctx)
    np.random.seed(1), random.seed(1), torch.manual_seed(1)
    before = (np.random.get_state()[1].copy(), random.getstate(), torch.get_rng_state())
    played = evaluator("mountaincar", epsilon=0.5)(agent.act)
    after = (np.random.get_state()[1], random.getstate(), torch.get_rng_state())
    assert played["action_share"] != [0.0, 0.0, 1.0] and max(played["action_share"]) < 0.9
    assert (before[0] == after[0]).all() and before[1] == after[1]
    assert torch.equal(before[2], after[2])
