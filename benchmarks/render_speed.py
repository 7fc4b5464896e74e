"""Frames/s of senbench's renderers against gymnasium's render() + grey + area resize, side
by side in one process, for MountainCar and Pendulum at 64x64 (one thread).

    .venv/bin/python benchmarks/render_speed.py          (≈ 1 min)

"render" turns a state into a 64x64 grey frame. gymnasium: set the state, render() the
600x400 / 500x500 RGB screen with pygame, grey, area resize. senbench "exact": draw the
frame from signed distances; "table": interpolate the pose table (what observations use).
"env step" is what an agent pays per frame: step + frame. envpool's batched C++ renderer
(8 envs, step + render + the same grey/resize) is a third column when it is installed
(`pip install envpool`).
"""

from __future__ import annotations

import os
import time

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")  # pygame: no display here
os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")

import gymnasium  # noqa: E402
import numpy as np  # noqa: E402

import senbench_classic  # noqa: E402, F401 - registers the gymnasium ids
from senbench.observe.pixels import area_resize, quantize, to_gray  # noqa: E402
from senbench.plugin.manager import registries  # noqa: E402
from senbench_classic import renderers  # noqa: E402

SIZE = (64, 64)
SECONDS = 1.5
ENVS = {
    "mountaincar": ("MountainCar-v0", "senbench/PixelMountainCar-v0", renderers.draw_mountaincar),
    "pendulum": ("Pendulum-v1", "senbench/PixelPendulum-v0", renderers.draw_pendulum),
}


def rate(frames_per_call: int, call) -> float:
    """Frames per second of ``call`` repeated for about SECONDS."""
    call()  # warm caches (pose tables, scenes)
    calls, start = 0, time.perf_counter()
    while (elapsed := time.perf_counter() - start) < SECONDS:
        call()
        calls += 1
    return calls * frames_per_call / elapsed


def gymnasium_render(spec, env, states):
    state = iter(states)

    def call():
        spec.set_state(env.unwrapped, next(state))
        quantize(area_resize(to_gray(env.render()), *SIZE))

    return call


def envpool_step(task: str, num_envs: int = 8):
    try:
        import envpool
    except ImportError:
        return None
    env = envpool.make_gymnasium(task, num_envs=num_envs, render_mode="rgb_array")
    env.reset()
    ids = np.arange(num_envs)
    discrete = isinstance(env.action_space, gymnasium.spaces.Discrete)

    def call():
        actions = np.zeros(num_envs, dtype=int) if discrete else np.zeros((num_envs, 1))
        env.step(actions, ids)
        for frame in env.render(env_ids=ids):
            quantize(area_resize(to_gray(frame), *SIZE))

    return lambda: rate(num_envs, call)


def measure(name: str, spec, gym_id: str, pixel_id: str, draw) -> list[tuple]:
    states = np.random.default_rng(0).uniform(spec.state_low, spec.state_high, (100_000, 2))
    poses = states[:, 0]
    env = gymnasium.make(gym_id, render_mode="rgb_array")
    env.reset(seed=0)
    theirs = rate(1, gymnasium_render(spec, env, states))
    ours = {
        "exact, 1 per call": rate(1, lambda: draw(poses[:1], *SIZE)),
        "exact, 256 per call": rate(256, lambda: draw(poses[:256], *SIZE)),
        "table, 1 per call": rate(1, lambda: spec.render(states[:1], SIZE)),
        "table, 256 per call": rate(256, lambda: spec.render(states[:256], SIZE)),
    }
    rows = [(name, "render", "gymnasium render+grey+resize", theirs, 1.0)]
    rows += [(name, "render", f"senbench {k}", v, v / theirs) for k, v in ours.items()]

    def gym_step():
        _, _, terminated, truncated, _ = env.step(env.action_space.sample())
        quantize(area_resize(to_gray(env.render()), *SIZE))
        if terminated or truncated:
            env.reset()

    pixel_env = gymnasium.make(pixel_id)
    pixel_env.reset(seed=0)

    def our_step():
        _, _, terminated, truncated, _ = pixel_env.step(pixel_env.action_space.sample())
        if terminated or truncated:
            pixel_env.reset()

    theirs_step, ours_step = rate(1, gym_step), rate(1, our_step)
    rows.append((name, "env step", "gymnasium step+render+grey+resize", theirs_step, 1.0))
    rows.append((name, "env step", f"senbench {pixel_id}", ours_step, ours_step / theirs_step))
    pool = envpool_step(gym_id)
    if pool is None:
        rows.append((name, "env step", "envpool (not installed)", float("nan"), float("nan")))
    else:
        pooled = pool()
        rows.append((name, "env step", "envpool x8 step+render+grey+resize", pooled,
                     pooled / theirs_step))
    return rows


def main() -> None:
    regs = registries()
    rows = []
    for name, (gym_id, pixel_id, draw) in ENVS.items():
        rows += measure(name, regs.envs.get(name), gym_id, pixel_id, draw)
    print(f"{'env':12s} {'what':9s} {'how':40s} {'frames/s':>12s} {'vs gymnasium':>13s}")
    for name, what, how, fps, ratio in rows:
        print(f"{name:12s} {what:9s} {how:40s} {fps:12,.0f} {ratio:12.1f}x")


if __name__ == "__main__":
    main()
