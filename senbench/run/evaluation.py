"""The one evaluation protocol, and the recorder every agent reports through.

Every ``eval.every`` frames (and at frame 0 and at the budget) the agent's greedy /
deterministic policy plays ``eval.episodes`` episodes on its own env, never the training
env. Episode k of every evaluation of a cell starts from seed ``EVAL_SEED + 1000·seed + k``,
so successive points of a curve are measured from the same start states.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import gymnasium
import numpy as np

EVAL_SEED = 1_000_003
PROGRESS_INTERVAL_S = 0.5


class Evaluator:
    def __init__(self, env: gymnasium.Env, episodes: int, seed: int):
        self.env = env
        self.seeds = [EVAL_SEED + 1000 * seed + k for k in range(episodes)]

    def __call__(self, act: Callable[[np.ndarray], Any]) -> tuple[float, float, float]:
        """Mean return, its std over episodes, and mean episode length."""
        returns, lengths = [], []
        for seed in self.seeds:
            obs, _ = self.env.reset(seed=seed)
            total, length, done = 0.0, 0, False
            while not done:
                obs, reward, terminated, truncated, _ = self.env.step(act(obs))
                total += float(reward)
                length += 1
                done = terminated or truncated
            returns.append(total)
            lengths.append(length)
        return float(np.mean(returns)), float(np.std(returns)), float(np.mean(lengths))


class CellRecorder:
    """Implements ``senbench.Recorder`` for one cell: collects rows, runs evaluations when
    due, reports progress, and tells the agent when the budget is spent."""

    def __init__(
        self,
        budget: int,
        every: int,
        evaluate: Callable[[], tuple[float, float, float]],
        on_progress: Callable[[int, float, float | None, int | None], None] | None = None,
    ):
        self.budget = budget
        self.every = every
        self.evaluate = evaluate
        self.on_progress = on_progress
        self.rows: list[dict[str, Any]] = []
        self.steps = 0
        self.last_eval: float | None = None
        self._last_eval_step: int | None = None
        self._next_eval = 0
        self._start = time.perf_counter()
        self._last_report = 0.0

    def elapsed(self) -> float:
        return time.perf_counter() - self._start

    def step(self, steps: int) -> bool:
        self.steps = steps
        due = steps >= self._next_eval or steps >= self.budget
        evaluated = due and self._last_eval_step != steps
        if evaluated:
            mean, std, length = self.evaluate()
            self.rows.append({"kind": "eval", "step": steps, "return": mean, "return_std": std,
                              "length": length, "wall_s": self.elapsed()})
            self.last_eval = mean
            self._last_eval_step = steps
            self._next_eval = (steps // self.every + 1) * self.every
        now = self.elapsed()
        # every evaluation is reported as it happens (a tuner prunes on them); steps between
        # at most every PROGRESS_INTERVAL_S
        if self.on_progress is not None and (evaluated
                                             or now - self._last_report >= PROGRESS_INTERVAL_S):
            self._last_report = now
            self.on_progress(steps, steps / max(now, 1e-9), self.last_eval,
                             self._last_eval_step)
        return steps < self.budget

    def episode(self, steps: int, episode_return: float, length: int) -> None:
        self.rows.append({"kind": "episode", "step": steps, "return": float(episode_return),
                          "return_std": None, "length": float(length), "wall_s": self.elapsed()})
