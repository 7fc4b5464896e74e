"""Encoder accuracy at the default spec, for the paper's d ∈ {2, 10, 20, 100}% of a
50,000-sample uniform pool, on both envs: held-out RMSE per dimension (units and % of
range), epochs, training time; then the trace figures of each env.

    .venv/bin/python benchmarks/encoder_accuracy.py [ENV ...] [--fractions 0.02,0.1,0.2,1]

d = 100% trains on 45,000 frame stacks an epoch (≈ 40 s an epoch on 2 cores, idle).

Encoders go to results/encoders (the cache `senbench run` uses), so a later suite with the
same spec loads them instead of training.
"""

from __future__ import annotations

import sys
from pathlib import Path

from senbench.cli.plots import find_encoders, plot_traces
from senbench.encoders import EncoderRequest, cache_dir, complete, load_or_train
from senbench.observe.pixels import PixelSpec
from senbench.plugin.manager import registries

CACHE = Path("results/encoders")
FRACTIONS = (0.02, 0.10, 0.20, 1.00)


def main(envs: list[str], fractions: tuple[float, ...] = FRACTIONS) -> None:
    import json

    regs = registries()
    rows = []
    for env in envs:
        requests = [complete(EncoderRequest(env, PixelSpec(), "sen-resnet", "uniform", 50_000,
                                            d), regs) for d in fractions]
        for request in requests:
            load_or_train(CACHE, request, regs, lambda m: print(m, flush=True))
            spec = json.loads((cache_dir(CACHE, request) / "spec.json").read_text())
            errors = ", ".join(f"{e['dimension']} {e['rmse']:.4g} "
                               f"({e['rmse_pct_of_range']:.2f}%)" for e in spec["errors"])
            rows.append(f"| {env} | {100 * request.fraction:g}% | {request.train_size} | "
                        f"{errors} | {spec['train_wall_s'] / 60:.1f} min |")
        ids = {r.id for r in requests}
        chosen = [e for e in find_encoders([CACHE], env) if e[0]["id"] in ids]
        plot_traces(chosen, Path(f"docs/images/traces-{env}.png"))
    print("| env | d | training samples | held-out RMSE (% of range) | training time |")
    print("| --- | --- | --- | --- | --- |")
    print("\n".join(rows))


if __name__ == "__main__":
    args = sys.argv[1:]
    chosen = FRACTIONS
    if "--fractions" in args:
        at = args.index("--fractions")
        chosen = tuple(float(v) for v in args[at + 1].split(","))
        del args[at:at + 2]
    main(args or ["mountaincar", "pendulum"], chosen)
