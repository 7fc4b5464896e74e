"""A plugin used by the tests: agents that fail, or die, on purpose."""

from __future__ import annotations

import os
import signal
from dataclasses import dataclass
from pathlib import Path

import senbench
from senbench import AgentSpec, Float


@dataclass
class CrashConfig:
    after: int = 10
    """Frames before the agent raises."""


class CrashAgent:
    def __init__(self, ctx):
        self.env = ctx.make_env()
        self.after = ctx.config.after
        self.seed = ctx.seed

    def act(self, observation):
        return 0

    def learn(self, budget, recorder):
        self.env.reset(seed=self.seed)
        for steps in range(budget + 1):
            if steps == self.after:
                raise ValueError(f"crash agent crashed on purpose at frame {steps}")
            if not recorder.step(steps):
                return
            self.env.step(0)


@dataclass
class CrashSeedConfig:
    seed: int = 1
    """The seed that raises; the others run to the budget."""
    after: int = 10


class CrashSeedAgent(CrashAgent):
    """Raises on one seed only: a seed batch's other seeds must finish (encoded frames, so
    it can run in a seed batch)."""

    def __init__(self, ctx):
        super().__init__(ctx)
        self.after = ctx.config.after if ctx.seed == ctx.config.seed else -1


class DieAgent(CrashAgent):
    """Kills its own process: what an out-of-memory kill looks like to the runner."""

    def learn(self, budget, recorder):
        os._exit(17)


class ExitAgent(CrashAgent):
    """Calls sys.exit, as some libraries do on errors."""

    def learn(self, budget, recorder):
        import sys

        recorder.step(0)
        sys.exit(3)


@dataclass
class DieTimesConfig:
    after: int = 10**9
    times: int = 1
    counter: str = ""
    """A file that gets a line per attempt. The first ``times`` attempts SIGKILL their own
    process (a worker lost mid-cell); later ones learn, and raise at frame ``after``."""


class DieTimesAgent(CrashAgent):
    def __init__(self, ctx):
        super().__init__(ctx)
        self.times, self.counter = ctx.config.times, Path(ctx.config.counter)

    def learn(self, budget, recorder):
        with open(self.counter, "a") as handle:
            handle.write(f"{os.getpid()}\n")
        if len(self.counter.read_text().splitlines()) <= self.times:
            os.kill(os.getpid(), signal.SIGKILL)
        super().learn(budget, recorder)


@dataclass
class SlowConfig:
    sleep_s: float = 0.01
    """Seconds per frame."""


class SlowAgent:
    """Acts at a known pace, so that a test can interrupt a run in the middle."""

    def __init__(self, ctx):
        self.env = ctx.make_env()
        self.sleep_s = ctx.config.sleep_s
        self.seed = ctx.seed

    def act(self, observation):
        return 1

    def learn(self, budget, recorder):
        import time

        self.env.reset(seed=self.seed)
        steps = 0
        while recorder.step(steps):
            time.sleep(self.sleep_s)
            _, _, terminated, truncated, _ = self.env.step(1)
            steps += 1
            if terminated or truncated:
                recorder.episode(steps, -1.0, 1)
                self.env.reset()


@dataclass
class NanConfig:
    what: str = "return"
    """return: a training episode's return is NaN; action: the policy acts NaN."""
    after: int = 300
    """Frames before it goes wrong."""


class NanAgent:
    """Goes NaN at frame ``after``, as a diverged learner would."""

    def __init__(self, ctx):
        import numpy as np

        space = ctx.make_env().action_space
        self.discrete = not hasattr(space, "shape") or not space.shape
        self.zero = 0 if self.discrete else np.zeros(space.shape, dtype=space.dtype)
        self.what, self.after = ctx.config.what, ctx.config.after
        self.broken = False

    def act(self, observation):
        return self.zero * float("nan") if self.broken and not self.discrete else self.zero

    def learn(self, budget, recorder):
        steps = 0
        while recorder.step(steps):
            steps += 1
            if steps == self.after and self.what == "return":
                recorder.episode(steps, float("nan"), steps)
            self.broken = self.broken or (steps >= self.after and self.what == "action")


@senbench.hookimpl
def register_agents(register):
    kinds = frozenset({"discrete"})
    register(AgentSpec("crash", CrashAgent, CrashConfig, kinds, frozenset({"state"})))
    register(AgentSpec("crash-seed", CrashSeedAgent, CrashSeedConfig, kinds,
                       frozenset({"encoded"}), seed_batching=True))
    register(AgentSpec("die", DieAgent, CrashConfig, kinds, frozenset({"state"})))
    register(AgentSpec("slow", SlowAgent, SlowConfig, kinds, frozenset({"state"}),
                       search_space={"sleep_s": Float(0.001, 0.1, log=True)}))
    register(AgentSpec("exit", ExitAgent, CrashConfig, kinds, frozenset({"state"})))
    register(AgentSpec("die-times", DieTimesAgent, DieTimesConfig, kinds,
                       frozenset({"state"})))
    register(AgentSpec("nan", NanAgent, NanConfig, frozenset({"discrete", "continuous"}),
                       frozenset({"state"})))
