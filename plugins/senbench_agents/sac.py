"""SAC (Haarnoja et al. 2018) from Stable-Baselines3, and DrQ's SAC (Kostrikov, Yarats &
Fergus 2020): the same learner whose updates see randomly shifted frames.

``sac`` is SB3's SAC as it is: an MLP actor and twin critics on the true or encoded state,
each with its own NatureCNN under it on pixels. ``drq-sac`` is SB3's SAC with a replay buffer
whose samples are shifted (:class:`AugmentedSamples`); ``SAC.train`` is used as it is. With
K shifts of the next frames and M of the frames, each sampled transition i comes back
M·K times, row (m, k, i) holding shift_m(s_i) and shift_k(s'_i). SAC's critic loss is a
mean of squares, so its gradient on those rows,

    1/(B M K) Σ_{i,m,k} (Q(shift_m(s_i), a_i) − y_ik) ∇Q(shift_m(s_i), a_i)
      = 1/(B M) Σ_{i,m} (Q(shift_m(s_i), a_i) − ȳ_i) ∇Q(shift_m(s_i), a_i),  ȳ_i = 1/K Σ_k y_ik,

is the gradient of DrQ's loss, 1/(B M) Σ_{i,m} (Q(shift_m(s_i), a_i) − ȳ_i)², with the target
averaged over K shifts (its equations 1 and 3). The actor and the temperature learn on the
same shifted frames, averaged over the M shifts (DrQ's actor uses the first). At K = M = 1
this is DrQ's loss exactly (not its networks: see :data:`DRQ_SIZED`); at larger K, M it
costs M·K rows where DrQ spends M + K.
Acting, in training and in evaluation, sees the frames unshifted.
"""

from __future__ import annotations

import re
from dataclasses import field
from functools import cache
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
from senbench_agents.augment import min_frame_size as shifted_min_frame_size
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

_ENT_COEF = re.compile(r"auto(_\d+(\.\d*)?(e-?\d+)?)?")

ActorConvs = Literal["own", "critic"]


@dataclass
class SACConfig:
    learning_rate: PositiveFloat = 3e-4
    buffer_size: PositiveInt = 1_000_000
    """Transitions kept; on 2x64x64 frames each costs 16 KB (obs and next obs)."""
    learning_starts: NonNegativeInt = 100
    """Frames of random actions before the first update."""
    batch_size: PositiveInt = 256
    tau: Probability = 0.005
    """Polyak rate of the target critics."""
    gamma: Probability = 0.99
    train_freq: PositiveInt = 1
    """Frames between updates."""
    gradient_steps: PositiveInt = 1
    """Updates each time."""
    ent_coef: float | str = "auto"
    """The entropy temperature α: a number, "auto" (learned, from 1) or "auto_<x>" (learned,
    from x)."""
    target_update_interval: PositiveInt = 1
    """Updates between target critic updates, counted over the run (SB3 counts them within
    one ``train`` call, where this would be ignored at one update a call)."""
    use_sde: bool = False
    """State-dependent exploration."""
    net_arch: Annotated[list[PositiveInt], Field(min_length=1)] = field(
        default_factory=lambda: [256, 256])
    """Hidden layers of the actor and of each critic (after the CNN on pixels)."""
    features_dim: PositiveInt = 512
    """Output of each network's CNN on pixels (SB3's NatureCNN)."""
    features_head: FeaturesHead = "relu"
    """The last layer of each CNN on pixels: NatureCNN's Linear → ReLU, or DrQ's Linear →
    LayerNorm → tanh."""
    actor_convs: ActorConvs = "own"
    """On pixels, the convolutions under the actor: its own, trained by the actor's loss
    (SB3's SAC), or the critic's, which only the critic's loss trains: the actor's gradient
    stops at them and its Linear head stays its own (DrQ's tie, from SAC-AE: Yarats et al.
    2019, who found the actor's gradient through the encoder degrades learning)."""

    LATE_FIELDS: ClassVar[tuple[str, ...]] = ("features_head", "actor_convs")
    PIXEL_FIELDS: ClassVar[tuple[str, ...]] = ("features_head", "actor_convs")

    def __post_init__(self) -> None:
        if isinstance(self.ent_coef, str) and not _ENT_COEF.fullmatch(self.ent_coef):
            raise ValueError(f"ent_coef must be a number, 'auto' or 'auto_<initial value>', "
                             f"got {self.ent_coef!r}")
        if isinstance(self.ent_coef, float) and not self.ent_coef > 0:
            raise ValueError(f"ent_coef must be positive, got {self.ent_coef}")


DRQ_SIZED = {"learning_rate": 1e-3, "buffer_size": 200_000, "learning_starts": 1000,
             "batch_size": 64, "tau": 0.01, "target_update_interval": 2, "train_freq": 4,
             "ent_coef": "auto_0.1", "net_arch": [1024, 1024], "features_dim": 50,
             "features_head": "layernorm-tanh", "actor_convs": "critic"}
"""DrQ's SAC (its paper and its code's config.yaml) sized to this machine: lr 1e-3, a buffer of
200k transitions (DrQ's 100k are steps at its action repeat of 4, 400k frames, so it hardly
evicts within its runs; here, without action repeat, 100k would hold 100k frames and evict
within the 200k budget of the Pendulum suites: with it each of 3 seeds collapsed once after
100k frames on the real Pendulum scene, and with 200k seeds 0, 1 and 2 did not,
suites/drq-sac-buffer.yaml; 200k holds the whole budget, as DrQ's holds its runs, and a
larger one gives the same curves there, as SB3 samples only what it has filled), 1,000
random frames first, critic targets at τ 0.01 every 2 updates, initial
temperature 0.1, hidden layers of 1,024, 50 features through DrQ's encoder head (Linear →
LayerNorm → tanh; with NatureCNN's ReLU head the actor's 50 features all died within 2,000
frames in one seed of two on the Pendulum bars, its action then the same on every frame:
REPRODUCTION.md, "Positive controls"). Departures, each for cost (frames/s from
benchmarks/drq_sizing.py): batch 64 (DrQ: 512 in the paper, 128 in its code, which runs at
0.52x the frames/s here); one update every 4 frames (DrQ updates once per agent step, which
at its default action repeat of 4 is the same ratio; senbench has no action repeat); K = M =
1 (DrQ: 2, at 0.25x the frames/s here); SB3's NatureCNN (DrQ: a 4-layer CNN), its
convolutions the critic's under the actor as DrQ ties them (with the actor's own, trained by
its loss, the actor's features stopped varying over frames within 2,000 frames on the real
Pendulum scene: REPRODUCTION.md); the actor updated at every update (DrQ: every 2)."""


@dataclass
class DrQSACConfig(SACConfig):
    """Defaults: :data:`DRQ_SIZED`, each read from it (the values are written once)."""

    learning_rate: PositiveFloat = DRQ_SIZED["learning_rate"]
    buffer_size: PositiveInt = DRQ_SIZED["buffer_size"]
    learning_starts: NonNegativeInt = DRQ_SIZED["learning_starts"]
    batch_size: PositiveInt = DRQ_SIZED["batch_size"]
    tau: Probability = DRQ_SIZED["tau"]
    target_update_interval: PositiveInt = DRQ_SIZED["target_update_interval"]
    train_freq: PositiveInt = DRQ_SIZED["train_freq"]
    ent_coef: float | str = DRQ_SIZED["ent_coef"]
    net_arch: Annotated[list[PositiveInt], Field(min_length=1)] = field(
        default_factory=lambda: list(DRQ_SIZED["net_arch"]))
    features_dim: PositiveInt = DRQ_SIZED["features_dim"]
    features_head: FeaturesHead = DRQ_SIZED["features_head"]
    actor_convs: ActorConvs = DRQ_SIZED["actor_convs"]
    LATE_FIELDS: ClassVar[tuple[str, ...]] = ()
    """Always in the id: drq-sac's cells before these fields had the ReLU head and the
    actor's own convolutions."""
    pad: Annotated[int, Field(ge=0)] | None = None
    """Pixels a frame may shift in each direction; None: DrQ's 4 at 84x84 scaled to the
    frame (3 at 64x64). At most half the frame."""
    k: PositiveInt = 1
    """Shifts of the next frames the target is averaged over (DrQ's K)."""
    m: PositiveInt = 1
    """Shifts of the frames the critic loss is averaged over (DrQ's M)."""


@cache
def augmented_samples() -> type:
    """SB3's replay buffer with DrQ's shifts on its samples; built on first use, so that
    listing plugins does not import torch."""
    import torch as th
    from stable_baselines3.common.buffers import ReplayBuffer

    from senbench_agents.augment import random_shift

    class AugmentedSamples(ReplayBuffer):
        """Samples of B transitions as B·M·K rows (m, k, i): shift_m(s_i), a_i, r_i,
        shift_k(s'_i), each shift drawn anew."""

        def __init__(self, *args, pad: int, k: int, m: int, seed: int, **kwargs):
            super().__init__(*args, **kwargs)
            self.pad, self.k, self.m = pad, k, m
            self.generator = th.Generator().manual_seed(seed)

        def sample(self, batch_size, env=None):
            data = super().sample(batch_size, env)
            m, k = self.m, self.k

            def shifted(frames: th.Tensor, copies: int) -> th.Tensor:
                return th.stack([random_shift(frames, self.pad, self.generator)
                                 for _ in range(copies)])

            def rows(x: th.Tensor) -> th.Tensor:  # (m, k, B, ...) → (m·k·B, ...)
                return x.reshape(-1, *x.shape[3:])

            obs = shifted(data.observations, m)[:, None].expand(m, k, *data.observations.shape)
            nxt = shifted(data.next_observations, k)[None].expand(
                m, k, *data.next_observations.shape)
            same = [None if x is None else rows(x[None, None].expand(m, k, *x.shape))
                    for x in (data.actions, data.dones, data.rewards, data.discounts)]
            return type(data)(rows(obs), same[0], rows(nxt), same[1], same[2], same[3])

    return AugmentedSamples


@cache
def critic_convs_policy() -> type:
    """SB3's SAC ``CnnPolicy`` with DrQ's tie (its code's ``copy_conv_weights_from`` and
    ``detach_encoder``): the actor's CNN keeps its own Linear head but reads the critic's
    convolutions, without gradient, so only the critic's loss trains them. The convolutions
    are not the actor's parameters: its optimiser leaves them to the critic's."""
    import torch as th
    from stable_baselines3.sac.policies import CnnPolicy

    class CriticConvs(th.nn.Module):
        def __init__(self, convs: th.nn.Module) -> None:
            super().__init__()
            object.__setattr__(self, "convs", convs)  # read, not owned: no submodule

        def forward(self, frames: th.Tensor) -> th.Tensor:
            with th.no_grad():
                return self.convs(frames)

    class CriticConvsPolicy(CnnPolicy):
        def _build(self, lr_schedule) -> None:
            super()._build(lr_schedule)
            self.actor.features_extractor.cnn = CriticConvs(self.critic.features_extractor.cnn)
            self.actor.optimizer = self.optimizer_class(
                self.actor.parameters(), lr=lr_schedule(1), **self.optimizer_kwargs)

    return CriticConvsPolicy


@cache
def periodic_target_sac() -> type:
    """SB3's SAC with ``target_update_interval`` counted over all the run's updates, as
    DrQ's ``critic_target_update_frequency`` is. SB3's ``SAC.train`` counts it within one
    call (``gradient_step % target_update_interval``), so at one update a call — every
    setting here — its targets move at every update whatever the interval. At interval 1
    this is SB3's SAC unchanged."""
    from stable_baselines3 import SAC

    class PeriodicTargetSAC(SAC):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            self.updates = 0

        def train(self, gradient_steps: int, batch_size: int = 64) -> None:
            if self.target_update_interval == 1:
                super().train(gradient_steps, batch_size)
                return
            tau = self.tau
            try:  # one update a call; at τ 0 SB3's Polyak step leaves the targets exact
                for _ in range(gradient_steps):
                    due = self.updates % self.target_update_interval == 0
                    self.tau = tau if due else 0.0
                    super().train(1, batch_size)
                    self.updates += 1
            finally:
                self.tau = tau

    return PeriodicTargetSAC


class SACAgent:
    def __init__(self, ctx: AgentContext):
        cfg: SACConfig = ctx.config
        venv = monitored_vec_env(ctx, 1)
        pixels = is_frame_stack(venv.observation_space)
        policy_kwargs = {"net_arch": list(cfg.net_arch), "optimizer_kwargs": {"fused": True}}
        if pixels:
            policy_kwargs["features_extractor_class"] = features_extractor_class(
                cfg.features_head)
            policy_kwargs["features_extractor_kwargs"] = {"features_dim": cfg.features_dim}
        policy = "MlpPolicy"
        if pixels:
            policy = critic_convs_policy() if cfg.actor_convs == "critic" else "CnnPolicy"
        self.model = with_precision(periodic_target_sac(), ctx.precision)(
            policy, venv,
            learning_rate=cfg.learning_rate, buffer_size=cfg.buffer_size,
            learning_starts=cfg.learning_starts, batch_size=cfg.batch_size, tau=cfg.tau,
            gamma=cfg.gamma, train_freq=cfg.train_freq, gradient_steps=cfg.gradient_steps,
            ent_coef=cfg.ent_coef, target_update_interval=cfg.target_update_interval,
            use_sde=cfg.use_sde, policy_kwargs=policy_kwargs, seed=ctx.seed, device="cpu",
            verbose=0, **self.buffer(cfg, venv.observation_space.shape[1:], ctx.seed))
        lay_out(self.model, ctx.memory_format)

    def buffer(self, cfg: SACConfig, frame: tuple[int, ...], seed: int) -> dict:
        """SAC's replay buffer arguments: SB3's own buffer."""
        return {}

    def act(self, observation: np.ndarray):
        action, _ = self.model.predict(observation, deterministic=True)
        return action

    def learn(self, budget: int, recorder: Recorder) -> None:
        learn_with_recorder(self.model, budget, recorder)


class DrQSACAgent(SACAgent):
    def buffer(self, cfg: DrQSACConfig, frame: tuple[int, ...], seed: int) -> dict:
        from senbench_agents.augment import scaled_pad

        pad = scaled_pad(*frame) if cfg.pad is None else cfg.pad
        return {"replay_buffer_class": augmented_samples(),
                "replay_buffer_kwargs": {"pad": pad, "k": cfg.k, "m": cfg.m, "seed": seed}}


ZOO_PENDULUM = AgentDefaults(
    values={"learning_rate": 1e-3},
    source="rl-baselines3-zoo hyperparams/sac.yml, Pendulum-v1",
)

SAC_SPACE = {  # after rl-baselines3-zoo's sample_sac_params
    "learning_rate": Float(1e-5, 1e-2, log=True),
    "batch_size": Choice((32, 64, 128, 256, 512)),
    "gamma": Choice((0.9, 0.95, 0.98, 0.99, 0.995)),
    "tau": Choice((0.001, 0.005, 0.01, 0.02, 0.05)),
    "train_freq": Choice((1, 4, 8, 16)),
}


ON_PIXELS = AgentDefaults(
    values=DRQ_SIZED, source="drq-sac's defaults without its shifts: DrQ's SAC (Kostrikov et "
    "al. 2020) sized to this machine")

SAC_SPEC = AgentSpec(
    name="sac", make=SACAgent, config=SACConfig, actions=frozenset({"continuous"}),
    observations=frozenset({"state", "encoded", "pixels"}),
    defaults={"pendulum": ZOO_PENDULUM, "pendulum-bars": ZOO_PENDULUM,
              "pendulum:pixels": ON_PIXELS, "pendulum-bars:pixels": ON_PIXELS},
    description="Stable-Baselines3 SAC: MLP actor and twin critics; a NatureCNN under each "
    "on pixels",
    search_space=SAC_SPACE, min_frame_size=NATURE_CNN_MIN_FRAME, precisions=PRECISIONS,
    memory_formats=MEMORY_FORMATS)

DRQ_SAC_SPEC = AgentSpec(
    name="drq-sac", make=DrQSACAgent, config=DrQSACConfig, actions=frozenset({"continuous"}),
    observations=frozenset({"pixels"}),
    description="DrQ's SAC: SB3's SAC on randomly shifted frames, target averaged over K "
    "shifts, critic loss over M (Kostrikov et al. 2020)",
    search_space=SAC_SPACE, min_frame_size=shifted_min_frame_size, precisions=PRECISIONS,
    memory_formats=MEMORY_FORMATS)
