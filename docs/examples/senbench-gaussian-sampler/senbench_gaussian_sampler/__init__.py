"""senbench sampler plugin: ``gaussian``, labelled (frames, observation) pairs of states
drawn from a normal distribution around the centre of the env's state bounds.

Where an agent spends its time is rarely uniform over the bounds: on CartPole, near the
upright pole in the middle of the track. This sampler puts the encoder's training data
there. Each frame stack comes from the real dynamics: set the oldest state, render, step
with a random action, render, ... The label is the observation of the newest state.
"""

from dataclasses import dataclass

import numpy as np

import senbench


@dataclass
class GaussianConfig:
    scale: float = 0.25
    """Standard deviation of each dimension, as a share of its range (states outside the
    bounds are clipped to them)."""

    def __post_init__(self):
        if not self.scale > 0:
            raise ValueError(f"scale must be positive, got {self.scale}")


def sample(env: senbench.EnvSpec, count: int, pixels: senbench.PixelSpec, seed: int,
           config: GaussianConfig) -> tuple[np.ndarray, np.ndarray]:
    """(frames (count, stack, H, W) uint8, oldest first; observations (count, k) float32,
    each that of its stack's newest state). The same seed gives the same pairs. The env has
    set_state, render and observe: ``needs`` below makes validation check it."""
    rng = np.random.default_rng(seed)
    dynamics = env.make(max_episode_steps=2**31 - 1)
    dynamics.reset(seed=seed)
    dynamics.action_space.seed(seed)
    base = dynamics.unwrapped
    low, high = np.asarray(env.state_low), np.asarray(env.state_high)
    centre, spread = (low + high) / 2, config.scale * (high - low)
    states = np.empty((count, pixels.stack, len(low)))
    states[:, 0] = np.clip(rng.normal(centre, spread, size=(count, len(low))), low, high)
    for i in range(count):
        env.set_state(base, states[i, 0])
        for k in range(1, pixels.stack):
            base.step(dynamics.action_space.sample())
            states[i, k] = env.physical_state(base)
    frames = env.render(states.reshape(-1, len(low)), pixels.size)
    frames = frames.reshape(count, pixels.stack, *pixels.size)
    return frames, env.observe(states[:, -1])


GAUSSIAN = senbench.SamplerSpec(
    name="gaussian",
    sample=sample,
    config=GaussianConfig,
    description="states normal around the centre of the bounds; stacks from the dynamics",
    labels="states set by hand, normal around the centre of the bounds",
    needs=frozenset({"set_state", "render", "observe"}),
)


@senbench.hookimpl
def register_samplers(register):
    register(GAUSSIAN)
