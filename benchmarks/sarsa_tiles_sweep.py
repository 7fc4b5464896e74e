"""Tile-coding sweep behind sarsa's MountainCar defaults.

For each (tilings, tiles per dimension, alpha, λ): 6 seeds of 20k frames on the true state;
prints the median and worst frames until the rolling-10 training return first reaches −150,
and the mean return of the last 20 episodes.

    .venv/bin/python benchmarks/sarsa_tiles_sweep.py      (≈ 1 min on 2 cores)
"""

import itertools

import numpy as np

from senbench.plugin.manager import registries
from senbench.plugin.specs import AgentContext

BUDGET = 20_000


class EpisodeLog:
    def __init__(self):
        self.episodes = []

    def step(self, steps):
        return steps < BUDGET

    def episode(self, steps, episode_return, length):
        self.episodes.append((steps, episode_return))


def frames_to_minus_150(episodes):
    steps = np.array([s for s, _ in episodes])
    returns = np.array([r for _, r in episodes])
    rolling = np.convolve(returns, np.ones(10) / 10, "valid")
    hit = np.flatnonzero(rolling >= -150)
    return (steps[hit[0] + 9] if len(hit) else np.inf), returns[-20:].mean()


def main():
    regs = registries()
    env, agent = regs.envs.get("mountaincar"), regs.agents.get("sarsa")
    grid = itertools.product([8, 16], [6, 7, 8], [0.5, 1.0, 1.5], [0.9, 0.95])
    for tilings, tiles, alpha, lam in grid:
        hits, finals = [], []
        for seed in range(6):
            cfg = agent.config(tilings=tilings, tiles=tiles, alpha=alpha, trace_decay=lam)
            learner = agent.make(AgentContext(cfg, env, env.make, seed, 1))
            log = EpisodeLog()
            learner.learn(BUDGET, log)
            hit, final = frames_to_minus_150(log.episodes)
            hits.append(hit)
            finals.append(final)
        print(
            f"tilings {tilings:2d} tiles {tiles} alpha {alpha:.1f} lambda {lam:.2f}: "
            f"frames to -150 median {np.median(hits):7.0f} worst {max(hits):7.0f}; "
            f"final {np.mean(finals):6.1f}"
        )


if __name__ == "__main__":
    main()
