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
)
