"""Pixel observations: stacks of grayscale frames, ``(stack, H, W)`` uint8.

Two ways to get frames: an env plugin's own renderer (``EnvSpec.render``: physical states
to frames, batched, fast), or, for any gymnasium env with ``render_mode="rgb_array"``,
gymnasium's render → grayscale → area resize. Either way the stack holds the most recent
frames oldest first (``obs[-1]`` is the newest) and is refilled with the first frame at
every reset, so an agent never sees frames of the previous episode.
"""

from __future__ import annotations

import functools
import os
from collections.abc import Callable
from dataclasses import dataclass

import gymnasium
import numpy as np

LUMA = np.array([0.299, 0.587, 0.114], dtype=np.float32)  # ITU-R 601, as PIL's "L" mode


@dataclass(frozen=True)
class PixelSpec:
    height: int = 64
    width: int = 64
    stack: int = 2
    """Frames per observation: one frame shows no velocity."""
    renderer: str = "auto"
    """"auto": the env plugin's renderer if it has one; "gymnasium": gymnasium's render()."""

    @property
    def size(self) -> tuple[int, int]:
        return (self.height, self.width)


def to_gray(rgb: np.ndarray) -> np.ndarray:
    """(..., H, W, 3) uint8 RGB → (..., H, W) float32 luma in [0, 255]."""
    return np.ascontiguousarray(rgb, dtype=np.float32) @ LUMA


@functools.lru_cache(maxsize=32)
def _area_matrix(source: int, target: int) -> np.ndarray:
    """(target, source) weights: each output pixel averages the source pixels it covers,
    partial ones by their covered share — area resampling, for any ratio."""
    edges = np.arange(target + 1) * source / target
    lo, hi = edges[:-1, None], edges[1:, None]
    pixel = np.arange(source)[None, :]
    overlap = np.clip(np.minimum(hi, pixel + 1) - np.maximum(lo, pixel), 0.0, None)
    return (overlap / (hi - lo)).astype(np.float32)


def area_resize(gray: np.ndarray, height: int, width: int) -> np.ndarray:
    """Area-resize (H, W) float frames to (height, width) float32."""
    rows = _area_matrix(gray.shape[-2], height)
    cols = _area_matrix(gray.shape[-1], width)
    # A transposed view (pygame's frames are) sends matmul down a path ~10x slower.
    return rows @ np.ascontiguousarray(gray, dtype=np.float32) @ cols.T


def quantize(gray: np.ndarray) -> np.ndarray:
    return np.clip(gray + 0.5, 0, 255).astype(np.uint8)


class FrameStack(gymnasium.Wrapper):
    """Replaces the observation by a stack of frames drawn by ``draw(env, info)``."""

    def __init__(self, env: gymnasium.Env, draw: Callable[[gymnasium.Env, dict], np.ndarray],
                 spec: PixelSpec):
        super().__init__(env)
        self._draw = draw
        self._frames = np.zeros((spec.stack, spec.height, spec.width), dtype=np.uint8)
        self.observation_space = gymnasium.spaces.Box(0, 255, self._frames.shape, np.uint8)

    def reset(self, **kwargs):
        _, info = self.env.reset(**kwargs)
        self._frames[:] = self._draw(self.env, info)
        return self._frames.copy(), info

    def step(self, action):
        _, reward, terminated, truncated, info = self.env.step(action)
        self._frames[:-1] = self._frames[1:]
        self._frames[-1] = self._draw(self.env, info)
        return self._frames.copy(), reward, terminated, truncated, info


def rendered_frames(render: Callable[[np.ndarray, tuple[int, int]], np.ndarray],
                    spec: PixelSpec) -> Callable[[gymnasium.Env, dict], np.ndarray]:
    """Frames from an env plugin's renderer and the physical state in ``info["state"]``."""

    def draw(env: gymnasium.Env, info: dict) -> np.ndarray:
        return render(np.asarray(info["state"])[None, :], spec.size)[0]

    return draw


def headless_pygame() -> None:
    """gymnasium's classic-control envs render with pygame, which wants a display (and
    complains on stderr) unless told there is none. Call before the env renders."""
    os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
    os.environ.setdefault("SDL_AUDIODRIVER", "dummy")


def gymnasium_frames(spec: PixelSpec) -> Callable[[gymnasium.Env, dict], np.ndarray]:
    """Frames from gymnasium's own ``render()`` (the env needs render_mode="rgb_array")."""
    headless_pygame()

    def draw(env: gymnasium.Env, info: dict) -> np.ndarray:
        rgb = env.render()
        if rgb is None:
            raise ValueError("the env returned no frame: make it with render_mode='rgb_array'")
        return quantize(area_resize(to_gray(np.asarray(rgb)), spec.height, spec.width))

    return draw
