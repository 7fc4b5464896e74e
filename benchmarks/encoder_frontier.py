"""The encoder cost frontier: held-out accuracy against inference cost, for sen-resnet at
several widths and for sen-keypoints (a spatial-softmax keypoint head), on both envs at
the paper's d = 20% of a 50,000-sample uniform pool (10,000 labelled frame stacks).

    .venv/bin/python benchmarks/encoder_frontier.py [ENV ...] [--train-only | --measure-only]
    (≈ 1 h on 2 idle cores the first time: 8 encoders to train; cached after)

For each: held-out RMSE per state dimension (% of its range, on 5,000 independent
frames), MFLOP per frame (torch.utils.flop_counter at batch 1), and frames/s through
senbench's own inference path (``StateEncoder``: frozen TorchScript, one torch thread) at
batch 1 and 32; a markdown table on stdout and docs/images/encoder-frontier.png. Encoders go
to results/encoders (the cache `senbench run` uses), so a suite with the same spec loads
them instead of training, and a second run only measures. ``--train-only`` trains them
and stops: training may share the machine; the speed columns want it idle.
``--measure-only`` measures the encoders trained so far and leaves out the rest.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from seed_batch import batch_costs

from senbench.encoders import EncoderRequest, cache_dir, complete, load, load_or_train
from senbench.observe.pixels import PixelSpec
from senbench.plugin.manager import registries
from senbench.run.processes import set_threads

CACHE = Path("results/encoders")
FIGURE = Path("docs/images/encoder-frontier.png")
DESIGNS = [  # (label, arch, config), cheapest to train first
    ("sen-keypoints ×0.5", "sen-keypoints", {"widths": [8, 16], "keypoints": 8,
                                             "hidden": 64}),
    ("sen-keypoints", "sen-keypoints", {}),
    ("sen-resnet ×0.5", "sen-resnet", {"widths": [8, 16, 32, 32], "hidden": 128}),
    ("sen-resnet (paper)", "sen-resnet", {}),
    ("sen-resnet ×2", "sen-resnet", {"widths": [32, 64, 128, 128], "hidden": 512}),
]


def cost(encoder, seconds: float = 3.0) -> tuple[float, float, float]:
    """MFLOP per frame, and frames/s at batch 1 and 32."""
    import torch
    from torch.utils.flop_counter import FlopCounterMode

    with torch.no_grad(), FlopCounterMode(display=False) as counter:
        encoder.model(torch.zeros((1, 2, 64, 64), dtype=torch.float32))
    ms = batch_costs(encoder, (1, 32), seconds)
    return counter.get_total_flops() / 1e6, 1e3 / ms[1], 1e3 / ms[32]


def main(envs: list[str], mode: str = "") -> None:
    """``--train-only``: train (or find) every encoder and stop; ``--measure-only``: measure
    the encoders already trained, leaving out the others; neither: both."""
    regs = registries()
    encoders = {}
    for label, arch, config in DESIGNS:  # train (or load) them all first, cheapest first
        for env in envs:
            request = complete(EncoderRequest(env, PixelSpec(), arch, "uniform", 50_000, 0.2,
                                              arch_config=config), regs)
            encoder = (load(CACHE, request, regs) if mode == "--measure-only" else
                       load_or_train(CACHE, request, regs, lambda m: print(m, flush=True)))
            if encoder is None:
                print(f"{env} {label}: not trained yet, left out")
            else:
                encoders[env, label] = request, encoder
    if mode == "--train-only":
        return
    set_threads(1)  # inference; training ran on its spec's threads
    rows, points = [], {}
    for env in envs:
        for label in [label for label, _, _ in DESIGNS if (env, label) in encoders]:
            request, encoder = encoders[env, label]
            spec = json.loads((cache_dir(CACHE, request) / "spec.json").read_text())
            errors = {e["dimension"]: e["rmse_pct_of_range"] for e in spec["errors"]}
            mflop, batch1, batch32 = cost(encoder)
            points.setdefault(env, []).append((label, mflop, errors))
            rows.append(f"| {env} | {label} | "
                        + ", ".join(f"{k} {v:.2f}%" for k, v in errors.items())
                        + f" | {mflop:.1f} | {batch1:,.0f} | {batch32:,.0f} | "
                        f"{spec['train_wall_s'] / 60:.1f} min | {request.id} |")
    print("| env | encoder | held-out RMSE (% of range) | MFLOP/frame | frames/s batch 1 "
          "| frames/s batch 32 | training | id |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    print("\n".join(rows))
    plot(points)


def plot(points: dict[str, list[tuple[str, float, dict[str, float]]]]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(points), figsize=(6 * len(points), 4.2), squeeze=False)
    for ax, (env, entries) in zip(axes[0], points.items(), strict=True):
        dimensions = list(entries[0][2])
        for dimension, marker in zip(dimensions, "osD^v", strict=False):
            ax.scatter([e[1] for e in entries], [e[2][dimension] for e in entries],
                       marker=marker, label=dimension)
        for label, mflop, errors in entries:
            ax.annotate(label, (mflop, max(errors.values())), fontsize=7,
                        textcoords="offset points", xytext=(3, 3))
        ax.set_xscale("log")
        ax.set_xlabel("MFLOP per frame (batch 1)")
        ax.set_ylabel("held-out RMSE, % of range")
        ax.set_title(f"{env}, d = 20% (10,000 labelled frames)")
        ax.legend(fontsize=8)
    fig.tight_layout()
    FIGURE.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(FIGURE, dpi=120)
    print(f"figure: {FIGURE}")


if __name__ == "__main__":
    modes = [a for a in sys.argv[1:] if a in ("--train-only", "--measure-only")]
    main([a for a in sys.argv[1:] if a not in modes] or ["mountaincar", "pendulum"],
         modes[0] if modes else "")
