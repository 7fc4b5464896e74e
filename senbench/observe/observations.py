"""Observation pipelines: what an agent sees of an env.

``state`` is the env's own observation vector (the true state); ``pixels`` a stack of
grayscale frames (see ``senbench.observe.pixels``); ``encoded`` those frames through a trained
state encoder (see ``senbench.encoders.cache``). Whatever the observation,
the physical state travels in ``info["state"]`` so that evaluation and encoder checks can
read it; an agent never receives it as its observation unless it runs on ``state``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import gymnasium
import numpy as np

from senbench.observe.pixels import FrameStack, PixelSpec, gymnasium_frames, rendered_frames
from senbench.plugin.specs import EnvSpec


class PhysicalStateInfo(gymnasium.Wrapper):
    """Puts the physical state (the env spec's ``state_labels`` order) in ``info["state"]``."""

    def __init__(self, env: gymnasium.Env, spec: EnvSpec):
        super().__init__(env)
        self._read_state: Callable[[Any], np.ndarray] = spec.physical_state

    def reset(self, **kwargs):
        obs, info = self.env.reset(**kwargs)
        return obs, {**info, "state": self._read_state(self.env.unwrapped)}

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        state = self._read_state(self.env.unwrapped)
        return obs, reward, terminated, truncated, {**info, "state": state}


def state_env(spec: EnvSpec, max_episode_steps: int, options: Mapping[str, Any],
              pixels: PixelSpec | None = None, encoder: Any = None) -> gymnasium.Env:
    return PhysicalStateInfo(spec.make(max_episode_steps=max_episode_steps, **options), spec)


def pixel_env(spec: EnvSpec, max_episode_steps: int, options: Mapping[str, Any],
              pixels: PixelSpec | None = None, encoder: Any = None) -> gymnasium.Env:
    """Stacked grayscale frames, from the env plugin's renderer when it has one (and
    ``pixels.renderer`` is not "gymnasium"), else from gymnasium's ``render()``."""
    pixels = pixels or PixelSpec()
    if spec.render is not None and pixels.renderer != "gymnasium":
        env = spec.make(max_episode_steps=max_episode_steps, **options)
        draw = rendered_frames(spec.render, pixels)
    else:
        env = spec.make(max_episode_steps=max_episode_steps, render_mode="rgb_array", **options)
        draw = gymnasium_frames(pixels)
    return FrameStack(PhysicalStateInfo(env, spec), draw, pixels)


class EncodedObservation(gymnasium.ObservationWrapper):
    """The frame stack → the state encoder's estimate of the state observation, clipped to
    the observation bounds. The agent sees the estimate only."""

    def __init__(self, env: gymnasium.Env, encoder: Any):
        super().__init__(env)
        self._encoder = encoder
        self.observation_space = gymnasium.spaces.Box(encoder.low, encoder.high,
                                                      dtype=np.float32)

    def observation(self, frames: np.ndarray) -> np.ndarray:
        return self._encoder(frames[None])[0]


def encoded_env(spec: EnvSpec, max_episode_steps: int, options: Mapping[str, Any],
                pixels: PixelSpec | None = None, encoder: Any = None) -> gymnasium.Env:
    if encoder is None:
        raise ValueError("the encoded observation needs a trained state encoder")
    return EncodedObservation(pixel_env(spec, max_episode_steps, options, pixels), encoder)


Builder = Callable[..., gymnasium.Env]
OBSERVATIONS: dict[str, Builder] = {
    "state": state_env,
    "pixels": pixel_env,
    "encoded": encoded_env,
}
"""Observation name → ``build(env_spec, max_episode_steps, options, pixels, encoder)``."""


def make_env(spec: EnvSpec, observation: str, max_episode_steps: int,
             options: Mapping[str, Any], pixels: PixelSpec | None = None,
             encoder: Any = None) -> gymnasium.Env:
    return OBSERVATIONS[observation](spec, max_episode_steps, options, pixels, encoder)
