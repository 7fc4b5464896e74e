import numpy as np
import pytest
import torch
from curves import curves_of

from senbench.plugins import registries
from senbench.runner import run_suite
from senbench.specs import AgentContext
from senbench.suite import load_suite
from senbench_agents.dqn import DQNConfig, algorithms


def test_double_dqn_target_uses_the_online_argmax_and_the_target_value():
    torch.manual_seed(0)
    TargetDQN, DoubleDQN = algorithms()
    spec = registries().envs.get("mountaincar")
    models = [cls("MlpPolicy", spec.make(), learning_starts=0, seed=0, device="cpu")
              for cls in (TargetDQN, DoubleDQN)]
    dqn, ddqn = models
    ddqn.policy.load_state_dict(dqn.policy.state_dict())
    with torch.no_grad():  # make the two networks disagree
        for p in dqn.q_net_target.parameters():
            p.add_(torch.randn_like(p))
        ddqn.q_net_target.load_state_dict(dqn.q_net_target.state_dict())

    class Batch:
        next_observations = torch.tensor([[-0.5, 0.0], [0.3, 0.05], [-1.1, -0.06]])
        rewards = torch.full((3, 1), -1.0)
        dones = torch.tensor([[0.0], [0.0], [1.0]])

    with torch.no_grad():
        online = dqn.q_net(Batch.next_observations)
        target = dqn.q_net_target(Batch.next_observations)
        y_dqn = dqn.td_target(Batch, 0.9)
        y_ddqn = ddqn.td_target(Batch, 0.9)
    chosen = target.gather(1, online.argmax(1, keepdim=True))
    assert torch.allclose(y_ddqn, -1 + torch.tensor([[0.9], [0.9], [0.0]]) * chosen)
    assert torch.allclose(y_dqn, -1 + torch.tensor([[0.9], [0.9], [0.0]]) *
                          target.max(1, keepdim=True).values)
    assert not torch.allclose(y_dqn[:2], y_ddqn[:2])  # the crafted batch tells them apart
    assert torch.equal(y_dqn[2], y_ddqn[2])  # a terminal transition has no next value


def test_dqn_config_checks_its_ranges():
    with pytest.raises(ValueError, match="gamma must be in"):
        DQNConfig(gamma=1.5)


PIXELS = """\
name: pixels
envs:
  mountaincar: {}
methods:
  dqn-pixels:
    agent: dqn
    observation: pixels
    hyperparams: {learning_starts: 100, buffer_size: 500, batch_size: 16,
                  train_freq: 4, gradient_steps: 1, features_dim: 64}
  ddqn-pixels:
    agent: ddqn
    observation: pixels
    hyperparams: {learning_starts: 100, buffer_size: 500, batch_size: 16,
                  train_freq: 4, gradient_steps: 1, features_dim: 64}
  ppo-pixels:
    agent: ppo
    observation: pixels
    hyperparams: {n_steps: 64, batch_size: 32, n_epochs: 1}
pixels: {height: 40, width: 40}
seeds: [0]
budget: 400
eval: {every: 200, episodes: 1}
"""


def test_pixel_agents_learn_from_frames_and_repeat_their_curves(write_suite, tmp_path):
    suite = load_suite(write_suite(PIXELS), registries())
    curves = []
    for run in ("a", "b"):
        summary = run_suite(suite, tmp_path / run)
        assert summary.ok == 3, [o.error for o in summary.failed]
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
