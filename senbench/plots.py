"""PNG figures a reader takes in at a glance: titles, axis units, legends."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd

from senbench.errors import ResultsError


def find_encoders(paths: list[Path], env: str | None) -> list[tuple[dict, pd.DataFrame]]:
    """(spec, traces) of every trained encoder under ``paths`` (encoder folders, or a cache
    holding them), for ``env`` if given, ordered by fraction."""
    found = []
    for path in paths:
        folders = [path] if (path / "spec.json").exists() else sorted(path.glob("*/"))
        for folder in folders:
            needed = ("spec.json", "traces.parquet", "model.pt")  # model.pt is written last
            if not all((folder / name).exists() for name in needed):
                continue
            spec = json.loads((folder / "spec.json").read_text())
            if env is None or spec["env"] == env:
                found.append((spec, pd.read_parquet(folder / "traces.parquet")))
    if not found:
        raise ResultsError(f"no trained encoder with traces under {', '.join(map(str, paths))}"
                           + (f" for env '{env}'" if env else "")
                           + "; train one with 'senbench encoder train'")
    return sorted(found, key=lambda item: (item[0]["arch"], item[0]["fraction"]))


def plot_traces(encoders: list[tuple[dict, pd.DataFrame]], out: Path) -> None:
    """True and predicted observation along the demo trajectory, one panel per dimension,
    one line per encoder (labelled by what differs between them, d first)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    envs = {spec["env"] for spec, _ in encoders}
    if len(envs) > 1:
        raise ResultsError(f"encoders of several envs ({', '.join(sorted(envs))}): "
                           "pass --env")
    dimensions = list(dict.fromkeys(encoders[0][1]["dimension"]))
    keys = ("arch", "sampler", "samples", "seed", "arch_config", "sampler_config", "pixels",
            "training")
    varying = [k for k in keys if len({json.dumps(s[k], sort_keys=True)
                                       for s, _ in encoders}) > 1]
    fig, axes = plt.subplots(len(dimensions), 1, figsize=(9, 2.6 * len(dimensions)),
                             sharex=True, squeeze=False)
    for row, dimension in enumerate(dimensions):
        ax = axes[row][0]
        first = encoders[0][1]
        truth = first[first["dimension"] == dimension]
        ax.plot(truth["step"], truth["true"], color="black", linewidth=2.2, label="true")
        for spec, traces in encoders:
            part = traces[traces["dimension"] == dimension]
            label = f"d = {100 * spec['fraction']:g}%" + "".join(
                f", {k} {spec[k]}" for k in varying)
            ax.plot(part["step"], part["predicted"], linewidth=1.1, label=label)
        ax.set_ylabel(dimension)
        ax.grid(alpha=0.3)
    axes[0][0].legend(fontsize=8, ncol=3, loc="best")
    axes[-1][0].set_xlabel("step of the trajectory (the env's demo policy, from seed 0)")
    env = encoders[0][0]["env"]
    fig.suptitle(f"{env}: state encoder estimates vs the true observation "
                 f"({int(first['step'].max()) + 1} steps)")
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
