"""An env's action_repeat: each action held k frames, the agent counting decisions, the
budget, evaluations, curves and episode lengths counting frames."""

import json

import numpy as np
import pytest

from senbench.errors import SuiteError
from senbench.observe.observations import make_env
from senbench.observe.pixels import PixelSpec
from senbench.plugin.manager import registries
from senbench.results.store import read_results
from senbench.run.evaluation import Evaluator
from senbench.run.runner import run_suite
from senbench.suite import Cell, load_suite

SUITE = """\
name: repeat
envs:
  mountaincar: {%s}
methods:
  sarsa-state: {agent: sarsa}
seeds: 1
budget: %d
eval: {every: %d, episodes: 2}
"""


def env(observation: str = "state", repeat: int = 1, cap: int = 50, stack: int = 2):
    spec = registries().envs.get("mountaincar")
    pixels = PixelSpec(height=32, width=32, stack=stack) if observation != "state" else None
    return make_env(spec, observation, cap, {}, pixels, None, repeat)


def test_an_action_is_held_for_k_frames_and_its_rewards_summed():
    held, single = env(repeat=4), env()
    first, _ = held.reset(seed=3)
    assert np.array_equal(first, single.reset(seed=3)[0])
    obs, reward, terminated, truncated, info = held.step(2)
    for _ in range(4):
        expected, *_ = single.step(2)
    assert np.array_equal(obs, expected)  # the physics of four frames, seen once
    assert reward == -4.0 and info["frames"] == 4 and not (terminated or truncated)


def test_an_episode_that_ends_inside_a_decision_stops_there():
    held = env(repeat=4, cap=10)  # 10 frames: decisions of 4, 4 and 2 frames
    held.reset(seed=0)
    steps = [held.step(0) for _ in range(3)]
    assert [s[4]["frames"] for s in steps] == [4, 4, 2]
    assert [s[1] for s in steps] == [-4.0, -4.0, -2.0] and steps[-1][3]


def test_a_pixel_stack_holds_the_frames_at_the_agents_decisions():
    spec = registries().envs.get("mountaincar")
    held = env("pixels", repeat=3)
    frames, info = held.reset(seed=1)
    before = info["state"]
    frames, _, _, _, info = held.step(2)
    drawn = spec.render(np.stack([before, info["state"]]), (32, 32))
    assert np.array_equal(frames, drawn)  # the oldest frame is the last decision's
    single = env("state")
    single.reset(seed=1)
    for _ in range(3):
        single.step(2)
    assert np.allclose(info["state"], single.unwrapped.state)


def test_evaluation_lengths_are_frames_and_action_shares_are_decisions():
    result = Evaluator(env(repeat=4, cap=50), 2, 0)(lambda obs: 2)
    assert result["length"] == 50.0  # 13 decisions, the last of 2 frames
    assert result["action_share"] == [0.0, 0.0, 1.0]


def load(write_suite, envs: str, budget: int = 1000, every: int = 500):
    return load_suite(write_suite(SUITE % (envs, budget, every)), registries())


def test_action_repeat_is_part_of_the_cell_and_left_out_of_its_id_at_one(write_suite):
    plain = load(write_suite, "").cells[0]
    one = load(write_suite, "action_repeat: 1").cells[0]
    four = load(write_suite, "action_repeat: 4").cells[0]
    assert plain.id == one.id and four.id != plain.id
    config = json.loads(json.dumps(four.config()))
    assert config["env"]["action_repeat"] == 4 and "action_repeat" not in plain.config()["env"]
    assert Cell.from_config(config, "repeat").id == four.id


@pytest.mark.parametrize("envs, budget, every, says", [
    ("action_repeat: 3", 1000, 500, r"suite.yaml:3: envs.mountaincar.action_repeat: .*its "
                                    r"budget \(1000 frames\) must be a multiple of 3"),
    ("action_repeat: 4", 1000, 250, r"its eval.every \(250 frames\) must be a multiple of 4"),
    ("action_repeat: 0", 1000, 500, r"envs.mountaincar.action_repeat: .*greater than or equal"),
    ("action_repeat: 17", 1000, 500, r"envs.mountaincar.action_repeat: .*less than or equal"),
    ("action_repeat: 4.0", 1000, 500, r"envs.mountaincar.action_repeat: .*valid integer"),
])
def test_a_repeat_that_does_not_fit_is_refused_with_its_line(write_suite, envs, budget, every,
                                                              says):
    with pytest.raises(SuiteError, match=says):
        load(write_suite, envs, budget, every)


def test_a_method_may_hold_its_actions_for_other_than_its_envs_repeat(write_suite):
    text = (SUITE % ("action_repeat: 4", 1000, 500)).replace(
        "seeds:", "  every-frame: {agent: sarsa, action_repeat: 1}\n"
                  "  pairs: {agent: sarsa, action_repeat: 2}\nseeds:")
    cells = {c.method: c for c in load_suite(write_suite(text), registries()).cells}
    assert {m: c.action_repeat for m, c in cells.items()} == {
        "sarsa-state": 4, "every-frame": 1, "pairs": 2}
    assert cells["every-frame"].id == load(write_suite, "").cells[0].id
    with pytest.raises(SuiteError, match=r"suite.yaml:7: methods.pairs.action_repeat: method "
                                         r"'pairs' holds each action 2 frames on mountaincar, "
                                         r"so its budget \(999 frames\)"):
        load_suite(write_suite(text.replace("budget: 1000", "budget: 999")), registries())


def test_an_encoded_method_takes_no_action_repeat(write_suite):
    from suites_for_tests import SEN_SARSA

    text = (SUITE % ("action_repeat: 2", 1000, 500)).replace("seeds:", SEN_SARSA + "seeds:")
    with pytest.raises(SuiteError, match=r"envs.mountaincar.action_repeat: method 'sen-sarsa' "
                                         r"observes through a state encoder"):
        load_suite(write_suite(text), registries())
    own = text.replace("    agent: sarsa\n    observation: encoded",
                       "    agent: sarsa\n    action_repeat: 1\n    observation: encoded")
    cells = load_suite(write_suite(own), registries()).cells  # its own repeat of 1 is fine
    assert {c.method: c.action_repeat for c in cells} == {"sarsa-state": 2, "sen-sarsa": 1}


def test_a_cell_learns_for_its_budget_in_frames_with_k_frames_a_decision(write_suite,
                                                                          tmp_path):
    suite = load(write_suite, "max_episode_steps: 202, action_repeat: 4",
                 budget=1200, every=400)
    summary = run_suite(suite, tmp_path / "results")
    assert summary.ok == 1 and not summary.failed, summary.failed
    rows = read_results(tmp_path / "results" / "repeat")
    evals = rows[rows["kind"] == "eval"]
    assert evals["step"].tolist() == [0, 400, 800, 1200]
    episodes = rows[rows["kind"] == "episode"]
    assert len(episodes) and (episodes["step"] % 4 == 0).all()
    # a 202-frame episode: 51 decisions, the last cut to 2 frames; counted whole in training
    assert set(episodes["length"]) <= set(np.arange(4, 205, 4).astype(float))
    assert (evals["length"] <= 202).all() and (evals["length"] == 202).any()
