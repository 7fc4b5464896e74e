"""PPO (Schulman et al. 2017) from Stable-Baselines3: an MLP actor-critic on the true or
encoded state, SB3's NatureCNN under it on pixels.

senbench adds only the glue: a vectorised training env built from the cell's observation
pipeline, a callback that reports frames and episodes through the one recorder protocol
(and stops at the budget, exactly), and deterministic actions for evaluation.
"""

from __future__ import annotations

from dataclasses import field
from typing import Annotated, ClassVar, Literal

import numpy as np
from pydantic import Field
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
from senbench_agents.ranges import NonNegativeFloat, PositiveFloat, PositiveInt, Probability
from senbench_agents.sb3 import (
    NATURE_CNN_MIN_FRAME,
    PRECISIONS,
    is_frame_stack,
    lay_out,
    learn_with_recorder,
    monitored_vec_env,
    with_precision,
)


@dataclass
class PPOConfig:
    n_envs: PositiveInt = 1
    """Parallel training envs; a budget is counted in frames over all of them."""
    n_steps: PositiveInt = 2048
    """Frames per env per rollout."""
    batch_size: Annotated[int, Field(ge=2)] = 64
    n_epochs: PositiveInt = 10
    learning_rate: PositiveFloat = 3e-4
    gamma: Probability = 0.99
    gae_lambda: Probability = 0.95
    clip_range: PositiveFloat = 0.2
    ent_coef: NonNegativeFloat = 0.0
    vf_coef: NonNegativeFloat = 0.5
    max_grad_norm: PositiveFloat = 0.5
    """Gradients are clipped to this norm (a negative one would turn them around)."""
    use_sde: bool = False
    """State-dependent exploration (continuous actions only)."""
    sde_sample_freq: Annotated[int, Field(ge=-1)] = -1
    """Frames between new exploration noise matrices (-1: only at a rollout's start)."""
    net_arch: Annotated[list[PositiveInt], Field(min_length=1)] = field(
        default_factory=lambda: [64, 64])
    """Hidden layer widths of the actor and of the critic (after the CNN on pixels)."""
    activation: Literal["tanh", "relu"] = "tanh"
    """tanh or relu."""
    normalize_reward: bool = False
    """Scale the rewards PPO learns from by a running estimate of the discounted return's
    standard deviation (SB3's VecNormalize with norm_reward only), as rl-baselines3-zoo's
    PPO sets for pixels (CarRacing). Recorded returns stay the env's own."""

    share_features_extractor: bool = True
    """On pixels: one CNN under both actor and critic (SB3's default), or one each, so that
    the critic's loss does not shape the actor's features."""

    LATE_FIELDS: ClassVar[tuple[str, ...]] = ("normalize_reward", "share_features_extractor")
    """Added after PPO results were committed: at their defaults, left out of a cell's id."""

    def __post_init__(self) -> None:  # each field's own range is in its type
        if self.batch_size > self.n_steps * self.n_envs:
            raise ValueError(f"batch_size must be at most a rollout, n_steps * n_envs = "
                             f"{self.n_steps * self.n_envs}, got {self.batch_size}")


class PPOAgent:
    def __init__(self, ctx: AgentContext):
        import torch
        from stable_baselines3 import PPO

        cfg: PPOConfig = ctx.config
        activations = {"tanh": torch.nn.Tanh, "relu": torch.nn.ReLU}
        venv = monitored_vec_env(ctx, cfg.n_envs)
        if cfg.normalize_reward:
            from stable_baselines3.common.vec_env import VecNormalize

            venv = VecNormalize(venv, norm_obs=False, norm_reward=True, gamma=cfg.gamma)
        self.model = with_precision(PPO, ctx.precision)(
            "CnnPolicy" if is_frame_stack(venv.observation_space) else "MlpPolicy",
            venv,
            n_steps=cfg.n_steps,
            batch_size=cfg.batch_size,
            n_epochs=cfg.n_epochs,
            learning_rate=cfg.learning_rate,
            gamma=cfg.gamma,
            gae_lambda=cfg.gae_lambda,
            clip_range=cfg.clip_range,
            ent_coef=cfg.ent_coef,
            vf_coef=cfg.vf_coef,
            max_grad_norm=cfg.max_grad_norm,
            use_sde=cfg.use_sde,
            sde_sample_freq=cfg.sde_sample_freq,
            policy_kwargs={
                "net_arch": {"pi": list(cfg.net_arch), "vf": list(cfg.net_arch)},
                "activation_fn": activations[cfg.activation],
                "share_features_extractor": cfg.share_features_extractor,
                # SB3's Adam (eps 1e-5, which it sets only when given no kwargs), fused:
                # the same update, 14-18% more frames/s on one core.
                "optimizer_kwargs": {"eps": 1e-5, "fused": True},
            },
            seed=ctx.seed,
            device="cpu",
            verbose=0,
        )
        lay_out(self.model, ctx.memory_format)

    def act(self, observation: np.ndarray):
        action, _ = self.model.predict(observation, deterministic=True)
        return action

    def learn(self, budget: int, recorder: Recorder) -> None:
        learn_with_recorder(self.model, budget, recorder)


ZOO_PENDULUM = AgentDefaults(
    values={
        "n_envs": 4,
        "n_steps": 1024,
        "gae_lambda": 0.95,
        "gamma": 0.9,
        "n_epochs": 10,
        "ent_coef": 0.0,
        "learning_rate": 1e-3,
        "clip_range": 0.2,
        "use_sde": True,
        "sde_sample_freq": 4,
    },
    source="rl-baselines3-zoo hyperparams/ppo.yml, Pendulum-v1",
)


PPO_SPEC = AgentSpec(
    name="ppo",
    make=PPOAgent,
    config=PPOConfig,
    actions=frozenset({"discrete", "continuous"}),
    observations=frozenset({"state", "encoded", "pixels"}),
    defaults={
        "pendulum": ZOO_PENDULUM,
        "pendulum-bars": ZOO_PENDULUM,  # the same task drawn as bars (the pixel control)
        "mountaincar": AgentDefaults(
            values={},
            source="Stable-Baselines3 PPO defaults (zoo's MountainCar-v0 set needs "
            "VecNormalize on observations, which senbench does not apply)",
        ),
    },
    description="Stable-Baselines3 PPO: MLP actor-critic; NatureCNN under it on pixels",
    min_frame_size=NATURE_CNN_MIN_FRAME,
    precisions=PRECISIONS,
    memory_formats=MEMORY_FORMATS,
    # After rl-baselines3-zoo's sample_ppo_params, and normalize_reward, which the zoo
    # sets per env (on for PPO on pixels): it decides whether PPO learns Pendulum's bars
    # from pixels (suites/controls-ppo-pixels.yaml).
    search_space={
        "learning_rate": Float(1e-5, 3e-3, log=True),
        "n_steps": Choice((256, 512, 1024, 2048)),
        "batch_size": Choice((32, 64, 128, 256)),
        "n_epochs": Choice((5, 10, 20)),
        "gamma": Choice((0.9, 0.95, 0.98, 0.99, 0.995)),
        "gae_lambda": Choice((0.8, 0.9, 0.92, 0.95, 0.98, 1.0)),
        "clip_range": Choice((0.1, 0.2, 0.3)),
        "ent_coef": Float(1e-8, 0.1, log=True),
        "normalize_reward": Choice((False, True)),
    },
)
