import re
import tempfile

import numpy as np
import pytest
from curves import curves_of

from senbench.plugin.manager import registries
from senbench.plugin.specs import AgentContext
from senbench.run.evaluation import CellRecorder
from senbench.run.runner import run_suite
from senbench.suite import load_suite


class EpisodeLog:
    def __init__(self, budget):
        self.budget, self.steps, self.episodes = budget, [], []

    def step(self, steps):
        self.steps.append(steps)
        return steps < self.budget

    def episode(self, steps, episode_return, length):
        self.episodes.append((steps, episode_return, length))


def learn(agent_name, env_name, budget, seed=0, **hyperparams):
    regs = registries()
    env, agent = regs.envs.get(env_name), regs.agents.get(agent_name)
    values = {**agent.defaults_for(env_name, "state").values, **hyperparams}
    learner = agent.make(AgentContext(agent.config(**values), env, env.make, seed, 1))
    log = EpisodeLog(budget)
    learner.learn(budget, log)
    return learner, log


@pytest.mark.slow
@pytest.mark.parametrize("seed", [0, 1])
def test_sarsa_learns_mountaincar_on_the_state(seed):
    # Measured: the rolling-10 return reaches -150 within 4.1k frames (median of 6 seeds,
    # worst 5.2k). Asserted with room: within 10k frames, and the greedy policy then
    # reaches the flag.
    learner, log = learn("sarsa", "mountaincar", 10_000, seed)
    returns = np.array([r for _, r, _ in log.episodes])
    rolling = np.convolve(returns, np.ones(10) / 10, "valid")
    assert rolling.max() >= -150
    env = registries().envs.get("mountaincar").make()
    obs, _ = env.reset(seed=123)
    length, terminated, truncated = 0, False, False
    while not (terminated or truncated):
        obs, _, terminated, truncated, _ = env.step(learner.act(obs))
        length += 1
    assert terminated and length < 180


def test_sarsa_stops_exactly_at_the_budget_and_reports_every_frame():
    _, log = learn("sarsa", "mountaincar", 777)
    assert log.steps == list(range(778))
    assert all(0 < length <= 200 for _, _, length in log.episodes)


@pytest.mark.slow
def test_ppo_stops_exactly_at_the_budget_and_reports_episodes():
    _, log = learn("ppo", "pendulum", 1024, n_envs=2, n_steps=128, batch_size=64, n_epochs=1)
    assert log.steps[0] == 0 and log.steps[-1] == 1024
    assert np.all(np.diff(log.steps[1:]) == 2)  # one call per vectorised step of 2 envs
    assert all(length == 200 for _, _, length in log.episodes)
    assert len(log.episodes) == 2 * (1024 // 2 // 200)


def test_ppo_normalize_reward_scales_what_it_learns_from_not_what_it_records():
    from stable_baselines3.common.vec_env import VecNormalize

    settings = {"n_envs": 1, "n_steps": 400, "batch_size": 100, "n_epochs": 1}
    plain, plain_log = learn("ppo", "pendulum", 400, **settings)
    scaled, scaled_log = learn("ppo", "pendulum", 400, normalize_reward=True, **settings)
    venv = scaled.model.get_env()
    assert isinstance(venv, VecNormalize) and venv.norm_reward and not venv.norm_obs
    assert not isinstance(plain.model.get_env(), VecNormalize)
    # Both episodes end inside the first rollout, before any update: the same actions, and
    # the recorded returns are the env's own, not the scaled rewards PPO learns from.
    assert len(scaled_log.episodes) == 2 and scaled_log.episodes == plain_log.episodes
    assert venv.ret_rms.count > 1  # the return statistics were updated


@pytest.mark.slow
@pytest.mark.parametrize("agent", ["ppo", "dqn"])
def test_sb3_agents_leave_no_log_folder_behind(agent, tmp_path, monkeypatch):
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))  # SB3's default log folder
    monkeypatch.delenv("SB3_LOGDIR", raising=False)  # which SB3 would take instead
    settings = ({"n_envs": 1, "n_steps": 64, "batch_size": 32, "n_epochs": 1} if agent == "ppo"
                else {"learning_starts": 20, "buffer_size": 100, "train_freq": 4})
    learn(agent, "pendulum" if agent == "ppo" else "mountaincar", 100, **settings)
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith("SB3-")] == []


def test_recorder_evaluates_at_zero_every_interval_and_the_budget():
    calls = []
    recorder = CellRecorder(1000, 300, lambda: calls.append(1) or {"return": 0.0, "return_std": 0.0,
                                                           "length": 1.0})
    for steps in range(0, 1001, 4):
        more = recorder.step(steps)
    assert not more
    assert [r["step"] for r in recorder.rows] == [0, 300, 600, 900, 1000]


@pytest.mark.parametrize("reports, said, evaluated", [
    ([1, 2], "first report was frame 1, not 0", []),
    ([0, 8, 4], "reported frame 4 after frame 8", [0, 8]),
    ([0, 10, 11], "reported frame 11 after step() returned False at frame 10", [0, 10]),
])
def test_an_agent_that_breaks_the_recorder_protocol_fails_saying_how(reports, said,
                                                                     evaluated):
    from senbench.errors import PluginError

    recorder = CellRecorder(10, 5, lambda: {"return": 0.0, "return_std": 0.0, "length": 1.0})
    with pytest.raises(PluginError, match=re.escape(said)):
        for steps in reports:
            recorder.step(steps)
    assert [r["step"] for r in recorder.rows] == evaluated
    again = CellRecorder(10, 5, lambda: {"return": 0.0, "return_std": 0.0, "length": 1.0})
    assert again.step(0) and not again.step(10) and not again.step(10)  # the same frame: fine


def test_recorder_reports_the_running_mean_of_the_training_returns_at_each_evaluation():
    reports = []
    recorder = CellRecorder(1000, 300, lambda: {"return": -5.0, "return_std": 0.0,
                                                "length": 1.0},
                            lambda *args: reports.append(args))
    recorder.step(0)
    recorder.episode(200, -100.0, 200)
    recorder.episode(290, -50.0, 90)
    recorder.step(300)
    assert reports[0] == (0, reports[0][1], -5.0, 0, None)  # no episode ended yet
    assert reports[1][2:] == (-5.0, 300, -75.0)


DETERMINISM = """\
name: determinism
envs:
  mountaincar: {}
  pendulum: {}
methods:
  sarsa-state: {agent: sarsa, envs: [mountaincar]}
  ppo-state:
    agent: ppo
    envs: [pendulum]
    hyperparams: {n_envs: 2, n_steps: 256, n_epochs: 2}
seeds: [3]
budget: 2048
eval: {every: 1024, episodes: 2}
"""


@pytest.mark.slow
def test_the_same_seed_gives_the_same_curves(write_suite, tmp_path):
    suite = load_suite(write_suite(DETERMINISM), registries())
    curves = []
    for run in ("a", "b"):
        summary = run_suite(suite, tmp_path / run)
        assert summary.ok == 2
        curves.append(curves_of(tmp_path / run / "determinism"))
    assert curves[0].equals(curves[1])
    assert len(curves[0]) > 10


@pytest.mark.parametrize(("agent_name", "observation"), [
    ("dqn", "state"), ("dqn", "pixels"), ("ddqn", "pixels"), ("drq", "pixels")])
def test_the_greedy_act_of_the_dqn_family_is_sb3s_deterministic_predict(agent_name,
                                                                        observation):
    """act() reads the Q-network directly (faster per call); it must pick what SB3's
    predict(deterministic=True) picks, after some learning too."""
    from senbench.observe.observations import make_env
    from senbench.observe.pixels import PixelSpec

    regs = registries()
    env, agent = regs.envs.get("mountaincar"), regs.agents.get(agent_name)
    config = agent.config(learning_starts=50, buffer_size=500, train_freq=4, batch_size=16)
    pixels = PixelSpec(36, 36) if agent_name != "drq" else PixelSpec(40, 40)
    learner = agent.make(AgentContext(config, env, lambda: make_env(
        env, observation, 200, {}, pixels if observation == "pixels" else None), 0, 1))
    learner.learn(300, EpisodeLog(300))
    space = learner.model.observation_space
    space.seed(0)
    observations = [space.sample() for _ in range(30)]
    ours = [learner.act(o) for o in observations]
    assert ours == [int(learner.model.predict(o, deterministic=True)[0]) for o in observations]
