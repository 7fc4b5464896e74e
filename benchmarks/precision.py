"""bf16 against fp32 network updates, side by side: frames/s of each learner while learning
(one torch thread, timed from its first update on) with ``precision: fp32`` and ``bf16``,
and the ratio. bf16 is torch.autocast on the CPU around the agent's updates
(senbench_agents.sb3.with_precision); it pays where the updates are large matrix products
and convolutions on a CPU with bf16 instructions, and costs where they are small.

    .venv/bin/python benchmarks/precision.py          (≈ 5 min on an idle core)
"""

from __future__ import annotations

from learners import learning_rate, timed_settings

from senbench.run.processes import set_threads

LEARNERS = [  # (agent, observation, env, frames timed)
    ("dqn", "pixels", "mountaincar", 1_000),
    ("drq", "pixels", "mountaincar", 1_000),
    ("ppo", "pixels", "pendulum", 1_028),
    ("sac", "state", "pendulum", 500),
    ("sac", "pixels", "pendulum", 200),
    ("drq-sac", "pixels", "pendulum", 200),
]


def frames_per_second(agent_name: str, observation: str, env_name: str, frames: int,
                      precision: str) -> float:
    values = timed_settings(agent_name, observation, env_name)
    return learning_rate(agent_name, observation, env_name, frames, values, precision)


def main() -> None:
    set_threads(1)
    print(f"{'agent':8s} {'observation':11s} {'fp32 f/s':>9s} {'bf16 f/s':>9s} {'bf16/fp32':>9s}")
    for agent, observation, env, frames in LEARNERS:
        fp32 = frames_per_second(agent, observation, env, frames, "fp32")
        bf16 = frames_per_second(agent, observation, env, frames, "bf16")
        print(f"{agent:8s} {observation:11s} {fp32:9.1f} {bf16:9.1f} {bf16 / fp32:9.2f}",
              flush=True)


if __name__ == "__main__":
    main()
