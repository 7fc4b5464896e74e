"""PNG figures a reader takes in at a glance: titles, axis units, legends."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd

from senbench.errors import ResultsError
from senbench.results.outputs import save_figure
from senbench.suite import Cell

DASHES = ["-", (0, (6, 3)), (0, (1, 2)), (0, (6, 2, 1, 2))]
"""Line styles of the methods on a curves plot, in turn."""


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


def encoders_of_results(results: Path, env: str | None = None, train: bool = False,
                        log=lambda message: None) -> list[Path]:
    """The folders of the encoders a results folder's cells (of ``env``, if given) ran on,
    in the ``encoders/`` cache beside the suites. One that is missing is trained from the
    cells' own spec if ``train`` (its id is the spec's hash, so it is the same encoder),
    else an error says so."""
    import json

    from senbench.results.store import find_cell_files, read_results

    frame = read_results(results)
    cells = frame[(frame["kind"] == "cell") & ((frame["env"] == env) if env else True)]
    cells = cells.dropna(subset=["encoder_id"])
    configs = dict(zip(cells["encoder_id"], cells["config"], strict=True))
    if not configs:
        raise ResultsError(f"no cell in {results} ran on an encoder"
                           + (f" on env '{env}'" if env else ""))
    roots = sorted({f.parent.parent.parent for f in find_cell_files(results)})
    folders = {i: next((r / "encoders" / i for r in roots
                        if (r / "encoders" / i / "model.pt").exists()), None)
               for i in sorted(configs)}
    missing = [i for i, folder in folders.items() if folder is None]
    if missing and not train:
        raise ResultsError(f"encoders {', '.join(missing)} used by {results} are not in "
                           f"{' or '.join(str(r / 'encoders') for r in roots)}; add --train "
                           "to train them from the cells' spec")
    if missing:
        from senbench.encoders import cache_dir, load_or_train
        from senbench.plugin.manager import registries

        for encoder_id in missing:
            request = Cell.from_config(json.loads(configs[encoder_id]), "").encoder_request()
            if request.id != encoder_id:  # the spec means something else to this build
                raise ResultsError(f"encoder {encoder_id} of {results}: this senbench names "
                                   f"its spec {request.id}, so it cannot train the same one")
            load_or_train(roots[0] / "encoders", request, registries(), log)
            folders[encoder_id] = cache_dir(roots[0] / "encoders", request)
    return list(folders.values())


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
    save_figure(fig, out, 110)


def learning_curves(results: pd.DataFrame, charge_labelled: bool = False
                    ) -> dict[str, dict[str, pd.DataFrame]]:
    """env → method label → finished cells' evaluation returns (one row per cell, one
    column per frame), on the evaluation frames every one of those cells has. Labels name
    the suite when the results hold several. ``charge_labelled``: an encoded method's frames
    start at the labelled frames its encoder was trained on, not at 0."""
    from senbench.analysis.summary import cell_labels, label

    cells = results[(results["kind"] == "cell") & (results["status"] == "ok")]
    evals = results[results["kind"] == "eval"]
    evals = evals[evals["cell_id"].isin(cells["cell_id"])]
    several = evals["suite"].nunique() > 1
    curves: dict[str, dict[str, pd.DataFrame]] = {}
    keys = ["suite", "env", "method", "variant"]
    for (suite, env, method, variant), group in evals.groupby(keys, sort=True):
        if group.groupby("seed")["cell_id"].nunique().max() > 1:
            raise ResultsError(f"{suite}: cells of several versions of the suite share "
                               f"{method} and a seed; plot without --all")
        table = group.pivot(index="cell_id", columns="step", values="return")
        name = (f"{suite}: " if several else "") + label(method, variant)
        labelled = cell_labels(cells[cells["cell_id"] == table.index[0]]["config"].iloc[0]
                               if "config" in cells else None)["labelled_frames"]
        if charge_labelled and labelled:
            table.columns = table.columns + labelled
            name += f" (+{labelled:,} labelled)"
        curves.setdefault(env, {})[name] = table.dropna(axis=1)
    return curves


def plot_curves(results: pd.DataFrame, out: Path, title: str,
                charge_labelled: bool = False) -> list[str]:
    """Mean evaluation return against frames with a 95% bootstrap band over seeds, one
    line per method (and variant), one panel per env, the threshold dashed: the paper's
    Figs. 4, 5, 8 and 9. ``charge_labelled`` shifts each encoded method right by the
    labelled frames its encoder consumed. Returns the envs drawn."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import FuncFormatter

    from senbench.analysis.stats import mean_ci

    curves = learning_curves(results, charge_labelled)
    if not curves:
        raise ResultsError("no finished cell with evaluations to plot; run the suite first")
    cells = results[results["kind"] == "cell"]
    fig, axes = plt.subplots(1, len(curves), figsize=(7.5 * len(curves), 4.8), squeeze=False)
    for ax, (env, methods) in zip(axes[0], curves.items(), strict=True):
        for i, (name, table) in enumerate(methods.items()):
            steps, values = table.columns.to_numpy(dtype=float), table.to_numpy(dtype=float)
            mean = values.mean(axis=0)
            # a dash pattern per method: curves that coincide (two agents stuck at -1,000)
            # still both show
            (line,) = ax.plot(steps, mean, linewidth=1.8, linestyle=DASHES[i % len(DASHES)],
                              label=f"{name} ({values.shape[0]} seeds)")
            low, high = mean_ci(values)
            ax.fill_between(steps, low, high, color=line.get_color(), alpha=0.2, linewidth=0)
        threshold = cells[cells["env"] == env]["threshold"].iloc[0]
        if pd.notna(threshold) and abs(threshold) != float("inf"):
            ax.axhline(threshold, color="black", linestyle="--", linewidth=1,
                       label=f"threshold {threshold:g}")
        ax.set_title(env)
        ax.set_xlabel("frames (environment steps)" + (
            "; encoded methods start at their labelled frames" if charge_labelled else ""))
        ax.set_ylabel("evaluation return (mean over seeds, 95% CI band)")
        ax.xaxis.set_major_formatter(FuncFormatter(
            lambda x, _: f"{x / 1e6:g}M" if x >= 1e6 else f"{x / 1e3:g}k" if x else "0"))
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="lower right")
    fig.suptitle(title)
    fig.tight_layout()
    save_figure(fig, out, 110)
    return list(curves)
