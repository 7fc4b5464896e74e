"""PPO's frames/s with SB3's Adam unfused and fused (senbench's choice), side by side in one
process; the update is the same (Adam, eps 1e-5), only the kernel differs.

    .venv/bin/python benchmarks/fused_adam.py          (≈ 1 min on 2 cores)
"""

from __future__ import annotations

import torch
from agent_throughput import frames_per_second
from stable_baselines3 import PPO

CASES = [("pixels", 4_096), ("state", 16_384)]


def with_adam(fused: bool, observation: str, frames: int) -> float:
    init = PPO.__init__

    def patched(self, *args, **kwargs):
        kwargs["policy_kwargs"] = {**kwargs["policy_kwargs"],
                                   "optimizer_kwargs": {"eps": 1e-5, "fused": fused}}
        init(self, *args, **kwargs)

    PPO.__init__ = patched
    try:
        return frames_per_second("ppo", observation, "pendulum", frames)
    finally:
        PPO.__init__ = init


def main() -> None:
    torch.set_num_threads(1)
    print(f"{'ppo on pendulum':16s} {'unfused':>8s} {'fused':>8s} {'ratio':>6s}")
    for observation, frames in CASES:
        plain, fused = (with_adam(f, observation, frames) for f in (False, True))
        print(f"{observation:16s} {plain:8,.0f} {fused:8,.0f} {fused / plain:6.2f}x")


if __name__ == "__main__":
    main()
