from types import SimpleNamespace

import numpy as np
import pytest
import stable_baselines3.dqn.dqn
import torch
from curves import curves_of
from stable_baselines3.common.logger import Logger

from senbench.plugin.manager import registries
from senbench.plugin.specs import AgentContext
from senbench.run.runner import run_suite
from senbench.suite import load_suite
from senbench_agents.dqn import DQNConfig


def dqn_and_ddqn(**hyperparams):
    """SB3 models of the dqn and ddqn agents on the MountainCar state, with the same
    weights and a target network that disagrees with the online one."""
    regs = registries()
    spec = regs.envs.get("mountaincar")
    models = []
    for name in ("dqn", "ddqn"):
        agent = regs.agents.get(name)
        cfg = agent.config(learning_starts=0, buffer_size=100, **hyperparams)
        model = agent.make(AgentContext(cfg, spec, spec.make, 0, 1)).model
        model.set_logger(Logger(folder=None, output_formats=[]))
        models.append(model)
    dqn, ddqn = models
    generator = torch.Generator().manual_seed(0)
    with torch.no_grad():
        for p in dqn.policy.q_net_target.parameters():
            p.add_(torch.randn(p.shape, generator=generator))
    ddqn.policy.load_state_dict(dqn.policy.state_dict())
    return dqn, ddqn


def td_target_of_sb3_train(model, batch, monkeypatch) -> torch.Tensor:
    """The TD target SB3's own DQN.train regresses on, for one update on ``batch``."""
    targets = []
    loss = stable_baselines3.dqn.dqn.F.smooth_l1_loss

    def recording_loss(current, target):
        targets.append(target)
        return loss(current, target)

    monkeypatch.setattr(stable_baselines3.dqn.dqn.F, "smooth_l1_loss", recording_loss)
    monkeypatch.setattr(model.replay_buffer, "sample", lambda *args, **kwargs: batch)
    model.train(gradient_steps=1, batch_size=len(batch.rewards))
    [target] = targets
    return target


def test_double_dqn_target_uses_the_online_argmax_and_the_target_value(monkeypatch):
    dqn, ddqn = dqn_and_ddqn(gamma=0.9)
    next_obs = torch.tensor([[-0.5, 0.0], [0.3, 0.05], [-1.1, -0.06]])
    batch = SimpleNamespace(observations=next_obs.flip(0), actions=torch.tensor([[0], [1], [2]]),
                            next_observations=next_obs, rewards=torch.full((3, 1), -1.0),
                            dones=torch.tensor([[0.0], [0.0], [1.0]]), discounts=None)
    with torch.no_grad():
        online = dqn.q_net(next_obs)
        target = dqn.policy.q_net_target(next_obs)
    y_dqn = td_target_of_sb3_train(dqn, batch, monkeypatch)
    y_ddqn = td_target_of_sb3_train(ddqn, batch, monkeypatch)
    not_done = torch.tensor([[0.9], [0.9], [0.0]])
    chosen = target.gather(1, online.argmax(1, keepdim=True))
    assert torch.allclose(y_ddqn, -1 + not_done * chosen)
    assert torch.allclose(y_dqn, -1 + not_done * target.max(1, keepdim=True).values)
    assert not torch.allclose(y_dqn[:2], y_ddqn[:2])  # the crafted batch tells them apart
    assert torch.equal(y_dqn[2], y_ddqn[2])  # a terminal transition has no next value


@pytest.mark.parametrize("tau", [1.0, 0.5])
def test_double_dqn_target_update_moves_only_the_target_network(tau):
    _, ddqn = dqn_and_ddqn(tau=tau, target_update_interval=1)
    online, target = ddqn.policy.q_net, ddqn.policy.q_net_target
    assert type(target) is type(online)  # the policy keeps the real target network
    assert [id(p) for p in ddqn.q_net_target.parameters()] == [id(p) for p in
                                                                target.parameters()]
    assert [id(b) for b in ddqn.q_net_target.buffers()] == [id(b) for b in target.buffers()]
    before = [p.clone() for p in online.parameters()]
    old_target = [p.clone() for p in target.parameters()]
    ddqn._on_step()  # SB3's target update, due at every step with an interval of 1
    for now, was, new, old in zip(online.parameters(), before, target.parameters(),
                                  old_target, strict=True):
        assert torch.equal(now, was)
        assert torch.allclose(new, tau * was + (1 - tau) * old)


def test_double_dqn_keeps_its_target_through_save_and_load(tmp_path):
    dqn, ddqn = dqn_and_ddqn()
    assert ddqn.policy.state_dict().keys() == dqn.policy.state_dict().keys()
    ddqn.save(tmp_path / "ddqn.zip")
    loaded = type(ddqn).load(tmp_path / "ddqn.zip", device="cpu")
    assert type(loaded.q_net_target) is type(ddqn.q_net_target)
    assert loaded.q_net_target.online is loaded.q_net
    assert loaded.q_net_target.target is loaded.policy.q_net_target


def test_dqn_config_checks_its_ranges():
    with pytest.raises(ValueError, match="gamma\n  Input should be less than or equal to 1"):
        DQNConfig(gamma=1.5)


PIXELS = """\
name: pixels
envs:
  mountaincar: {}
  pendulum: {}
methods:
  dqn-pixels:
    agent: dqn
    envs: [mountaincar]
    observation: pixels
    hyperparams: {learning_starts: 100, buffer_size: 500, batch_size: 16,
                  train_freq: 4, gradient_steps: 1, features_dim: 64}
  ddqn-pixels:
    agent: ddqn
    envs: [mountaincar]
    observation: pixels
    hyperparams: {learning_starts: 100, buffer_size: 500, batch_size: 16,
                  train_freq: 4, gradient_steps: 1, features_dim: 64}
  ppo-pixels:
    agent: ppo
    envs: [mountaincar]
    observation: pixels
    hyperparams: {n_steps: 64, batch_size: 32, n_epochs: 1}
  drq-pixels:
    agent: drq
    envs: [mountaincar]
    observation: pixels
    hyperparams: {learning_starts: 100, buffer_size: 500, batch_size: 16, features_dim: 64,
                  k: 2, m: 2, n_steps: 3}
  drq-sac-pixels:
    agent: drq-sac
    observation: pixels
    envs: [pendulum]
    hyperparams: {learning_starts: 100, buffer_size: 500, batch_size: 8, features_dim: 16,
                  net_arch: [32], train_freq: 8, k: 2, m: 2}
pixels: {height: 40, width: 40}
seeds: [0]
budget: 400
eval: {every: 200, episodes: 1}
"""


@pytest.mark.slow
def test_pixel_agents_learn_from_frames_and_repeat_their_curves(write_suite, tmp_path):
    suite = load_suite(write_suite(PIXELS), registries())
    curves = []
    for run in ("a", "b"):
        summary = run_suite(suite, tmp_path / run)
        assert summary.ok == 5, [o.error for o in summary.failed]
        curves.append(curves_of(tmp_path / run / "pixels"))
    assert curves[0].equals(curves[1])
    evals = curves[0][curves[0]["kind"] == "eval"]
    assert sorted(set(evals["step"])) == [0, 200, 400]


def test_dqn_stops_exactly_at_the_budget():
    spec = registries().envs.get("mountaincar")
    agent = registries().agents.get("dqn")
    steps = []

    class Log:
        def step(self, n):
            steps.append(n)
            return n < 333

        def episode(self, *args):
            pass

    cfg = agent.config(learning_starts=50, buffer_size=200, train_freq=4)
    agent.make(AgentContext(cfg, spec, spec.make, 0, 1)).learn(333, Log())
    assert steps[0] == 0 and steps[-1] == 333 and np.all(np.diff(steps) == 1)


def test_dqn_takes_its_pixel_defaults_on_pixels_and_its_state_defaults_on_the_state(
        write_suite):
    suite = load_suite(write_suite("""\
        name: defaults
        envs:
          mountaincar: {}
        methods:
          dqn-pixels: {agent: dqn, observation: pixels}
          dqn-state: {agent: dqn}
          dqn-pixels-set: {agent: dqn, observation: pixels, hyperparams: {train_freq: 8}}
        seeds: 1
        budget: 100
        eval: {every: 100, episodes: 1}
        """), registries())
    params = {c.method: c.hyperparams for c in suite.cells}
    assert params["dqn-pixels"]["train_freq"] == 4 and params["dqn-pixels"]["batch_size"] == 32
    assert params["dqn-pixels"]["learning_starts"] == 10_000
    assert params["dqn-state"]["train_freq"] == 16 and params["dqn-state"]["batch_size"] == 128
    assert params["dqn-pixels-set"]["train_freq"] == 8  # a suite still overrides


def test_optimize_memory_usage_stores_each_frame_once():
    spec = registries().envs.get("mountaincar")
    agent = registries().agents.get("dqn")
    sizes = {}
    for optimize in (False, True):
        cfg = agent.config(learning_starts=50, buffer_size=300, optimize_memory_usage=optimize,
                           features_dim=32)

        def make():
            from senbench.observe.observations import make_env
            from senbench.observe.pixels import PixelSpec

            return make_env(spec, "pixels", 200, {}, PixelSpec(40, 40, 2))

        learner = agent.make(AgentContext(cfg, spec, make, 0, 1))
        buffer = learner.model.replay_buffer
        sizes[optimize] = buffer.observations.nbytes + (
            getattr(buffer, "next_observations", np.empty(0)).nbytes)
        learner.learn(120, type("R", (), {"step": lambda s, n: n < 120,
                                          "episode": lambda s, *a: None})())
    assert sizes[True] * 2 == sizes[False] == 2 * 300 * 2 * 40 * 40


ENCODER = ("{arch: sen-resnet, config: {widths: [8, 8, 16, 16], hidden: 32}, samples: 300, "
           "fraction: 1.0, epochs: 2, test_samples: 100}")
DQN = "{learning_starts: 50, buffer_size: 300, batch_size: 16, features_dim: 32}"
PPO = "{n_envs: 1, n_steps: 64, batch_size: 32, n_epochs: 1}"
SEVEN = f"""\
name: seven
envs:
  mountaincar: {{max_episode_steps: 100}}
  pendulum: {{max_episode_steps: 100}}
methods:
  sarsa-state: {{agent: sarsa, envs: [mountaincar]}}
  sen-sarsa: {{agent: sarsa, observation: encoded, envs: [mountaincar], encoder: {ENCODER}}}
  dqn-pixels: {{agent: dqn, observation: pixels, envs: [mountaincar], hyperparams: {DQN}}}
  ddqn-pixels: {{agent: ddqn, observation: pixels, envs: [mountaincar], hyperparams: {DQN}}}
  ppo-state: {{agent: ppo, envs: [pendulum], hyperparams: {PPO}}}
  sen-ppo: {{agent: ppo, observation: encoded, envs: [pendulum], encoder: {ENCODER},
            hyperparams: {PPO}}}
  ppo-pixels: {{agent: ppo, observation: pixels, envs: [pendulum], hyperparams: {PPO}}}
pixels: {{height: 36, width: 36}}
seeds: 1
budget: 300
eval: {{every: 150, episodes: 1}}
"""


@pytest.mark.slow
def test_the_papers_seven_methods_run_in_one_suite_and_report(write_suite, tmp_path):
    """The comparison of the paper end to end, from the command line: encoders trained,
    every method run on 2 workers, the report printed."""
    import os
    import subprocess
    import sys

    path = write_suite(SEVEN)
    done = subprocess.run([sys.executable, "-m", "senbench", "run", str(path), "--workers", "2",
                           "--results", str(tmp_path / "results")],
                          capture_output=True, text=True, env={**os.environ, "COLUMNS": "200"})
    assert done.returncode == 0, done.stdout + done.stderr
    assert "suite 'seven': 7 finished, 0 failed" in done.stdout
    done = subprocess.run([sys.executable, "-m", "senbench", "report",
                           str(tmp_path / "results" / "seven")],
                          capture_output=True, text=True, env={**os.environ, "COLUMNS": "200"})
    assert done.returncode == 0, done.stderr
    assert "mountaincar: evaluation return" in done.stdout
    assert "pendulum: evaluation return" in done.stdout
    for method in ("sarsa-state", "sen-sarsa", "dqn-pixels", "ddqn-pixels", "ppo-state",
                   "sen-ppo", "ppo-pixels"):
        assert method in done.stdout
    png = tmp_path / "traces.png"
    done = subprocess.run([sys.executable, "-m", "senbench", "plot", "traces", "--results",
                           str(tmp_path / "results" / "seven"), "--env", "pendulum",
                           "--out", str(png)], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert "1 encoders" in done.stdout and png.stat().st_size > 10_000
    # On a clone without the encoder cache, --train makes the very encoder the cells used.
    cache = tmp_path / "results" / "encoders"
    [folder] = [f for f in cache.iterdir()
                if f.is_dir() and '"pendulum"' in (f / "spec.json").read_text()]
    cache.rename(tmp_path / "kept")
    traces = [sys.executable, "-m", "senbench", "plot", "traces", "--results",
              str(tmp_path / "results" / "seven"), "--env", "pendulum", "--out", str(png)]
    done = subprocess.run(traces, capture_output=True, text=True)
    assert done.returncode == 2 and "add --train" in done.stderr, done.stderr
    done = subprocess.run([*traces, "--train"], capture_output=True, text=True)
    assert done.returncode == 0 and "1 encoders" in done.stdout, done.stderr
    assert [f.name for f in cache.iterdir() if f.is_dir()] == [folder.name]  # pendulum's only
    again = torch.load(folder / "model.pt", weights_only=True)
    first = torch.load(tmp_path / "kept" / folder.name / "model.pt", weights_only=True)
    assert again.keys() == first.keys() and again["model"].keys() == first["model"].keys()
    assert all(torch.equal(again["model"][k], first["model"][k]) for k in first["model"])
    assert torch.equal(again["mean"], first["mean"])


def test_ppo_on_pixels_shares_its_cnn_unless_told_to_give_the_actor_its_own(write_suite):
    from senbench.run.execute import agent_context

    regs = registries()
    policies = {}
    for share in (True, False):
        setting = "" if share else ", share_features_extractor: false"
        text = PIXELS.replace("n_epochs: 1}", f"n_epochs: 1{setting}}}")
        cell = next(c for c in load_suite(write_suite(text), regs).cells if c.agent == "ppo")
        learner = regs.agents.get("ppo").make(agent_context(cell))
        policies[share] = learner.model.policy
    assert policies[True].pi_features_extractor is policies[True].vf_features_extractor
    separate = policies[False]
    assert separate.pi_features_extractor is not separate.vf_features_extractor
    assert type(separate.vf_features_extractor).__name__ == "NatureCNN"
