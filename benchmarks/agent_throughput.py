"""Environment steps (frames) per second of every (agent, observation) pair while learning,
one torch thread each; then a small grid run with 1 and with 2 workers, side by side.

    .venv/bin/python benchmarks/agent_throughput.py          (≈ 6 min on 2 cores)

Each pair runs with its defaults for that env and observation (their sources: the
table of docs/builtin-plugins.md, and every result's ``hyperparams_source``). The
encoded observation uses an untrained sen-resnet (its speed does not depend on its
weights). The off-policy learners (DQN, DDQN, DrQ, SAC, DrQ's SAC) are timed from their
first update on, DQN's kind acting mostly greedily, so the rate is that of their steady
state, not of the warm-up: on pixels DQN and DDQN update every 4 frames (batch 32); on the
state and encoded state the zoo's MountainCar set updates 8 times (batch 128) every 16
frames; DrQ, SAC and DrQ's SAC update as their defaults say (docs/builtin-plugins.md).
PPO is timed over whole rollouts, each with its update (10 epochs over the rollout in
batches of 64).
"""

from __future__ import annotations

import tempfile
import textwrap
import time
from pathlib import Path

import numpy as np
from learners import Count

from senbench.encoders import EncoderRequest, StateEncoder, build_model, observation_bounds
from senbench.observe.observations import make_env
from senbench.observe.pixels import PixelSpec
from senbench.plugin.manager import registries
from senbench.plugin.specs import AgentContext
from senbench.run.processes import set_threads
from senbench.run.runner import run_suite
from senbench.suite import load_suite

PAIRS = [  # (agent, observation, env, frames to time): every pair the agents accept
    ("sarsa", "state", "mountaincar", 20_000),
    ("sarsa", "encoded", "mountaincar", 4_000),
    ("ppo", "state", "mountaincar", 8_192),
    ("ppo", "encoded", "mountaincar", 4_096),
    ("ppo", "pixels", "mountaincar", 4_096),
    ("ppo", "state", "pendulum", 16_384),
    ("ppo", "encoded", "pendulum", 4_096),
    ("ppo", "pixels", "pendulum", 4_096),
    ("dqn", "state", "mountaincar", 4_000),
    ("dqn", "encoded", "mountaincar", 2_000),
    ("dqn", "pixels", "mountaincar", 3_000),
    ("ddqn", "state", "mountaincar", 4_000),
    ("ddqn", "encoded", "mountaincar", 2_000),
    ("ddqn", "pixels", "mountaincar", 3_000),
    ("drq", "pixels", "mountaincar", 2_000),
    ("sac", "state", "pendulum", 1_000),
    ("sac", "encoded", "pendulum", 500),
    ("sac", "pixels", "pendulum", 300),
    ("drq-sac", "pixels", "pendulum", 300),
]


def untrained_encoder(env_name: str) -> StateEncoder:
    regs = registries()
    spec = regs.envs.get(env_name)
    low, high = observation_bounds(spec)
    request = EncoderRequest(env_name, PixelSpec(), "sen-resnet", "uniform", 10, 1.0)
    k = len(low)
    return StateEncoder(build_model(request, regs, k), np.zeros(k), np.ones(k), low, high,
                        traceable=regs.encoders.get(request.arch).traceable)


def frames_per_second(agent_name: str, observation: str, env_name: str, frames: int) -> float:
    regs = registries()
    spec, agent = regs.envs.get(env_name), regs.agents.get(agent_name)
    encoder = untrained_encoder(env_name) if observation == "encoded" else None
    defaults = agent.defaults_for(env_name, observation)
    config = agent.config(**(defaults.values if defaults else {}))
    if hasattr(config, "learning_starts"):  # the off-policy learners: DQN, DrQ, SAC
        config.learning_starts = 0  # time learning, not the warm-up
    if hasattr(config, "exploration_initial_eps"):
        config.exploration_initial_eps = config.exploration_final_eps  # mostly greedy

    def make():
        return make_env(spec, observation, spec.max_episode_steps, {}, PixelSpec(), encoder)

    if agent_name == "ppo":
        # PPO updates after each rollout; a budget that ends with a rollout stops before
        # that rollout's update, so time whole rollouts and one frame of the next.
        rollout = config.n_steps * config.n_envs
        frames = max(1, round(frames / rollout)) * rollout + config.n_envs
    learner = agent.make(AgentContext(config, spec, make, 0, 1))
    start = time.perf_counter()
    learner.learn(frames, Count(frames))
    return frames / (time.perf_counter() - start)


GRID = textwrap.dedent("""\
    name: throughput
    envs:
      pendulum: {}
    methods:
      ppo-state: {agent: ppo}
    seeds: 4
    budget: 49152
    eval: {every: 49152, episodes: 2}
""")


def grid_seconds(workers: int) -> float:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "grid.yaml"
        path.write_text(GRID)
        suite = load_suite(path, registries())
        start = time.perf_counter()
        summary = run_suite(suite, Path(tmp) / "results", workers=workers)
        assert summary.ok == len(suite.cells)
        return time.perf_counter() - start


def main() -> None:
    set_threads(1)
    print(f"{'agent':6s} {'observation':12s} {'env':12s} {'frames/s':>9s}")
    for agent, observation, env, frames in PAIRS:
        rate = frames_per_second(agent, observation, env, frames)
        print(f"{agent:6s} {observation:12s} {env:12s} {rate:9,.0f}")
    one, two = grid_seconds(1), grid_seconds(2)
    print(f"grid of 4 ppo-state cells x 49k frames: 1 worker {one:.1f} s, 2 workers {two:.1f} s"
          f" -> {one / two:.2f}x")


if __name__ == "__main__":
    main()
