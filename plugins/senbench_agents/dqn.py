"""DQN (Mnih et al. 2015) and Double DQN (van Hasselt et al. 2016) from Stable-Baselines3,
end to end on pixels (a CNN on the frame stack) or on the state (an MLP).

SB3's DQN is used as it is. Double DQN changes only the TD target: the online network
picks the next action, the target network values it,

    DQN:  y = r + γ (1 − done) max_a Q_target(s', a)
    DDQN: y = r + γ (1 − done) Q_target(s', argmax_a Q_online(s', a))

SB3's ``DQN.train`` has no hook for the target: it takes ``q_net_target(s').max(dim=1)``.
So Double DQN hands ``train`` a target network whose output is Q_target(s', a) at the
online network's argmax and −∞ elsewhere: the max over actions is then the DDQN value.
"""

from __future__ import annotations

from dataclasses import field
from functools import cache
from typing import ClassVar

import numpy as np
from pydantic.dataclasses import dataclass

from senbench import (
    MEMORY_FORMATS,
    AgentContext,
    AgentDefaults,
    AgentSpec,
    Choice,
    Float,
    Recorder,
)
from senbench_agents.ranges import NonNegativeInt, PositiveFloat, PositiveInt, Probability
from senbench_agents.sb3 import (
    NATURE_CNN_MIN_FRAME,
    PRECISIONS,
    FeaturesHead,
    features_extractor_class,
    is_frame_stack,
    lay_out,
    learn_with_recorder,
    monitored_vec_env,
    with_precision,
)


@dataclass
class DQNConfig:
    learning_rate: PositiveFloat = 1e-4
    buffer_size: PositiveInt = 100_000
    """Transitions kept; on 2x64x64 frames each costs 16 KB (obs and next obs), 8 KB
    with ``optimize_memory_usage``."""
    learning_starts: NonNegativeInt = 1000
    batch_size: PositiveInt = 32
    tau: Probability = 1.0
    gamma: Probability = 0.99
    train_freq: PositiveInt = 4
    """Frames between updates."""
    gradient_steps: PositiveInt = 1
    target_update_interval: PositiveInt = 1000
    exploration_fraction: Probability = 0.1
    exploration_initial_eps: Probability = 1.0
    exploration_final_eps: Probability = 0.05
    max_grad_norm: PositiveFloat = 10.0
    net_arch: list[PositiveInt] = field(default_factory=list)
    """Hidden layers of the Q head (after the CNN on pixels; the whole MLP on the state)."""
    features_dim: PositiveInt = 512
    """Output of the CNN on pixels (SB3's NatureCNN: 3 convolutions and a linear layer)."""
    features_head: FeaturesHead = "relu"
    """The CNN's last layer on pixels: NatureCNN's Linear → ReLU, or DrQ's Linear →
    LayerNorm → tanh. On a state there is no CNN and it is unused."""
    optimize_memory_usage: bool = False
    """Store each observation once (SB3's option): halves the buffer, but SB3 then cannot
    tell a time-limit truncation from a termination, so the last step of a truncated
    episode is not bootstrapped. Off by default for that reason."""

    LATE_FIELDS: ClassVar[tuple[str, ...]] = ("features_head",)
    """Left out of a cell's id at their defaults: added after results were committed."""
    PIXEL_FIELDS: ClassVar[tuple[str, ...]] = ("features_head",)
    """Act only on the CNN: validation refuses them off their default on state or encoded."""


@cache
def double_dqn() -> type:
    """SB3's DQN with the Double-DQN target; built on first use, so that listing plugins
    does not import torch."""
    import torch as th
    from stable_baselines3 import DQN

    class DoubleDQNTarget(th.nn.Module):
        """The target network as DQN.train sees it in Double DQN. Its parameters and buffers
        are the target network's alone, as SB3's target update (a pairwise copy from the
        online network's) needs: the online network is held, not registered."""

        def __init__(self, online: th.nn.Module, target: th.nn.Module):
            super().__init__()
            self.target = target
            object.__setattr__(self, "online", online)

        def forward(self, next_obs: th.Tensor) -> th.Tensor:
            best = self.online(next_obs).argmax(dim=1, keepdim=True)
            q = self.target(next_obs)
            return th.full_like(q, -th.inf).scatter(1, best, q.gather(1, best))

    class DoubleDQN(DQN):
        def _setup_model(self) -> None:
            super()._setup_model()
            # train()'s alias only: the policy's q_net_target stays the target network
            self.q_net_target = DoubleDQNTarget(self.q_net, self.policy.q_net_target)

    return DoubleDQN


class DQNAgent:
    double = False

    def __init__(self, ctx: AgentContext):
        cfg: DQNConfig = ctx.config
        venv = monitored_vec_env(ctx, 1)
        pixels = is_frame_stack(venv.observation_space)
        if pixels and min(venv.observation_space.shape[1:]) < NATURE_CNN_MIN_FRAME:
            raise ValueError("on pixels this agent uses SB3's NatureCNN, which needs frames "
                             "of at least 36x36; set pixels: {height: 36, width: 36} or more")
        # Fused Adam: the same update as SB3's default Adam in one kernel per step; a
        # pixel DQN update takes 7.0 instead of 9.8 ms on one core.
        policy_kwargs = {"net_arch": list(cfg.net_arch), "optimizer_kwargs": {"fused": True}}
        if pixels:
            policy_kwargs["features_extractor_class"] = features_extractor_class(
                cfg.features_head)
            policy_kwargs["features_extractor_kwargs"] = {"features_dim": cfg.features_dim}
        algorithm, extra = self.algorithm(cfg, venv.observation_space.shape[1:])
        buffer_kwargs = {"handle_timeout_termination": not cfg.optimize_memory_usage,
                         **extra.pop("replay_buffer_kwargs", {})}
        self.model = with_precision(algorithm, ctx.precision)(
            "CnnPolicy" if pixels else "MlpPolicy", venv,
            learning_rate=cfg.learning_rate, buffer_size=cfg.buffer_size,
            learning_starts=cfg.learning_starts, batch_size=cfg.batch_size, tau=cfg.tau,
            gamma=cfg.gamma, train_freq=cfg.train_freq, gradient_steps=cfg.gradient_steps,
            target_update_interval=cfg.target_update_interval,
            exploration_fraction=cfg.exploration_fraction,
            exploration_initial_eps=cfg.exploration_initial_eps,
            exploration_final_eps=cfg.exploration_final_eps, max_grad_norm=cfg.max_grad_norm,
            optimize_memory_usage=cfg.optimize_memory_usage,
            replay_buffer_kwargs=buffer_kwargs, policy_kwargs=policy_kwargs, seed=ctx.seed,
            device="cpu", verbose=0, **extra,
        )
        lay_out(self.model, ctx.memory_format)

    def algorithm(self, cfg: DQNConfig, frame: tuple[int, ...]) -> tuple[type, dict]:
        """The SB3 class to build and the keyword arguments it takes beyond DQN's."""
        from stable_baselines3 import DQN

        return (double_dqn() if self.double else DQN), {}

    def act(self, observation: np.ndarray):
        """The greedy action: the policy's Q-network on this one observation. It is what
        SB3's ``predict(observation, deterministic=True)`` computes, the same arithmetic,
        without that call's per-call checks, copies and mode switch (the network has no
        layer that a mode changes): about 1.3x faster a call here (2x64x64 frames, measured
        side by side under load), and evaluation calls it once
        a frame (``tests/test_agents.py`` checks the two agree)."""
        import torch

        with torch.inference_mode():
            batch = torch.as_tensor(observation).unsqueeze(0)
            return int(self.model.policy.q_net._predict(batch, deterministic=True)[0])

    def learn(self, budget: int, recorder: Recorder) -> None:
        learn_with_recorder(self.model, budget, recorder)


class DoubleDQNAgent(DQNAgent):
    double = True


ZOO_MOUNTAINCAR = AgentDefaults(
    values={"learning_rate": 4e-3, "batch_size": 128, "buffer_size": 10_000,
            "learning_starts": 1000, "gamma": 0.98, "target_update_interval": 600,
            "train_freq": 16, "gradient_steps": 8, "exploration_fraction": 0.2,
            "exploration_final_eps": 0.07, "net_arch": [256, 256]},
    source="rl-baselines3-zoo hyperparams/dqn.yml, MountainCar-v0 (tuned on the state)",
)


ATARI_AT_1M = AgentDefaults(
    values={"learning_rate": 1e-4, "batch_size": 32, "buffer_size": 100_000,
            "learning_starts": 10_000, "gamma": 0.99, "target_update_interval": 1000,
            "train_freq": 4, "gradient_steps": 1, "exploration_fraction": 0.1,
            "exploration_final_eps": 0.1, "net_arch": [], "features_dim": 512},
    source="rl-baselines3-zoo hyperparams/dqn.yml, atari (the standard pixel DQN the paper "
    "compares with), its 10M-frame buffer, warm-up and target period scaled to 1M frames",
)


DQN_SPACE = {  # after rl-baselines3-zoo's sample_dqn_params
    "learning_rate": Float(1e-5, 1e-2, log=True),
    "batch_size": Choice((16, 32, 64, 128, 256)),
    "gamma": Choice((0.9, 0.95, 0.98, 0.99, 0.995)),
    "train_freq": Choice((1, 4, 8, 16)),
    "target_update_interval": Choice((500, 1000, 5000, 10000)),
    "exploration_fraction": Float(0.05, 0.5),
    "exploration_final_eps": Float(0.01, 0.2),
}


def dqn_spec(name: str, agent: type, description: str) -> AgentSpec:
    return AgentSpec(name=name, make=agent, config=DQNConfig,
                     actions=frozenset({"discrete"}),
                     observations=frozenset({"pixels", "state", "encoded"}),
                     # mountaincar-bars: the same task drawn as bars (the pixel control)
                     defaults={"mountaincar": ZOO_MOUNTAINCAR,
                               "mountaincar:pixels": ATARI_AT_1M,
                               "mountaincar-bars": ZOO_MOUNTAINCAR,
                               "mountaincar-bars:pixels": ATARI_AT_1M},
                     description=description, search_space=DQN_SPACE,
                     min_frame_size=NATURE_CNN_MIN_FRAME, precisions=PRECISIONS,
                     memory_formats=MEMORY_FORMATS)


DQN_SPEC = dqn_spec("dqn", DQNAgent, "Stable-Baselines3 DQN: NatureCNN on pixels, MLP on a state")
DDQN_SPEC = dqn_spec("ddqn", DoubleDQNAgent,
                     "Double DQN: SB3's DQN with the online network choosing the next action")
