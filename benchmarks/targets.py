"""The speed targets side by side, in one command, one torch thread per cell:

1. SEN-SARSA: frames/s of a 3-seed run (alone, then as one seed batch) ÷ its encoder's
   rate at batch 1 (target ≥ 1.3);
2. pixel DQN: frames/s while learning ÷ its fp32 update bound, the rate its updates alone
   would allow (one update of batch 32 every 4 frames; target ≥ 0.95);
3. the four paper suites' projected wall time on 2 cores (target ≤ 6 h): the committed
   cells' own wall times (two cells at a time) with the cells this benchmark speeds up
   scaled by the speed-up measured in 1 (SEN-SARSA in seed batches of 5, the paper's
   seeds); the other cells as they ran;
4. a grid of 4 PPO cells on 2 workers against 1 (target ≥ 1.8×);
5. 1 and 2 again with ``memory_format: channels_last`` (NHWC convolutions), each ÷ the
   rate of its own layout (the encoder's batch-1 rate NHWC, the update bound NHWC), and
   the grid projected with the SEN-SARSA and pixel DQN/DDQN cells that much faster.

    .venv/bin/python benchmarks/targets.py            (≈ 10 min on 2 idle cores)

Rates vary with the machine's load from day to day: the ratios, measured side by side,
are what it reports. Measured figures: docs/benchmarks.md.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from agent_throughput import grid_seconds
from learners import Count
from seed_batch import batch1_rate, cells, run_rate

from senbench.encoders import load_or_train
from senbench.observe.observations import make_env
from senbench.observe.pixels import PixelSpec
from senbench.plugin.manager import registries
from senbench.plugin.specs import AgentContext
from senbench.results.store import read_results
from senbench.run.execute import RunInfo
from senbench.run.processes import set_threads

ROOT = Path(__file__).resolve().parent.parent
PAPER = ["paper-mountaincar", "paper-mountaincar-d", "paper-pendulum", "paper-pendulum-d"]


def sen_sarsa(frames: int = 6_000, layout: str = "contiguous", batched: bool = True
              ) -> tuple[float, dict[int, float], dict[int, float]]:
    """The encoder's batch-1 rate in ``layout``; per seed count, the run's rate alone and
    (``batched``) in one seed batch."""
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        info = RunInfo.gather(folder / "encoders")
        first = cells(folder, 1, 1, frames, layout)[0]
        base = batch1_rate(load_or_train(info.encoder_cache, first.encoder_request(),
                                         registries()).laid_out(layout))
        alone, together = {}, {}
        for seeds in (3, 5):
            alone[seeds] = run_rate(cells(folder, seeds, 1, frames, layout), info)
            if batched:
                together[seeds] = run_rate(cells(folder, seeds, seeds, frames, layout), info)
    return base, alone, together


def pixel_dqn(frames: int = 3_000, updates: int = 200,
              layout: str = "contiguous") -> tuple[float, float]:
    """Pixel DQN's frames/s while learning (its MountainCar pixel defaults, from its first
    update on), and the frames/s its updates alone allow: train_freq ÷ one update's time."""
    regs = registries()
    spec, agent = regs.envs.get("mountaincar"), regs.agents.get("dqn")
    values = dict(agent.defaults_for("mountaincar", "pixels").values)
    values.update(learning_starts=0)

    def make():
        return make_env(spec, "pixels", spec.max_episode_steps, {}, PixelSpec(), None)

    config = agent.config(**values)
    learner = agent.make(AgentContext(config, spec, make, 0, 1, "fp32", layout))
    start = time.perf_counter()
    learner.learn(frames, Count(frames))
    rate = frames / (time.perf_counter() - start)
    model = learner.model
    model.train(gradient_steps=1, batch_size=config.batch_size)  # warm
    start = time.perf_counter()
    for _ in range(updates):
        model.train(gradient_steps=1, batch_size=config.batch_size)
    per_update = (time.perf_counter() - start) / updates
    return rate, config.train_freq / per_update


def projected_hours(speedup: dict[tuple[str, str], float]) -> tuple[float, float]:
    """The paper suites' grid hours on 2 workers: as committed, and with the cells of each
    (agent, observation) in ``speedup`` that much faster."""
    today = after = 0.0
    for suite in PAPER:
        frame = read_results(ROOT / "results" / suite)
        for (agent, observation), walls in frame[frame.kind == "cell"].groupby(
                ["agent", "observation"])["cell_wall_s"]:
            today += walls.sum()
            after += walls.sum() / speedup.get((agent, observation), 1.0)
    return today / 2 / 3600, after / 2 / 3600


def main() -> None:
    set_threads(1)
    base, alone, together = sen_sarsa()
    dqn_rate, dqn_bound = pixel_dqn()
    nhwc_base, nhwc, _ = sen_sarsa(layout="channels_last", batched=False)
    nhwc_dqn, nhwc_bound = pixel_dqn(layout="channels_last")
    today, after = projected_hours({("sarsa", "encoded"): together[5] / alone[5]})
    _, laid_out = projected_hours({("sarsa", "encoded"): nhwc[5] / alone[5],
                                   ("dqn", "pixels"): nhwc_dqn / dqn_rate,
                                   ("ddqn", "pixels"): nhwc_dqn / dqn_rate})
    one, two = grid_seconds(1), grid_seconds(2)
    rows = [("SEN-SARSA 3 seeds alone ÷ encoder batch-1 rate", alone[3] / base, "≥ 1.3"),
            ("SEN-SARSA 3 seeds, seed_batch 3 ÷ encoder batch-1 rate", together[3] / base,
             "≥ 1.3"),
            ("SEN-SARSA 5 seeds, seed_batch 5 ÷ encoder batch-1 rate", together[5] / base,
             "≥ 1.3"),
            ("pixel DQN ÷ its fp32 update bound", dqn_rate / dqn_bound, "≥ 0.95"),
            ("paper suites on 2 cores, hours: committed", today, "≤ 6"),
            ("paper suites on 2 cores, hours: with seed batches", after, "≤ 6"),
            ("NHWC: SEN-SARSA 3 seeds alone ÷ NHWC encoder batch-1 rate",
             nhwc[3] / nhwc_base, "≥ 1.3"),
            ("NHWC: pixel DQN ÷ its NHWC fp32 update bound", nhwc_dqn / nhwc_bound, "≥ 0.95"),
            ("NHWC ÷ NCHW: SEN-SARSA 5 seeds alone", nhwc[5] / alone[5], "-"),
            ("NHWC ÷ NCHW: pixel DQN", nhwc_dqn / dqn_rate, "-"),
            ("paper suites on 2 cores, hours: SEN-SARSA, DQN, DDQN NHWC", laid_out, "≤ 6"),
            ("2 workers vs 1 (4 ppo-state cells)", one / two, "≥ 1.8")]
    print(f"encoder batch-1 {base:,.0f} frames/s; SEN-SARSA alone 3/5 seeds "
          f"{alone[3]:,.0f}/{alone[5]:,.0f}, batched {together[3]:,.0f}/{together[5]:,.0f}; "
          f"pixel DQN {dqn_rate:,.0f} frames/s, bound {dqn_bound:,.0f}; NHWC: encoder "
          f"{nhwc_base:,.0f}, SEN-SARSA alone 3/5 seeds {nhwc[3]:,.0f}/{nhwc[5]:,.0f}, "
          f"pixel DQN {nhwc_dqn:,.0f}, bound {nhwc_bound:,.0f}")
    width = max(len(r[0]) for r in rows)
    for name, value, target in rows:
        print(f"{name:<{width}}  {value:8.2f}   target {target}")


if __name__ == "__main__":
    main()
