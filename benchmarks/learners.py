"""What the learner benchmarks share: a recorder that only counts, and frames/s of one
learner while it learns (imported by the scripts beside it, run from the repository root)."""

from __future__ import annotations

import time
from typing import Any

from senbench.observe.observations import make_env
from senbench.observe.pixels import PixelSpec
from senbench.plugin.manager import registries
from senbench.plugin.specs import AgentContext


class Count:
    """A recorder that stops the agent at ``budget`` frames and records nothing."""

    def __init__(self, budget: int):
        self.budget = budget

    def step(self, steps: int) -> bool:
        return steps < self.budget

    def episode(self, *args) -> None:
        pass


def timed_settings(agent_name: str, observation: str, env_name: str) -> dict[str, Any]:
    """The agent's defaults for the env and observation, learning from the first frame (no
    warm-up), PPO with a rollout and its update within a thousand frames."""
    agent = registries().agents.get(agent_name)
    defaults = agent.defaults_for(env_name, observation)
    values = dict(defaults.values) if defaults else {}
    if "learning_starts" in agent.config.__dataclass_fields__:
        values["learning_starts"] = 0  # time learning, not the warm-up
    if agent_name == "ppo":
        values.update(n_envs=4, n_steps=256)  # a rollout and its update within the frames
    return values


def learning_rate(agent_name: str, observation: str, env_name: str, frames: int,
                  hyperparams: dict[str, Any], precision: str = "fp32",
                  encoder: Any = None, memory_format: str = "contiguous") -> float:
    """Frames/s of the agent learning for ``frames`` frames with these hyperparameters
    (beyond its config's defaults) on 2x64x64 frames where it sees pixels."""
    regs = registries()
    spec, agent = regs.envs.get(env_name), regs.agents.get(agent_name)

    def make():
        return make_env(spec, observation, spec.max_episode_steps, {}, PixelSpec(), encoder)

    ctx = AgentContext(agent.config(**hyperparams), spec, make, 0, 1, precision, memory_format)
    learner = agent.make(ctx)
    start = time.perf_counter()
    learner.learn(frames, Count(frames))
    return frames / (time.perf_counter() - start)
