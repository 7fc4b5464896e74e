"""DrQ for discrete actions (Kostrikov, Yarats & Fergus 2020): DQN whose updates see
randomly shifted frames, with the target averaged over K shifts of the next frames and the
loss over M shifts of the frames:

    y_i = r_i + γ (1 − done_i) · 1/K Σ_k max_a Q_target(shift_k(s'_i), a)
    L   = 1/(B M) Σ_{i,m} Huber(Q(shift_m(s_i), a_i) − y_i)

With ``double``, the online network chooses the next action on the same shifted frames
(Q_target(shift_k(s'), argmax_a Q(shift_k(s'), a))), as DrQ's Atari agent does.

Built on SB3's DQN the way ``ddqn`` is: ``DQN.train`` is used as it is and handed, in
place of its two networks, wrappers that shift: the online one shifts each frame stack it
is given; the target one computes the K-averaged value above and returns it as the only
finite entry of its row, so that ``train``'s max over actions reads it. For M > 1 the replay
buffer returns each sampled transition M times (:class:`RepeatedSamples`): the online wrapper
shifts each copy on its own, the target wrapper computes y once per transition and repeats
it. The policy's own networks are never wrapped, so acting, in training and in evaluation,
sees the frames unshifted.
"""

from __future__ import annotations

from functools import cache
from typing import Annotated

from pydantic import Field
from pydantic.dataclasses import dataclass

from senbench import MEMORY_FORMATS, AgentSpec, Choice
from senbench_agents.augment import min_frame_size, scaled_pad
from senbench_agents.dqn import DQN_SPACE, DQNAgent, DQNConfig
from senbench_agents.ranges import NonNegativeInt, PositiveInt, Probability
from senbench_agents.sb3 import PRECISIONS


@dataclass
class DrQConfig(DQNConfig):
    """DrQ's Atari 100k agent (Dopamine's DrQ.gin, built from the DrQ authors' code), sized
    to this project's budgets; each departure from it says why below, and the published
    set is in docs/builtin-plugins.md."""

    learning_starts: NonNegativeInt = 1600
    """Frames before the first update (DrQ's 1,600)."""
    train_freq: PositiveInt = 4
    """Frames between updates. DrQ updates every frame; 4 is the paper's pixel DQN's ratio,
    at 2.8x the frames/s of every frame here (benchmarks/drq_sizing.py)."""
    target_update_interval: PositiveInt = 1
    """Frames between target copies: 1, so the target is the online network as it was
    before the update (DrQ copies it at every update)."""
    exploration_final_eps: Probability = 0.1
    """DrQ's training ε (DrQ(ε): 0.01). Its decay spans ``exploration_fraction`` of the
    budget (DrQ: 5,000 frames after its warm-up; SB3 schedules by fraction)."""
    pad: Annotated[int, Field(ge=0)] | None = None
    """Pixels a frame may shift in each direction; None: DrQ's 4 at 84x84 scaled to the
    frame (3 at 64x64). At most half the frame."""
    k: PositiveInt = 1
    """Shifts of the next frames the target is averaged over (DrQ's K)."""
    m: PositiveInt = 1
    """Shifts of the frames the loss is averaged over (DrQ's M)."""
    double: bool = True
    """The online network chooses the next action (Double DQN), as DrQ's Atari agent."""
    n_steps: PositiveInt = 10
    """Rewards summed before bootstrapping (SB3's n-step replay; DrQ's 10)."""

    def __post_init__(self) -> None:
        if self.n_steps > 1 and self.optimize_memory_usage:
            raise ValueError("n_steps > 1 needs optimize_memory_usage: false (SB3's n-step "
                             "replay stores next observations)")


@cache
def sb3_classes() -> tuple[type, type, type]:
    """(DrQ, RepeatedSamples, RepeatedNStepSamples), built on first use so that listing
    plugins does not import torch."""
    import torch as th
    from stable_baselines3 import DQN
    from stable_baselines3.common.buffers import NStepReplayBuffer, ReplayBuffer

    from senbench_agents.augment import random_shift

    class Repeat:
        """A replay buffer whose samples hold each transition ``repeats`` times, the copies
        one after the other: rows i, B + i, 2B + i, ... are transition i."""

        def __init__(self, *args, repeats: int = 1, **kwargs):
            super().__init__(*args, **kwargs)
            self.repeats = repeats

        def sample(self, batch_size, env=None):
            data = super().sample(batch_size, env)
            if self.repeats == 1:
                return data
            return type(data)(*(None if x is None else x.repeat(self.repeats, *[1] * (x.ndim - 1))
                                for x in data))

    class RepeatedSamples(Repeat, ReplayBuffer):
        pass

    class RepeatedNStepSamples(Repeat, NStepReplayBuffer):
        pass

    class Shifted(th.nn.Module):
        """train()'s online network: the policy's, on shifted frames. Its parameters are the
        online network's, in their order, as SB3's target update (a pairwise copy) needs."""

        def __init__(self, online: th.nn.Module, shift):
            super().__init__()
            self.online = online
            self.shift = shift

        def forward(self, obs: th.Tensor) -> th.Tensor:
            return self.online(self.shift(obs))

    class AveragedTarget(th.nn.Module):
        """train()'s target network: each row's max over actions is the DrQ target value.
        Its parameters and buffers are the target network's alone (SB3's target update
        copies pairwise from the online network's)."""

        def __init__(self, online: th.nn.Module, target: th.nn.Module, shift, k: int,
                     m: int, double: bool):
            super().__init__()
            self.target = target
            object.__setattr__(self, "online", online)
            self.shift, self.k, self.m, self.double = shift, k, m, double

        def forward(self, next_obs: th.Tensor) -> th.Tensor:
            transitions = next_obs[: next_obs.shape[0] // self.m]  # the copies repeat it
            total = 0.0
            for _ in range(self.k):
                shifted = self.shift(transitions)
                q = self.target(shifted)
                if self.double:
                    best = self.online(shifted).argmax(dim=1, keepdim=True)
                    total = total + q.gather(1, best).squeeze(1)
                else:
                    total = total + q.max(dim=1).values
            value = (total / self.k).repeat(self.m)
            out = th.full((value.shape[0], q.shape[1]), -th.inf, dtype=q.dtype, device=q.device)
            out[:, 0] = value
            return out

    class DrQ(DQN):
        def __init__(self, *args, pad: int, k: int, m: int, double: bool, **kwargs):
            self.pad, self.k, self.m, self.double = pad, k, m, double
            super().__init__(*args, **kwargs)

        def _setup_model(self) -> None:
            super()._setup_model()
            generator = th.Generator().manual_seed(self.seed if self.seed is not None else 0)

            def shift(frames: th.Tensor) -> th.Tensor:
                return random_shift(frames, self.pad, generator)

            # train()'s aliases only: the policy's q_net and q_net_target stay as they are
            self.q_net = Shifted(self.policy.q_net, shift)
            self.q_net_target = AveragedTarget(self.policy.q_net, self.policy.q_net_target,
                                               shift, self.k, self.m, self.double)

    return DrQ, RepeatedSamples, RepeatedNStepSamples


class DrQAgent(DQNAgent):
    def algorithm(self, cfg: DrQConfig, frame: tuple[int, int]) -> tuple[type, dict]:
        drq, repeated, repeated_n_step = sb3_classes()
        buffer_kwargs = {"repeats": cfg.m}
        if cfg.n_steps > 1:
            buffer_kwargs.update(n_steps=cfg.n_steps, gamma=cfg.gamma)
        return drq, {
            "pad": scaled_pad(*frame) if cfg.pad is None else cfg.pad, "k": cfg.k, "m": cfg.m,
            "double": cfg.double,
            "replay_buffer_class": repeated_n_step if cfg.n_steps > 1 else repeated,
            "replay_buffer_kwargs": buffer_kwargs}


DRQ_SPEC = AgentSpec(
    name="drq", make=DrQAgent, config=DrQConfig, actions=frozenset({"discrete"}),
    observations=frozenset({"pixels"}),
    description="DrQ: SB3's DQN on randomly shifted frames, target averaged over K shifts, "
    "loss over M (Kostrikov et al. 2020)",
    # DrQ copies its target at every update (target_update_interval 1, its default): the
    # zoo's DQN choices (500 to 10,000) hold no such value, so a study of DrQ would not
    # run its own settings as trial 0 without it
    search_space={**DQN_SPACE,
                  "target_update_interval": Choice((1, 500, 1000, 5000, 10000))},
    min_frame_size=min_frame_size, precisions=PRECISIONS, memory_formats=MEMORY_FORMATS)
