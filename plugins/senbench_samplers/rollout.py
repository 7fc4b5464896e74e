"""Frames from episodes of a random policy, as an agent would see them: no state is ever
set by hand, so this works for any env with pixels, and covers only the states a random
policy reaches (on MountainCar, the bottom of the valley)."""

from __future__ import annotations

from typing import Annotated

import numpy as np
from pydantic import Field
from pydantic.dataclasses import dataclass

from senbench import EnvSpec, PixelSpec, SamplerSpec, make_env


@dataclass
class RolloutConfig:
    repeat: Annotated[int, Field(ge=1)] = 1
    """Steps each random action is held: longer holds reach farther on MountainCar."""


def sample(env: EnvSpec, count: int, pixels: PixelSpec, seed: int,
           config: RolloutConfig | None = None) -> tuple[np.ndarray, np.ndarray]:
    config = config or RolloutConfig()
    if env.observe is None:
        raise ValueError(f"env '{env.name}' has no observe(): no labels for its frames")
    game = make_env(env, "pixels", env.max_episode_steps, {}, pixels)
    game.action_space.seed(seed)
    frames = np.empty((count, pixels.stack, *pixels.size), dtype=np.uint8)
    states = []
    obs, info = game.reset(seed=seed)
    held = 0
    for i in range(count):
        frames[i] = obs
        states.append(info["state"])
        if held == 0:
            action, held = game.action_space.sample(), config.repeat
        obs, _, terminated, truncated, info = game.step(action)
        held -= 1
        if terminated or truncated:
            obs, info = game.reset()
            held = 0
    return frames, env.observe(np.asarray(states))


ROLLOUT = SamplerSpec(
    name="rollout",
    sample=sample,
    config=RolloutConfig,
    description="frames of random-policy episodes, labelled with their states",
    labels="random-policy rollouts from the env's resets",
    needs=frozenset({"observe"}),
)
