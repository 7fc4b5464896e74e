"""States drawn uniformly from the env's state bounds, with frame stacks the real dynamics
would produce: set the oldest state, render, step with a random action, render, … The
label is the observation of the newest state, so the stack carries the velocity."""

from __future__ import annotations

import numpy as np
from pydantic.dataclasses import dataclass

from senbench import EnvSpec, PixelSpec, SamplerSpec


@dataclass
class UniformConfig:
    pass


def sample(env: EnvSpec, count: int, pixels: PixelSpec, seed: int,
           config: UniformConfig | None = None) -> tuple[np.ndarray, np.ndarray]:
    if env.set_state is None or env.render is None or env.observe is None:
        raise ValueError(f"env '{env.name}' cannot be put in a chosen state (set_state), "
                         "drawn from one (render) or observed (observe): use the rollout "
                         "sampler")
    if pixels.renderer == "gymnasium":
        raise ValueError("the uniform sampler draws with the env plugin's renderer, but these "
                         "observations come from gymnasium's render(): use the rollout "
                         "sampler, or renderer: auto")
    rng = np.random.default_rng(seed)
    dynamics = env.make(max_episode_steps=2**31 - 1)
    dynamics.reset(seed=seed)
    dynamics.action_space.seed(seed)
    base = dynamics.unwrapped
    low, high = np.asarray(env.state_low), np.asarray(env.state_high)
    states = np.empty((count, pixels.stack, len(low)))
    states[:, 0] = rng.uniform(low, high, size=(count, len(low)))
    for i in range(count):
        env.set_state(base, states[i, 0])
        for k in range(1, pixels.stack):
            base.step(dynamics.action_space.sample())
            states[i, k] = env.physical_state(base)
    frames = env.render(states.reshape(-1, len(low)), pixels.size)
    frames = frames.reshape(count, pixels.stack, *pixels.size)
    return frames, env.observe(states[:, -1])


UNIFORM = SamplerSpec(
    name="uniform",
    sample=sample,
    config=UniformConfig,
    description="states uniform in the state bounds; stacks from the real dynamics",
    labels="states set by hand, uniform in the bounds",
    needs=frozenset({"set_state", "render", "observe"}),
)
