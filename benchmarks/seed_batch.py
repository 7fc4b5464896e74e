"""SEN-SARSA's seeds alone and in a seed batch, side by side, on one torch thread: frames/s
of the whole run (all seeds) divided by the encoder's rate at batch 1 (the issue's target:
≥ 1.3 for a 3-seed run; one seed a frame at a time reaches 0.5-0.8).

    .venv/bin/python benchmarks/seed_batch.py            (≈ 4 min on 2 idle cores)
    .venv/bin/python benchmarks/seed_batch.py --frames 2000 --seeds 3   (a quick look)

It first prints the encoder's own cost per frame at batch sizes 1-8 (frozen TorchScript,
one thread): the most a seed batch can save is on that share of a step.

Each run is senbench's own path (``senbench.run.batch.execute_cells``, as a worker runs a
batch): the paper's sen-resnet at 2x64x64, SARSA with its MountainCar defaults, 200-step
episodes, evaluations at 0 and at the budget only. The encoder is trained on 64 labelled
frames for one epoch — its speed does not depend on its weights, and the curves are not
read — so the agent's episodes are those of a poor encoder, about as long as a learning
one's early on.
"""

from __future__ import annotations

import argparse
import tempfile
import textwrap
import time
from pathlib import Path

import numpy as np

from senbench.encoders import load_or_train
from senbench.plugin.manager import registries
from senbench.run.batch import execute_cells
from senbench.run.execute import RunInfo
from senbench.run.processes import set_threads
from senbench.suite import load_suite

SUITE = """\
name: seed-batch-benchmark
envs:
  mountaincar: {{max_episode_steps: 200}}
methods:
  sen-sarsa:
    agent: sarsa
    observation: encoded
    encoder: {{samples: 64, fraction: 1.0, epochs: 1, test_samples: 32}}
seeds: {seeds}
seed_batch: {batch}
memory_format: {layout}
budget: {frames}
eval: {{every: {frames}, episodes: 1}}
"""


def cells(folder: Path, seeds: int, batch: int, frames: int, layout: str = "contiguous"):
    path = folder / f"batch{batch}-{layout}.yaml"
    path.write_text(textwrap.dedent(SUITE.format(seeds=seeds, batch=batch, frames=frames,
                                                 layout=layout)))
    return load_suite(path, registries()).cells


def batch1_rate(encoder, seconds: float = 5.0) -> float:
    return 1e3 / batch_costs(encoder, (1,), seconds)[1]


def batch_costs(encoder, sizes=(1, 2, 3, 5, 8), seconds: float = 2.0) -> dict[int, float]:
    """Milliseconds of encoder time per frame at each batch size (one pass of B frames ÷ B),
    on random 2x64x64 frames: what a seed batch of B can save at most on the encoder's
    share of a step."""
    frames = np.random.default_rng(0).integers(0, 256, (max(sizes), 2, 64, 64), dtype=np.uint8)
    costs = {}
    for size in sizes:
        batch = frames[:size]
        for _ in range(10):  # freezes the TorchScript copy for this shape and warms it
            encoder(batch)
        start, n = time.perf_counter(), 0
        while time.perf_counter() - start < seconds:
            encoder(batch)
            n += 1
        costs[size] = (time.perf_counter() - start) / n / size * 1e3
    return costs


def run_rate(todo, info: RunInfo) -> float:
    """Frames/s of the cells run as a worker runs them: the seeds one after another (batch
    1), or together (a seed batch)."""
    start = time.perf_counter()
    results = execute_cells(todo, info)
    wall = time.perf_counter() - start
    failed = [o.error for _, o in results if o.status != "ok"]
    if failed:
        raise SystemExit(f"a cell failed: {failed[0]}")
    return sum(c.budget for c in todo) / wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=10_000, help="frames per seed")
    parser.add_argument("--seeds", type=int, nargs="+", default=[3, 5],
                        help="seed counts to run, each alone and as one batch")
    args = parser.parse_args()
    set_threads(1)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        info = RunInfo.gather(folder / "encoders")
        first = cells(folder, 1, 1, args.frames)[0]
        encoder = load_or_train(info.encoder_cache, first.encoder_request(), registries())
        base = batch1_rate(encoder)
        print(f"sen-resnet, 2x64x64, one thread: {base:,.0f} frames/s at batch 1")
        costs = batch_costs(encoder)
        print("encoder ms per frame by batch size: " + ", ".join(
            f"{size}: {ms:.2f} ({costs[1] / ms:.2f}x)" for size, ms in costs.items()))
        print(f"{'seeds':>5}  {'seed_batch':>10}  {'frames/s':>9}  {'÷ batch-1 rate':>14}  "
              f"{'vs alone':>8}")
        for seeds in args.seeds:
            alone = run_rate(cells(folder, seeds, 1, args.frames), info)
            together = run_rate(cells(folder, seeds, seeds, args.frames), info)
            print(f"{seeds:>5}  {1:>10}  {alone:>9,.0f}  {alone / base:>14.2f}  {1:>8.2f}")
            print(f"{seeds:>5}  {seeds:>10}  {together:>9,.0f}  {together / base:>14.2f}  "
                  f"{together / alone:>8.2f}")


if __name__ == "__main__":
    main()
