"""What each pixel agent keeps in memory: the resident size of one learner at its
MountainCar / Pendulum defaults before and after its buffer is full, in a fresh process
each (one cell's worth, as a worker holds it).

    .venv/bin/python benchmarks/agent_memory.py          (≈ 1 min on 2 cores)

A replay buffer is filled with ``buffer_size`` random transitions through SB3's own
``add`` (so numpy really touches every page), a PPO rollout buffer by one rollout.
"""

from __future__ import annotations

import multiprocessing
import sys

CASES = [  # (agent, observation, env, extra config)
    ("dqn", "pixels", "mountaincar", {}),
    ("dqn", "pixels", "mountaincar", {"optimize_memory_usage": True}),
    ("ddqn", "pixels", "mountaincar", {}),
    ("ppo", "pixels", "pendulum", {}),
    ("ppo", "state", "pendulum", {}),
    ("sarsa", "state", "mountaincar", {}),
]


def rss_mb() -> float:
    import psutil

    return psutil.Process().memory_info().rss / 2**20


def measure(agent_name: str, observation: str, env_name: str, extra: dict, out) -> None:
    import numpy as np
    import torch

    from senbench.observe.observations import make_env
    from senbench.observe.pixels import PixelSpec
    from senbench.plugin.manager import registries
    from senbench.plugin.specs import AgentContext

    torch.set_num_threads(1)
    regs = registries()
    spec, agent = regs.envs.get(env_name), regs.agents.get(agent_name)
    defaults = agent.defaults_for(env_name, observation)
    config = agent.config(**{**(defaults.values if defaults else {}), **extra})

    def make():
        return make_env(spec, observation, spec.max_episode_steps, {}, PixelSpec(), None)

    learner = agent.make(AgentContext(config, spec, make, 0, 1))
    before = rss_mb()
    model = getattr(learner, "model", None)
    if model is not None and hasattr(model, "replay_buffer"):
        buffer = model.replay_buffer
        rng = np.random.default_rng(0)
        obs = rng.integers(0, 256, (1, *buffer.obs_shape), dtype=np.uint8)
        for _ in range(buffer.buffer_size):
            buffer.add(obs, obs, np.zeros((1, 1)), np.zeros(1), np.zeros(1),
                       [{"TimeLimit.truncated": False}])
        held = f"replay buffer of {buffer.buffer_size:,} transitions"
    elif model is not None:
        budget = model.n_steps * model.n_envs

        class Count:
            def step(self, steps):
                return steps < budget

            def episode(self, *args):
                pass

        learner.learn(budget, Count())
        held = f"rollout buffer of {model.n_steps} x {model.n_envs} frames (float32)"
    else:
        learner.learn(20_000, type("C", (), {"step": lambda s, n: n < 20_000,
                                             "episode": lambda s, *a: None})())
        held = "tile-coding weights and traces"
    out.send((before, rss_mb(), held))


def main() -> None:
    ctx = multiprocessing.get_context("spawn")
    print(f"{'agent':6s} {'obs':7s} {'env':12s} {'extra':28s} {'built MB':>9s} "
          f"{'full MB':>8s}  what fills")
    for agent, observation, env, extra in CASES:
        parent, child = ctx.Pipe()
        proc = ctx.Process(target=measure, args=(agent, observation, env, extra, child))
        proc.start()
        before, after, held = parent.recv()
        proc.join()
        label = ", ".join(f"{k}={v}" for k, v in extra.items()) or "-"
        print(f"{agent:6s} {observation:7s} {env:12s} {label:28s} {before:9,.0f} "
              f"{after:8,.0f}  {held}")
        sys.stdout.flush()


if __name__ == "__main__":
    main()
