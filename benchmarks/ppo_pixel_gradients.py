"""What shapes pixel PPO's CNN: at its first update, the gradient its value loss and its
policy loss each put on the CNN that SB3's CnnPolicy shares between actor and critic, with
the env's rewards and with rewards scaled (``normalize_reward``).

PPO with rl-baselines3-zoo's Pendulum set (tuned on the state) learned the bars control in 1
seed of 3 (results/controls-pixels); the other two froze into a constant action. Pendulum's
unscaled returns (down to about -160 at γ 0.9) make the critic's targets large, so its loss
could own the shared features. This prints, per seed, the norm of each loss's gradient on
the CNN's weights over the first minibatch of the first rollout (the cell's own settings and
seed; the value loss weighted by vf_coef, as PPO sums it), and their ratio.

    .venv/bin/python benchmarks/ppo_pixel_gradients.py      (≈ 2 min on one core)
"""

from __future__ import annotations

from pathlib import Path

import torch
import torch.nn.functional as F

from senbench.plugin.manager import registries
from senbench.run.execute import agent_context
from senbench.suite import load_suite

SUITES = Path(__file__).resolve().parents[1] / "suites"


def first_update_gradients(cell) -> tuple[float, float, float]:
    """(policy-loss gradient norm, vf_coef × value-loss gradient norm, mean |return|) on the
    shared CNN at the cell's first update."""
    torch.manual_seed(cell.seed)
    model = registries().agents.get(cell.agent).make(agent_context(cell)).model
    seen = {}

    def probe() -> None:  # in place of PPO.train, after the first rollout
        policy = model.policy
        policy.set_training_mode(True)
        data = next(model.rollout_buffer.get(model.batch_size))
        values, log_prob, _ = policy.evaluate_actions(data.observations, data.actions)
        advantages = data.advantages
        advantages = (advantages - advantages.mean()) / (advantages.std() + 1e-8)
        ratio = torch.exp(log_prob - data.old_log_prob)
        clip = model.clip_range(1.0)
        policy_loss = -torch.min(advantages * ratio,
                                 advantages * torch.clamp(ratio, 1 - clip, 1 + clip)).mean()
        value_loss = model.vf_coef * F.mse_loss(data.returns, values.flatten())
        cnn = list(policy.features_extractor.parameters())
        g_pi = torch.autograd.grad(policy_loss, cnn, retain_graph=True)
        g_v = torch.autograd.grad(value_loss, cnn)
        norm = lambda grads: float(torch.sqrt(sum((g ** 2).sum() for g in grads)))  # noqa: E731
        seen.update(pi=norm(g_pi), v=norm(g_v), ret=float(data.returns.abs().mean()))

    model.train = probe
    model.learn(total_timesteps=model.n_steps * model.n_envs)
    return seen["pi"], seen["v"], seen["ret"]


def main() -> None:
    regs = registries()
    runs = [("env's rewards", load_suite(SUITES / "controls-pixels.yaml", regs)),
            ("normalize_reward", load_suite(SUITES / "controls-ppo-pixels.yaml", regs))]
    print(f"{'rewards':<18}{'env':<15}{'seed':>5}{'|policy grad|':>15}{'|value grad|':>14}"
          f"{'value/policy':>14}{'mean |return|':>15}")
    for label, suite in runs:
        for cell in suite.cells:
            if (cell.agent != "ppo" or cell.env != "pendulum-bars"
                    or not cell.hyperparams.get("share_features_extractor", True)):
                continue  # a CNN of the actor's own gets no gradient from the value loss
            pi, v, ret = first_update_gradients(cell)
            print(f"{label:<18}{cell.env:<15}{cell.seed:>5}{pi:>15.3g}{v:>14.3g}"
                  f"{v / pi:>14.1f}{ret:>15.3g}")


if __name__ == "__main__":
    main()
