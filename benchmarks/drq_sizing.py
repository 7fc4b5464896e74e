"""What DrQ's published settings cost here against the defaults sized to this machine, run
side by side: frames/s of each while learning on 2x64x64 frames, one torch thread, timed from
the first update on, and the ratio to the default.

    .venv/bin/python benchmarks/drq_sizing.py          (≈ 4 min on an idle core)

drq: DrQ updates every frame (train_freq 1); the default updates every 4. drq-sac: DrQ's
paper uses K = M = 2 and batch 512 (its code: 128); the default is K = M = 1, batch 64.
"""

from __future__ import annotations

from learners import learning_rate

from senbench.run.processes import set_threads

SETTINGS = [  # (agent, env, frames to time, hyperparams beyond the defaults)
    ("drq", "mountaincar", 1_000, {}),
    ("drq", "mountaincar", 250, {"train_freq": 1}),
    ("drq-sac", "pendulum", 400, {}),
    ("drq-sac", "pendulum", 200, {"k": 2, "m": 2}),
    ("drq-sac", "pendulum", 100, {"batch_size": 128}),
]


def frames_per_second(agent_name: str, env_name: str, frames: int, hyperparams: dict) -> float:
    return learning_rate(agent_name, "pixels", env_name, frames,
                         {"learning_starts": 0, **hyperparams})


def main() -> None:
    set_threads(1)
    print(f"{'agent':8s} {'beyond the defaults':26s} {'frames/s':>9s} {'x default':>9s}")
    default = {}
    for agent, env, frames, hyperparams in SETTINGS:
        rate = frames_per_second(agent, env, frames, hyperparams)
        default.setdefault(agent, rate)
        print(f"{agent:8s} {str(hyperparams or '(defaults)'):26s} {rate:9.1f} "
              f"{rate / default[agent]:9.2f}", flush=True)


if __name__ == "__main__":
    main()
