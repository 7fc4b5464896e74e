"""A trained state encoder as a callable: frames in, estimated observation out."""

from __future__ import annotations

import copy
import warnings
from typing import Any

import numpy as np

from senbench.encoders.request import EncoderRequest
from senbench.plugin.registry import Registries


class StateEncoder:
    """Frames → estimated observation: the trained network, its target normalisation, and
    the observation bounds its output is clipped to."""

    def __init__(self, model: Any, mean: np.ndarray, std: np.ndarray, low: np.ndarray,
                 high: np.ndarray, traceable: bool = False,
                 memory_format: str = "contiguous"):
        import torch

        self.model = model.eval()
        self.mean = torch.as_tensor(mean, dtype=torch.float32)
        self.std = torch.as_tensor(std, dtype=torch.float32)
        self.low, self.high = np.asarray(low, np.float32), np.asarray(high, np.float32)
        self.traceable = traceable
        self.memory_format = memory_format
        self._frozen: dict[tuple[int, ...], Any] = {}

    def laid_out(self, memory_format: str) -> StateEncoder:
        """This encoder with its network's 4-d weights laid out as ``memory_format``
        (``contiguous``: itself; ``channels_last``: a copy, NHWC, which oneDNN's CPU
        convolutions run faster; its outputs differ from NCHW's by float rounding)."""
        import torch

        if memory_format == "contiguous":
            return self
        if memory_format != "channels_last":
            raise ValueError(f"memory_format must be contiguous or channels_last, "
                             f"got {memory_format!r}")
        model = copy.deepcopy(self.model).to(memory_format=torch.channels_last)
        return StateEncoder(model, self.mean.numpy(), self.std.numpy(), self.low, self.high,
                            self.traceable, memory_format)

    def __call__(self, frames: np.ndarray) -> np.ndarray:
        """(B, stack, H, W) uint8 → (B, k) float32."""
        import torch

        with torch.inference_mode():
            x = torch.as_tensor(np.asarray(frames), dtype=torch.float32) / 255.0
            if self.memory_format == "channels_last":
                x = x.contiguous(memory_format=torch.channels_last)
            y = self._network(x)(x) * self.std + self.mean
        return np.clip(y.numpy(), self.low, self.high)

    def _network(self, x: Any) -> Any:
        """For an architecture that declares itself traceable, the model frozen into
        TorchScript for this input shape (1.4-1.6x faster at batch 1, where a SEN-SARSA step
        spends most of its time), kept only if it gives the eager model's outputs."""
        import torch

        if not self.traceable:
            return self.model
        shape = tuple(x.shape)
        if shape not in self._frozen:
            self._frozen[shape] = self.model
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    frozen = torch.jit.freeze(torch.jit.trace(self.model, x,
                                                              check_trace=False))
                    same = torch.allclose(frozen(x), self.model(x), rtol=1e-4, atol=1e-5)
            except Exception:  # noqa: BLE001 - a network TorchScript cannot take stays eager
                same = False
            if same:
                self._frozen[shape] = frozen
        return self._frozen[shape]


def observation_bounds(env_spec: Any) -> tuple[np.ndarray, np.ndarray]:
    space = env_spec.make(max_episode_steps=1).observation_space
    return np.asarray(space.low, np.float32), np.asarray(space.high, np.float32)


def build_model(request: EncoderRequest, regs: Registries, outputs: int) -> Any:
    arch = regs.encoders.get(request.arch)
    config = arch.config(**request.arch_config)
    shape = (request.pixels.stack, request.pixels.height, request.pixels.width)
    return arch.build(shape, outputs, config)
