"""The one evaluation protocol, and the recorder every agent reports through.

Every ``eval.every`` frames (and at frame 0 and at the budget) the agent's greedy /
deterministic policy plays ``eval.episodes`` episodes on its own env, never the training
env. Episode k of every evaluation of a cell starts from seed ``EVAL_SEED + 1000·seed + k``,
so successive points of a curve are measured from the same start states. With
``eval.epsilon`` = ε > 0, each step takes a uniformly random action with probability ε
(the DQN literature's ε-greedy evaluation), drawn from a generator seeded per episode, so
the evaluation stays reproducible and the same for every method of a suite.

Each evaluation records what the policy did, so that a curve that stays flat can be told
apart from a policy stuck on one action: for discrete actions the share of each action over
all steps of its episodes, for continuous actions the mean and standard deviation of each
action dimension.

No NaN passes silently: an evaluation observation, continuous action or reward, an
evaluation return or a training episode's return that is NaN or infinite fails the cell
with a NonFiniteError naming what and where (one ``isfinite`` per evaluation step and per
episode return; nothing is added to an agent's training steps).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any

import gymnasium
import numpy as np

from senbench.errors import NonFiniteError, PluginError

EVAL_SEED = 1_000_003
PROGRESS_INTERVAL_S = 0.5


class Evaluator:
    def __init__(self, env: gymnasium.Env, episodes: int, seed: int, epsilon: float = 0.0):
        if not 0.0 <= epsilon <= 1.0:
            raise ValueError(f"eval epsilon must be in [0, 1], got {epsilon}")
        self.env = env
        self.seeds = [EVAL_SEED + 1000 * seed + k for k in range(episodes)]
        self.epsilon = epsilon
        self.discrete = isinstance(env.action_space, gymnasium.spaces.Discrete)

    def __call__(self, act: Callable[[np.ndarray], Any]) -> dict[str, Any]:
        """Mean return, its std over episodes, mean episode length in frames, and the
        actions' stats, one per decision (the columns of an evaluation row)."""
        returns, lengths, actions = [], [], []
        space = self.env.action_space
        for episode, seed in enumerate(self.seeds, 1):
            obs, _ = self.env.reset(seed=seed)
            explore = np.random.default_rng(seed)
            if self.epsilon:
                space.seed(seed)
            total, length, done = 0.0, 0, False
            while not done:
                _check(obs, "the observation", length, episode, OBSERVATION_CAUSE)
                if self.epsilon and explore.random() < self.epsilon:
                    action = space.sample()
                else:
                    action = act(obs)
                if not self.discrete:
                    _check(action, "the agent's action", length, episode, ACTION_CAUSE)
                actions.append(action)
                obs, reward, terminated, truncated, info = self.env.step(action)
                total += float(reward)
                if not math.isfinite(total):
                    _check(reward, "the reward", length, episode, REWARD_CAUSE)
                length += info.get("frames", 1)  # an action held k frames takes k
                done = terminated or truncated
            returns.append(total)
            lengths.append(length)
        return {"return": float(np.mean(returns)), "return_std": float(np.std(returns)),
                "length": float(np.mean(lengths)), **self._action_stats(actions)}

    def _action_stats(self, actions: list[Any]) -> dict[str, list[float] | None]:
        if self.discrete:
            counts = np.bincount(np.asarray(actions, dtype=np.int64).ravel(),
                                 minlength=int(self.env.action_space.n))
            return {"action_share": (counts / max(counts.sum(), 1)).tolist(),
                    "action_mean": None, "action_std": None}
        taken = np.asarray(actions, dtype=np.float64).reshape(len(actions), -1)
        return {"action_share": None, "action_mean": taken.mean(axis=0).tolist(),
                "action_std": taken.std(axis=0).tolist()}


OBSERVATION_CAUSE = ("the agent's observations contain NaN or infinity — is the env's "
                     "observation space unbounded, or an option of the env out of range?")
ACTION_CAUSE = ("the agent's policy outputs NaN or infinity — did its training diverge "
                "(a learning rate too high, or unbounded observations or rewards)?")
REWARD_CAUSE = ("the env's reward is NaN or infinite — is the env's observation space "
                "unbounded, or an option of the env out of range?")


def _check(value: Any, what: str, step: int, episode: int, cause: str) -> None:
    """Raise if ``value`` (a number or an array) holds a NaN or an infinity."""
    array = np.asarray(value)
    if array.dtype.kind not in "fc" or np.isfinite(array).all():
        return
    bad = "nan" if np.isnan(array).any() else "infinite"
    raise NonFiniteError(f"{what} is {bad} at step {step} of evaluation episode {episode}: "
                         f"{cause}")


class DecisionRecorder:
    """The recorder an agent reports through when each of its actions is held for
    ``repeat`` frames (an env's ``action_repeat``): it counts decisions, the cell counts
    frames. A training episode's length is its decisions times ``repeat``, so an episode
    that ended inside its last decision counts that decision whole (as the ALE's frame
    counts do); evaluation lengths are exact."""

    def __init__(self, frames: CellRecorder, repeat: int):
        self.frames = frames
        self.repeat = repeat

    def step(self, steps: int) -> bool:
        return self.frames.step(steps * self.repeat)

    def episode(self, steps: int, episode_return: float, length: int) -> None:
        self.frames.episode(steps * self.repeat, episode_return, length * self.repeat)


class CellRecorder:
    """Implements ``senbench.Recorder`` for one cell: collects rows, runs evaluations when
    due, reports progress, and tells the agent when the budget is spent (or, with
    ``stop_at``, when that many frames of it are)."""

    def __init__(
        self,
        budget: int,
        every: int,
        evaluate: Callable[[], dict[str, Any]],
        on_progress: Callable[[int, float, float | None, int | None, float | None], None]
        | None = None,
        stop_at: int | None = None,
    ):
        self.budget = budget
        self.stop_at = budget if stop_at is None else min(stop_at, budget)
        self.every = every
        self.evaluate = evaluate
        self.on_progress = on_progress
        self.rows: list[dict[str, Any]] = []
        self.steps = 0
        self.last_eval: float | None = None
        self._last_eval_step: int | None = None
        self._train_sum, self._train_count = 0.0, 0  # the training episodes' returns so far
        self._next_eval = 0
        self._reported: int | None = None
        self._stopped_at: int | None = None
        self._start = time.perf_counter()
        self._last_report = 0.0

    def elapsed(self) -> float:
        return time.perf_counter() - self._start

    def step(self, steps: int) -> bool:
        self._check_report(steps)
        self.steps = steps
        due = steps >= self._next_eval or steps >= self.budget
        evaluated = due and self._last_eval_step != steps
        if evaluated:
            try:
                result = self.evaluate()
            except NonFiniteError as exc:
                raise NonFiniteError(f"evaluation at frame {steps:,}: {exc}") from None
            if not math.isfinite(result["return"]):
                raise NonFiniteError(f"evaluation return is {result['return']} at frame "
                                     f"{steps:,}: {REWARD_CAUSE}")
            self.rows.append({"kind": "eval", "step": steps, **result,
                              "wall_s": self.elapsed()})
            self.last_eval = result["return"]
            self._last_eval_step = steps
            self._next_eval = (steps // self.every + 1) * self.every
        now = self.elapsed()
        # every evaluation is reported as it happens (a tuner prunes on them); steps between
        # at most every PROGRESS_INTERVAL_S
        if self.on_progress is not None and (evaluated
                                             or now - self._last_report >= PROGRESS_INTERVAL_S):
            self._last_report = now
            train_return = (self._train_sum / self._train_count if self._train_count
                            else None)
            self.on_progress(steps, steps / max(now, 1e-9), self.last_eval,
                             self._last_eval_step, train_return)
        if steps >= self.stop_at:
            self._stopped_at = steps
        return steps < self.stop_at

    def _check_report(self, steps: int) -> None:
        """The agent keeps the Recorder protocol: frames counted from 0, never back, and
        none past the frame at which ``step`` returned False. Else its curve would hold
        evaluations at frames the cell never asked for, so the cell fails."""
        rule = ("Recorder.step(steps) takes the running total of frames, from step(0) "
                "before the first env step, and the agent stops once it returns False")
        if self._reported is None and steps != 0:
            raise PluginError(f"the agent's first report was frame {steps:,}, not 0: it "
                              f"evaluates the untrained policy there. {rule}")
        if self._reported is not None and steps < self._reported:
            raise PluginError(f"the agent reported frame {steps:,} after frame "
                              f"{self._reported:,}. {rule}")
        if self._stopped_at is not None and steps > self._stopped_at:
            raise PluginError(f"the agent reported frame {steps:,} after step() returned "
                              f"False at frame {self._stopped_at:,}. {rule}")
        self._reported = steps

    def episode(self, steps: int, episode_return: float, length: int) -> None:
        episode_return = float(episode_return)
        if not math.isfinite(episode_return):
            raise NonFiniteError(
                f"episode return is {episode_return} at frame {steps:,}: the env's rewards, "
                "or the agent's sum of them, are NaN or infinite — are the env's observations "
                "or rewards unbounded, or did the agent's learning diverge?")
        self._train_sum += episode_return
        self._train_count += 1
        self.rows.append({"kind": "episode", "step": steps, "return": episode_return,
                          "return_std": None, "length": float(length), "wall_s": self.elapsed()})
