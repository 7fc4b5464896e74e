"""The pixel envs as gymnasium ids, for use outside senbench suites:

    import senbench_classic, gymnasium
    env = gymnasium.make("senbench/PixelMountainCar-v0", height=64, width=64, stack=2)

Observations are (stack, height, width) uint8 frames from senbench's renderers, oldest
first; ``info["state"]`` carries the physical state. ``render_mode="rgb_array"`` still
gives gymnasium's own colour frame from ``env.render()``.
"""

from __future__ import annotations

import gymnasium
from gymnasium.envs.classic_control import MountainCarEnv, PendulumEnv

from senbench.observations import PhysicalStateInfo
from senbench.pixels import FrameStack, PixelSpec, rendered_frames
from senbench_classic.mountaincar import MOUNTAINCAR
from senbench_classic.pendulum import PENDULUM


def make_pixel_mountaincar(height: int = 64, width: int = 64, stack: int = 2,
                           render_mode: str | None = None, goal_velocity: float = 0.0):
    pixels = PixelSpec(height, width, stack)
    env = MountainCarEnv(render_mode=render_mode, goal_velocity=goal_velocity)
    return FrameStack(PhysicalStateInfo(env, MOUNTAINCAR),
                      rendered_frames(MOUNTAINCAR.render, pixels), pixels)


def make_pixel_pendulum(height: int = 64, width: int = 64, stack: int = 2,
                        render_mode: str | None = None, g: float = 10.0):
    pixels = PixelSpec(height, width, stack)
    env = PendulumEnv(render_mode=render_mode, g=g)
    return FrameStack(PhysicalStateInfo(env, PENDULUM),
                      rendered_frames(PENDULUM.render, pixels), pixels)


def register_gymnasium_ids() -> None:
    for env_id, entry_point in (("senbench/PixelMountainCar-v0", make_pixel_mountaincar),
                                ("senbench/PixelPendulum-v0", make_pixel_pendulum)):
        if env_id not in gymnasium.registry:
            gymnasium.register(env_id, entry_point=entry_point, max_episode_steps=200)
