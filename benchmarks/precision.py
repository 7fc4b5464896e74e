"""bf16 against fp32 network updates, side by side: frames/s of each learner while learning
(one torch thread, timed from its first update on) with ``precision: fp32`` and ``bf16``,
and the ratio. bf16 is torch.autocast on the CPU around the agent's updates
(senbench_agents.sb3.with_precision); it pays where the updates are large matrix products
and convolutions on a CPU with bf16 instructions, and costs where they are small.

One timing of 200-1,000 frames moves by up to 30% between runs on 2 cores, so each learner
is timed ``--repeats`` times, fp32 and bf16 taking turns (a slow spell of the machine falls
on both), and the median of each is printed, with the lowest and highest ratio of a turn.

    .venv/bin/python benchmarks/precision.py                 (2 min 21 s idle, 2026-12-08's EPYC)
    .venv/bin/python benchmarks/precision.py --repeats 1     (one timing each instead of three)
    .venv/bin/python benchmarks/precision.py --learner drq-sac/pixels
"""

from __future__ import annotations

import argparse
import statistics

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
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=3,
                        help="timings of each learner at each precision (default 3)")
    parser.add_argument("--learner", action="append", default=[], metavar="AGENT/OBSERVATION",
                        help="time only these (repeatable), e.g. sac/pixels")
    args = parser.parse_args()
    known = {f"{row[0]}/{row[1]}": row for row in LEARNERS}  # agent/observation: its row
    unknown = [name for name in args.learner if name not in known]
    if args.repeats < 1:
        parser.error(f"--repeats must be at least 1 (got {args.repeats})")
    if unknown:
        parser.error(f"--learner {unknown[0]}: not timed here; use one of {', '.join(known)}")
    chosen = [row for name, row in known.items() if not args.learner or name in args.learner]
    set_threads(1)
    print(f"{'agent':8s} {'observation':11s} {'fp32 f/s':>9s} {'bf16 f/s':>9s} "
          f"{'bf16/fp32':>9s} {'turns':>10s}")
    for agent, observation, env, frames in chosen:
        turns = [(frames_per_second(agent, observation, env, frames, "fp32"),
                  frames_per_second(agent, observation, env, frames, "bf16"))
                 for _ in range(args.repeats)]
        fp32 = statistics.median(t[0] for t in turns)
        bf16 = statistics.median(t[1] for t in turns)
        ratios = [b / f for f, b in turns]
        print(f"{agent:8s} {observation:11s} {fp32:9.1f} {bf16:9.1f} {bf16 / fp32:9.2f} "
              f"{min(ratios):5.2f}-{max(ratios):4.2f}", flush=True)


if __name__ == "__main__":
    main()
