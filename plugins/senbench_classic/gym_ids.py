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

from senbench import FrameStack, PhysicalStateInfo, PixelSpec, rendered_frames
from senbench_classic.mountaincar import MOUNTAINCAR
from senbench_classic.pendulum import PENDULUM

GYMNASIUM_CLASSES = {"mountaincar": (MOUNTAINCAR, MountainCarEnv),
                     "pendulum": (PENDULUM, PendulumEnv)}


def make_pixel_env(env: str, height: int = 64, width: int = 64, stack: int = 2,
                   render_mode: str | None = None, **options) -> gymnasium.Env:
    """The gymnasium env class itself (gymnasium.make adds the TimeLimit), observed as
    frames; ``options`` go to the class (goal_velocity, g)."""
    spec, env_class = GYMNASIUM_CLASSES[env]
    pixels = PixelSpec(height, width, stack)
    base = env_class(render_mode=render_mode, **options)
    return FrameStack(PhysicalStateInfo(base, spec), rendered_frames(spec.render, pixels),
                      pixels)


def register_gymnasium_ids() -> None:
    for env_id, env in (("senbench/PixelMountainCar-v0", "mountaincar"),
                        ("senbench/PixelPendulum-v0", "pendulum")):
        if env_id not in gymnasium.registry:
            gymnasium.register(env_id, entry_point=make_pixel_env, max_episode_steps=200,
                               kwargs={"env": env})
