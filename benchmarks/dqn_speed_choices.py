"""What the pixel DQN's speed choices buy: frames/s on MountainCar pixels with its defaults
and with each faster setting alone, one torch thread, side by side in one process.

    .venv/bin/python benchmarks/dqn_speed_choices.py          (≈ 1 min on 2 cores)

Each run is 3,000 frames of which the first 500 are warm-up (no updates), so the rates are
a little above the steady state that benchmarks/agent_throughput.py reports. What each
setting costs in learning is not measured here.
"""

from __future__ import annotations

import time

import torch
from agent_throughput import Count

from senbench.observe.observations import make_env
from senbench.observe.pixels import PixelSpec
from senbench.plugin.manager import registries
from senbench.plugin.specs import AgentContext

CHOICES = [  # (label, frames, hyperparameters over the defaults)
    ("defaults (64x64, update every 4 frames, head 512)", PixelSpec(), {}),
    ("48x48 frames", PixelSpec(height=48, width=48), {}),
    ("an update every 8 frames", PixelSpec(), {"train_freq": 8}),
    ("a 256-wide CNN head", PixelSpec(), {"features_dim": 256}),
]


def frames_per_second(pixels: PixelSpec, overrides: dict, frames: int = 3000) -> float:
    regs = registries()
    spec, agent = regs.envs.get("mountaincar"), regs.agents.get("dqn")
    defaults = agent.defaults_for("mountaincar", "pixels")
    config = agent.config(**{**defaults.values, "learning_starts": 500, **overrides})

    def make():
        return make_env(spec, "pixels", spec.max_episode_steps, {}, pixels)

    learner = agent.make(AgentContext(config, spec, make, 0, 1))
    start = time.perf_counter()
    learner.learn(frames, Count(frames))
    return frames / (time.perf_counter() - start)


def main() -> None:
    torch.set_num_threads(1)
    base = None
    for label, pixels, overrides in CHOICES:
        rate = frames_per_second(pixels, overrides)
        base = base or rate
        print(f"{label:50s} {rate:6,.0f} frames/s  {rate / base:4.2f}x")


if __name__ == "__main__":
    main()
