"""The same tasks drawn as plain pictures of their state: a positive control for pixel
learners.

``mountaincar-bars`` and ``pendulum-bars`` have the dynamics, rewards and thresholds of
``mountaincar`` and ``pendulum``; only the frame differs. It shows one horizontal bar per
observation dimension (MountainCar: position, velocity; Pendulum: cos θ, sin θ, θ̇), each in
its own band of rows, its length proportional to the value within the dimension's bounds.
Everything an agent on the state sees is in every single frame, with no scene to parse, so
a pixel learner that cannot learn here has a broken pipeline or settings — not a hard
scene. Where it learns here and not on the real scene, the scene is what makes it hard.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

from senbench import EnvSpec


def bar_renderer(observe: Callable[[np.ndarray], np.ndarray], low: tuple[float, ...],
                 high: tuple[float, ...]) -> Callable[[np.ndarray, tuple[int, int]], np.ndarray]:
    """``render(states (B, d), (H, W)) -> (B, H, W) uint8``: white bars on black, one per
    observation dimension, with a one-row gap between bands."""
    low_, high_ = np.asarray(low, np.float64), np.asarray(high, np.float64)

    def render(states: np.ndarray, size: tuple[int, int]) -> np.ndarray:
        height, width = size
        values = np.asarray(observe(np.asarray(states, np.float64)), np.float64)
        fraction = np.clip((values - low_) / (high_ - low_), 0.0, 1.0)  # (B, k)
        k = fraction.shape[1]
        band = height // k
        # the bar covers columns [0, fraction · width): the last column partly, so that the
        # frame changes with every change of the value, not only at whole pixels
        filled = np.clip(fraction[:, :, None] * width - np.arange(width), 0.0, 1.0)  # (B,k,W)
        frames = np.zeros((len(values), height, width), np.float64)
        for i in range(k):
            frames[:, i * band: (i + 1) * band - 1, :] = filled[:, i, None, :]
        return np.round(frames * 255).astype(np.uint8)

    return render


def with_bars(spec: EnvSpec, low: tuple[float, ...], high: tuple[float, ...]) -> EnvSpec:
    """``spec`` renamed ``<name>-bars``, drawn as bars of its observation in [low, high]."""
    assert spec.observe is not None
    return dataclasses.replace(
        spec, name=f"{spec.name}-bars", render=bar_renderer(spec.observe, low, high),
        description=f"{spec.name} drawn as a bar per observation dimension (a pixel "
                    "learner's positive control)")
