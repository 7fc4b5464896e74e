"""Observation pipelines: what an agent sees of an env.

``state`` is the env's own observation vector (the true state); ``pixels`` a stack of
grayscale frames (see ``senbench.observe.pixels``); ``encoded`` those frames through a trained
state encoder (see ``senbench.encoders.cache``). Whatever the observation,
the physical state travels in ``info["state"]`` so that evaluation and encoder checks can
read it; an agent never receives it as its observation unless it runs on ``state``.

With an action repeat of k (an env's ``action_repeat``; the Arcade Learning Environment's
frame skip), each action the agent takes is held for k frames of the env, its rewards summed,
and the agent sees the frames at its decisions only: a stack of pixel frames then holds
frames k apart. ``info["frames"]`` says how many frames a step took (fewer than k where the
episode ended inside it).
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


class ActionRepeat(gymnasium.Wrapper):
    """Holds each action for ``repeat`` frames (or until the episode ends), returning the
    last frame's observation and info, the frames' summed reward, and in ``info["frames"]``
    the frames the step took. The episode cap (``max_episode_steps``) counts frames: it sits
    inside, on the env itself."""

    def __init__(self, env: gymnasium.Env, repeat: int):
        super().__init__(env)
        if repeat < 1:
            raise ValueError(f"action_repeat must be at least 1, got {repeat}")
        self.repeat = repeat

    def step(self, action):
        total, frames = 0.0, 0
        while frames < self.repeat:
            obs, reward, terminated, truncated, info = self.env.step(action)
            total, frames = total + float(reward), frames + 1
            if terminated or truncated:
                break
        return obs, total, terminated, truncated, {**info, "frames": frames}


def physical(env: gymnasium.Env, spec: EnvSpec, action_repeat: int) -> gymnasium.Env:
    """The env with its physical state in ``info`` and, for k > 1, each action held k frames."""
    env = PhysicalStateInfo(env, spec)
    return env if action_repeat == 1 else ActionRepeat(env, action_repeat)


def state_env(spec: EnvSpec, max_episode_steps: int, options: Mapping[str, Any],
              pixels: PixelSpec | None = None, encoder: Any = None,
              action_repeat: int = 1) -> gymnasium.Env:
    return physical(spec.make(max_episode_steps=max_episode_steps, **options), spec,
                    action_repeat)


def pixel_env(spec: EnvSpec, max_episode_steps: int, options: Mapping[str, Any],
              pixels: PixelSpec | None = None, encoder: Any = None,
              action_repeat: int = 1) -> gymnasium.Env:
    """Stacked grayscale frames, from the env plugin's renderer when it has one (and
    ``pixels.renderer`` is not "gymnasium"), else from gymnasium's ``render()``; with an
    action repeat, the frames at the agent's decisions."""
    pixels = pixels or PixelSpec()
    if spec.render is not None and pixels.renderer != "gymnasium":
        env = spec.make(max_episode_steps=max_episode_steps, **options)
        draw = rendered_frames(spec.render, pixels)
    else:
        env = spec.make(max_episode_steps=max_episode_steps, render_mode="rgb_array", **options)
        draw = gymnasium_frames(pixels)
    return FrameStack(physical(env, spec, action_repeat), draw, pixels)


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
                pixels: PixelSpec | None = None, encoder: Any = None,
                action_repeat: int = 1) -> gymnasium.Env:
    if encoder is None:
        raise ValueError("the encoded observation needs a trained state encoder")
    if action_repeat != 1:  # the samplers draw stacks of consecutive frames
        raise ValueError("an encoded observation takes no action repeat: its encoder was "
                         "trained on stacks of consecutive frames")
    return EncodedObservation(pixel_env(spec, max_episode_steps, options, pixels), encoder)


Builder = Callable[..., gymnasium.Env]
OBSERVATIONS: dict[str, Builder] = {
    "state": state_env,
    "pixels": pixel_env,
    "encoded": encoded_env,
}
"""Observation name → ``build(env_spec, max_episode_steps, options, pixels, encoder,
action_repeat)``."""


def make_env(spec: EnvSpec, observation: str, max_episode_steps: int,
             options: Mapping[str, Any], pixels: PixelSpec | None = None,
             encoder: Any = None, action_repeat: int = 1) -> gymnasium.Env:
    return OBSERVATIONS[observation](spec, max_episode_steps, options, pixels, encoder,
                                     action_repeat)
