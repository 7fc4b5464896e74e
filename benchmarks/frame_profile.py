"""Where a frame's time goes: for each (agent, observation) pair, a real cell (the runner's
own ``execute_cell``, evaluation and recording included) with its time split between env
dynamics, rendering, the state encoder, the agent's updates, its action selection,
evaluation and recording; and, beside the measured frames/s, the rate the cell's network
arithmetic alone would allow at the FLOP/s a batched conv net reaches on this machine.

    .venv/bin/python benchmarks/frame_profile.py          (≈ 6 min on an idle core)

Each share is exclusive: a part's time excludes the parts it calls (rendering is not in
"env"; the encoder is not in "rendering"); evaluation includes everything it does (its own
env steps, renders and actions). "other" is the rest: the agents' glue (SB3's rollout
collection and replay buffer; SARSA's update, which is inline in its loop) and the wrappers.
The cells run on one torch thread with their agents' defaults for the env and observation,
from their first update on (off-policy learners start learning at once), and evaluate at
the start and at the end, one episode each: the evaluation share of a suite's cell is set by
its eval.every and eval.episodes, not by this profile. Encoded cells use the
committed sen-resnet encoders (results/encoders; the paper's d = 20% spec).

The FLOP bound counts every multiply-add of the cell's torch operations
(``torch.utils.flop_counter``) over a second, shorter run of the same cell (long enough to
hold the learner's updates: a whole rollout for PPO), and divides the peak FLOP/s measured
here (NatureCNN forward, batch 256, one thread) by the FLOPs per frame.
"""

from __future__ import annotations

import tempfile
import time
from collections import defaultdict
from contextlib import ExitStack
from pathlib import Path
from unittest import mock

PAIRS = [  # (agent, observation, env, frames timed, frames whose FLOPs are counted)
    ("sarsa", "state", "mountaincar", 20_000, 5_000),
    ("sarsa", "encoded", "mountaincar", 4_000, 1_000),
    # PPO (the zoo's Pendulum set: 4 envs x 1,024 frames a rollout): whole rollouts, each
    # with its update, and the first frames of the next. Its FLOPs are counted over one
    # whole rollout and its update: a run shorter than a rollout never updates, and its
    # bound would count the rollout's forward passes only.
    ("ppo", "state", "pendulum", 8_196, 4_100),
    ("ppo", "encoded", "pendulum", 4_100, 4_100),
    ("ppo", "pixels", "pendulum", 4_100, 4_100),
    ("dqn", "state", "mountaincar", 4_000, 1_000),
    ("dqn", "pixels", "mountaincar", 2_000, 500),
    ("ddqn", "pixels", "mountaincar", 2_000, 500),
    ("drq", "pixels", "mountaincar", 1_000, 250),
    ("sac", "state", "pendulum", 1_000, 250),
    ("sac", "pixels", "pendulum", 300, 200),
    ("drq-sac", "pixels", "pendulum", 300, 200),
]
PARTS = ("env", "rendering", "encoder", "update", "action", "evaluation", "recording", "other")
ENCODER = "encoder: {arch: sen-resnet, sampler: uniform, samples: 50000, fraction: 0.2}"


class Clock:
    """Exclusive time per part: the innermost timed call owns the time; evaluation, once
    entered, owns everything under it."""

    def __init__(self):
        self.spent: dict[str, float] = defaultdict(float)
        self.stack: list[tuple[str, float]] = []

    def wrap(self, part: str, function):
        clock = self

        def timed(*args, **kwargs):
            if clock.stack and clock.stack[-1][0] == "evaluation":
                return function(*args, **kwargs)
            now = time.perf_counter()
            if clock.stack:  # pause the caller
                outer, since = clock.stack[-1]
                clock.spent[outer] += now - since
            clock.stack.append((part, now))
            try:
                return function(*args, **kwargs)
            finally:
                end = time.perf_counter()
                _, since = clock.stack.pop()
                clock.spent[part] += end - since
                if clock.stack:  # resume the caller
                    clock.stack[-1] = (clock.stack[-1][0], end)

        return timed


def patches(clock: Clock) -> list:
    """Every place a part lives, wrapped in the clock."""
    import gymnasium.envs.classic_control as classic
    from stable_baselines3 import DQN, PPO, SAC
    from stable_baselines3.common.policies import ActorCriticPolicy, BasePolicy

    from senbench.observe import observations, pixels
    from senbench.run import evaluation
    from senbench_agents import sarsa

    def on(owner, name, part):
        return mock.patch.object(owner, name, clock.wrap(part, getattr(owner, name)))

    original_init = pixels.FrameStack.__init__

    def frame_stack_init(self, env, draw, spec):
        original_init(self, env, clock.wrap("rendering", draw), spec)

    return [
        on(classic.MountainCarEnv, "step", "env"), on(classic.MountainCarEnv, "reset", "env"),
        on(classic.PendulumEnv, "step", "env"), on(classic.PendulumEnv, "reset", "env"),
        mock.patch.object(pixels.FrameStack, "__init__", frame_stack_init),
        on(observations.EncodedObservation, "observation", "encoder"),
        on(DQN, "train", "update"), on(PPO, "train", "update"), on(SAC, "train", "update"),
        on(BasePolicy, "predict", "action"), on(ActorCriticPolicy, "forward", "action"),
        on(sarsa.SarsaAgent, "q", "action"), on(sarsa.SarsaAgent, "_behave", "action"),
        on(sarsa.TileCoder, "__call__", "action"),
        on(evaluation.Evaluator, "__call__", "evaluation"),
        on(evaluation.CellRecorder, "step", "recording"),
        on(evaluation.CellRecorder, "episode", "recording"),
    ]


def cell_for(agent: str, observation: str, env: str, frames: int, folder: Path):
    from senbench.plugin.manager import registries
    from senbench.suite import load_suite

    regs = registries()
    fields = regs.agents.get(agent).config.__dataclass_fields__
    # off-policy learners: time learning, not the warm-up
    hyperparams = "{learning_starts: 0}" if "learning_starts" in fields else "{}"
    lines = ["name: profile", "envs:", f"  {env}: {{}}", "methods:", "  m:",
             f"    agent: {agent}", f"    observation: {observation}",
             f"    hyperparams: {hyperparams}"]
    if observation == "encoded":
        lines.append(f"    {ENCODER}")
    lines += ["seeds: 1", f"budget: {frames}", f"eval: {{every: {frames}, episodes: 1}}"]
    path = folder / f"{agent}-{observation}.yaml"
    path.write_text("\n".join(lines) + "\n")
    [cell] = load_suite(path, regs).cells
    return cell


def peak_flops() -> float:
    """FLOP/s of a batched NatureCNN forward on 2x64x64 frames, one thread."""
    import torch
    from stable_baselines3.common.torch_layers import NatureCNN
    from torch.utils.flop_counter import FlopCounterMode

    space = __import__("gymnasium").spaces.Box(0, 255, (2, 64, 64), "uint8")
    net = NatureCNN(space, features_dim=512)
    batch = torch.rand(256, 2, 64, 64)
    with torch.no_grad(), FlopCounterMode(display=False) as counter:
        net(batch)
    flops = counter.get_total_flops()
    with torch.no_grad():
        net(batch)
        start = time.perf_counter()
        for _ in range(5):
            net(batch)
    return 5 * flops / (time.perf_counter() - start)


def main() -> None:
    from torch.utils.flop_counter import FlopCounterMode

    from senbench.encoders import StateEncoder
    from senbench.run.execute import RunInfo, execute_cell
    from senbench.run.processes import set_threads

    original = StateEncoder.__init__

    def eager(self, *args, **kwargs):  # a frozen TorchScript encoder hides its FLOPs
        original(self, *args, **{**kwargs, "traceable": False})

    set_threads(1)
    peak = peak_flops()
    print(f"peak: {peak / 1e9:.0f} GFLOP/s (NatureCNN forward, batch 256, 1 thread)\n")
    print(f"{'agent':8s} {'observation':11s} {'frames/s':>9s} {'bound':>9s} "
          + " ".join(f"{p:>10s}" for p in PARTS))
    info = RunInfo.gather(Path("results") / "encoders")
    with tempfile.TemporaryDirectory() as tmp:
        for agent, observation, env, frames, counted in PAIRS:
            cell = cell_for(agent, observation, env, frames, Path(tmp))
            clock = Clock()
            with ExitStack() as stack:
                for patch in patches(clock):
                    stack.enter_context(patch)
                start = time.perf_counter()
                rows, outcome = execute_cell(cell, info)
                wall = time.perf_counter() - start
            if outcome.status != "ok":
                raise SystemExit(f"{agent} {observation}: {outcome.error}")
            shares = dict(clock.spent)
            shares["other"] = wall - sum(shares.values())
            short = cell_for(agent, observation, env, counted, Path(tmp))
            with mock.patch.object(StateEncoder, "__init__", eager), \
                    FlopCounterMode(display=False) as counter:
                execute_cell(short, info)
            per_frame = counter.get_total_flops() / short.budget
            bound = f"{peak / per_frame:9,.0f}" if per_frame else f"{'-':>9s}"
            print(f"{agent:8s} {observation:11s} {frames / wall:9,.0f} {bound} "
                  + " ".join(f"{100 * shares.get(p, 0.0) / wall:9.0f}%" for p in PARTS),
                  flush=True)


if __name__ == "__main__":
    main()
