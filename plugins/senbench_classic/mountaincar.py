"""MountainCar: an under-powered car in a valley must rock back and forth to reach the flag.

State (position m, velocity m/step), three actions (push left, none, right), reward −1 per
step until the car reaches position 0.5. gymnasium's ``MountainCar-v0`` dynamics.
"""

import gymnasium
import numpy as np

from senbench import EnvSpec
from senbench_classic.renderers import render_mountaincar


def make(max_episode_steps: int = 200, render_mode: str | None = None,
         goal_velocity: float = 0.0) -> gymnasium.Env:
    return gymnasium.make("MountainCar-v0", max_episode_steps=max_episode_steps,
                          render_mode=render_mode, goal_velocity=goal_velocity)


def physical_state(env: gymnasium.Env) -> np.ndarray:
    return np.asarray(env.state, dtype=np.float64)


def set_state(env: gymnasium.Env, state: np.ndarray) -> None:
    env.state = np.asarray(state, dtype=np.float64).copy()


def observe(states: np.ndarray) -> np.ndarray:
    return np.asarray(states, dtype=np.float32)  # the observation is the state


def pump_energy(observation: np.ndarray) -> int:
    """Push the way the car moves: it rocks higher each swing and reaches the flag in
    about 100-120 steps from the valley."""
    return 2 if observation[1] >= 0 else 0


MOUNTAINCAR = EnvSpec(
    name="mountaincar",
    make=make,
    physical_state=physical_state,
    state_labels=("position", "velocity"),
    state_low=(-1.2, -0.07),
    state_high=(0.6, 0.07),
    actions="discrete",
    threshold=-110.0,
    threshold_source="gymnasium MountainCar-v0 reward_threshold",
    max_episode_steps=200,
    options={"goal_velocity": float},
    description="gymnasium MountainCar-v0 dynamics; 3 discrete actions; reward -1 per step",
    render=render_mountaincar,
    set_state=set_state,
    observe=observe,
    observation_labels=("position", "velocity"),
    demo_policy=pump_energy,
)
