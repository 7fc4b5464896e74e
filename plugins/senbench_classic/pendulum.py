"""Pendulum: swing a pole up from a random angle and hold it upright with bounded torque.

Physical state (angle rad, 0 = upright, wrapped to [−π, π); angular velocity rad/s). The
observation on the true state is gymnasium's (cos θ, sin θ, θ̇); one continuous action,
torque in [−2, 2] N·m. gymnasium's ``Pendulum-v1`` dynamics.
"""

import gymnasium
import numpy as np

from senbench import EnvSpec
from senbench_classic.renderers import render_pendulum


def make(max_episode_steps: int = 200, render_mode: str | None = None,
         g: float = 10.0) -> gymnasium.Env:
    return gymnasium.make("Pendulum-v1", max_episode_steps=max_episode_steps,
                          render_mode=render_mode, g=g)


def physical_state(env: gymnasium.Env) -> np.ndarray:
    theta, theta_dot = env.state
    wrapped = (theta + np.pi) % (2 * np.pi) - np.pi
    return np.array([wrapped, theta_dot], dtype=np.float64)


def set_state(env: gymnasium.Env, state: np.ndarray) -> None:
    env.state = np.asarray(state, dtype=np.float64).copy()
    env.last_u = None  # gymnasium draws an arrow for the last torque; there is none


def observe(states: np.ndarray) -> np.ndarray:
    """gymnasium's observation (cos θ, sin θ, θ̇): no jump where θ wraps at ±π."""
    states = np.asarray(states, dtype=np.float64)
    return np.stack([np.cos(states[:, 0]), np.sin(states[:, 0]), states[:, 1]], 1).astype(
        np.float32)


def swing_up(observation: np.ndarray) -> np.ndarray:
    """Pump energy towards the upright energy, then balance with a PD law near the top."""
    cos, sin, velocity = (float(v) for v in observation)
    angle = np.arctan2(sin, cos)
    if cos > 0.9:
        torque = -10.0 * angle - 2.0 * velocity
    else:
        energy = 0.5 * velocity**2 / 3.0 + 10.0 * cos / 2.0  # per unit m·l²/3
        torque = 2.0 * np.sign(velocity * (5.0 - energy)) if velocity != 0 else 2.0
    return np.array([np.clip(torque, -2.0, 2.0)], dtype=np.float32)


PENDULUM = EnvSpec(
    name="pendulum",
    make=make,
    physical_state=physical_state,
    state_labels=("angle", "angular_velocity"),
    state_low=(-np.pi, -8.0),
    state_high=(np.pi, 8.0),
    actions="continuous",
    threshold=-200.0,
    threshold_source=(
        "senbench convention (gymnasium sets none): a swing-up held upright scores above "
        "-200 from most starts"
    ),
    max_episode_steps=200,
    options={"g": float},
    description="gymnasium Pendulum-v1 dynamics; torque in [-2, 2]; 200 steps per episode",
    render=render_pendulum,
    set_state=set_state,
    observe=observe,
    observation_labels=("cos_angle", "sin_angle", "angular_velocity"),
    demo_policy=swing_up,
)
