"""What every Stable-Baselines3 agent shares: a vectorised env from the cell's observation
pipeline, and learning that reports through the recorder and stops at the budget."""

from __future__ import annotations

from functools import cache
from typing import Any, Literal, get_args

from senbench import AgentContext, Recorder

NATURE_CNN_MIN_FRAME = 36
"""SB3's NatureCNN (the CnnPolicy's features extractor) takes frames of at least 36x36: its
convolutions (8x8 stride 4, 4x4 stride 2, 3x3 stride 1) leave nothing of a 35x35 frame."""


def is_frame_stack(space) -> bool:
    """A pixel observation: (stack, H, W) uint8, for SB3's CnnPolicy."""
    import numpy as np
    from gymnasium.spaces import Box

    return isinstance(space, Box) and space.dtype == np.uint8 and len(space.shape) == 3


def monitored_vec_env(ctx: AgentContext, n_envs: int):
    from stable_baselines3.common.monitor import Monitor
    from stable_baselines3.common.vec_env import DummyVecEnv

    return DummyVecEnv([lambda: Monitor(ctx.make_env()) for _ in range(n_envs)])


def learn_with_recorder(model, budget: int, recorder: Recorder) -> None:
    """model.learn, reporting frames and finished episodes to ``recorder`` after every
    vectorised step and stopping exactly when it says the budget is spent."""
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.logger import Logger

    class Report(BaseCallback):
        def _on_step(self) -> bool:
            for info in self.locals["infos"]:
                episode = info.get("episode")
                if episode is not None:
                    recorder.episode(self.num_timesteps, float(episode["r"]), int(episode["l"]))
            return recorder.step(self.num_timesteps)

    # A logger that writes nothing: left to itself, learn() makes a /tmp/SB3-<timestamp>
    # folder per model, a cell or a test. The recorder is the cell's only log.
    model.set_logger(Logger(folder=None, output_formats=[]))
    if recorder.step(0):
        # total_timesteps = budget: SB3's schedules (DQN's exploration) span the budget; the
        # callback stops collection at the budget itself, mid-rollout if need be.
        model.learn(total_timesteps=budget, callback=Report())


FeaturesHead = Literal["relu", "layernorm-tanh"]
"""The last layer of an agent's CNN on pixels: SB3's NatureCNN as it is (Linear, ReLU), or
DrQ's encoder head (Linear, LayerNorm, tanh: Kostrikov et al. 2020, its code's Encoder)."""


def features_extractor_class(head: str) -> type:
    """SB3's NatureCNN with ``head`` as its last layer, for a policy's
    ``features_extractor_class``. A ReLU head can die whole: every feature 0 on every frame,
    the network after it then blind (measured on drq-sac, REPRODUCTION.md); LayerNorm keeps
    the features spread over frames and tanh bounds them."""
    from stable_baselines3.common.torch_layers import NatureCNN

    if head == "relu":
        return NatureCNN
    if head != "layernorm-tanh":
        raise ValueError(f"features_head must be one of {', '.join(get_args(FeaturesHead))}, "
                         f"got {head!r}")
    return _layer_norm_tanh_cnn()


@cache
def _layer_norm_tanh_cnn() -> type:
    import torch as th
    from stable_baselines3.common.torch_layers import NatureCNN

    class LayerNormTanhCNN(NatureCNN):
        """NatureCNN whose features are Linear → LayerNorm → tanh. The Linear is
        NatureCNN's own, so the two draw the same initial weights from one seed."""

        def __init__(self, observation_space, features_dim: int = 512,
                     normalized_image: bool = False) -> None:
            super().__init__(observation_space, features_dim, normalized_image)
            self.linear = th.nn.Sequential(self.linear[0], th.nn.LayerNorm(features_dim),
                                           th.nn.Tanh())

    return LayerNormTanhCNN


PRECISIONS = frozenset({"fp32", "bf16"})
"""What every SB3 agent offers: its updates in fp32, or in bf16 under torch.autocast."""


def lay_out(model: Any, memory_format: str) -> None:
    """Lay out the 4-d weights of ``model``'s networks (an SB3 model's policy: online and
    target networks alike) as ``memory_format``. The parameters stay the same objects, so
    the optimiser already built over them goes on; a convolution with NHWC weights computes
    NHWC whatever its input's layout, and its gradients follow its weights."""
    if memory_format == "contiguous":
        return
    if memory_format != "channels_last":
        raise ValueError(f"memory_format must be contiguous or channels_last, "
                         f"got {memory_format!r}")
    import torch as th

    model.policy.to(memory_format=th.channels_last)


def with_precision(algorithm: type, precision: str) -> type:
    """``algorithm`` (an SB3 class) whose ``train`` (the network updates) runs under
    ``torch.autocast("cpu", dtype=torch.bfloat16)`` for ``bf16``: matrix products and
    convolutions in bf16, losses and the optimiser's state in fp32 (autocast's own rules).
    Acting stays fp32. ``fp32``: the class itself."""
    if precision == "fp32":
        return algorithm
    if precision != "bf16":
        raise ValueError(f"precision must be fp32 or bf16, got {precision!r}")
    import torch as th

    class BF16(algorithm):
        def train(self, *args, **kwargs):
            with th.autocast("cpu", dtype=th.bfloat16):
                return super().train(*args, **kwargs)

    BF16.__name__ = BF16.__qualname__ = f"{algorithm.__name__}BF16"
    return BF16
