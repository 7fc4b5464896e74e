"""The ``senbench`` command line."""

from __future__ import annotations

import functools
import os
import signal
import sys
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from senbench.errors import SenbenchError

app = typer.Typer(
    help="Benchmark data-efficient RL from images: state encoders (SEN-DRL) vs pixel RL.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
)
# Piped output (make demo, CI logs) gets tables 140 columns wide rather than rich's 80;
# COLUMNS still wins. Messages are never hard-wrapped, so they stay greppable.
_width = None if sys.stdout.isatty() or os.environ.get("COLUMNS") else 140
out = Console(width=_width, soft_wrap=True)
err = Console(stderr=True, soft_wrap=True)


def user_errors(command):
    """A user's mistake prints its message and exits 2; a traceback would be a bug."""

    @functools.wraps(command)
    def wrapper(*args, **kwargs):
        try:
            return command(*args, **kwargs)
        except SenbenchError as exc:
            err.print(f"[bold red]error:[/] {escape(str(exc))}", highlight=False)
            raise typer.Exit(exc.exit_code) from None

    return wrapper


def _load(suite_file: Path):
    from senbench.plugins import registries
    from senbench.suite import load_suite

    return load_suite(suite_file, registries())


@app.command()
@user_errors
def validate(suite_file: Annotated[Path, typer.Argument(help="Suite YAML file.")]) -> None:
    """Check a suite file and show the cells it expands into; runs nothing."""
    suite = _load(suite_file)
    model = suite.model
    variants = {(c.env, c.method, c.variant) for c in suite.cells}
    out.print(
        f"[green]ok[/]: suite '{suite.name}': {len(suite.cells)} cells = "
        f"{len(variants)} env × method × variant combinations × {len(model.seeds)} seeds"
    )


@app.command()
@user_errors
def run(
    suite_file: Annotated[Path, typer.Argument(help="Suite YAML file.")],
    workers: Annotated[int, typer.Option("--workers", "-w", min=1,
                                         help="Cells run in parallel processes.")] = 1,
    results: Annotated[Path, typer.Option(help="Results root; cells go to RESULTS/<suite>/.")]
    = Path("results"),
    force: Annotated[bool, typer.Option(help="Redo cells that already finished.")] = False,
) -> None:
    """Run every cell of a suite that has not finished yet (resumable)."""
    from senbench.progress import GridProgress
    from senbench.runner import run_suite

    suite = _load(suite_file)
    signal.signal(signal.SIGTERM, _stop_like_ctrl_c)  # batch schedulers stop jobs this way
    summary = run_suite(suite, results, workers=workers, force=force,
                        progress=GridProgress(err))
    folder = results / suite.name
    out.print(
        f"suite '{suite.name}': {summary.ok} finished, {len(summary.failed)} failed, "
        f"{summary.skipped} already done, of {summary.total} cells → {folder}"
    )
    for outcome in summary.failed:
        last = (outcome.error or "").strip().splitlines()[-1:] or [""]
        err.print(f"[red]failed[/] {escape(outcome.label)} ({outcome.cell_id}): "
                  f"{escape(last[0])}", highlight=False)
    if summary.interrupted:
        left = summary.total - summary.skipped - len(summary.outcomes)
        err.print(f"interrupted: {left} cells not run; run the same command again to resume")
        raise typer.Exit(130)
    if summary.failed:
        raise typer.Exit(1)


def _stop_like_ctrl_c(signum, frame) -> None:
    raise KeyboardInterrupt


@app.command()
@user_errors
def report(
    results_dir: Annotated[Path, typer.Argument(help="A suite's results folder.")],
    all_cells: Annotated[bool, typer.Option(
        "--all", help="Include cells of earlier versions of the suite.")] = False,
) -> None:
    """Final return, frames to threshold and AUC per env and method, over seeds."""
    from senbench.report import render, summarize
    from senbench.results import read_results

    results = read_results(results_dir, include_stale=all_cells)
    render(summarize(results), out)
    if results.attrs.get("stale"):
        err.print(f"left out {results.attrs['stale']} cells of earlier versions of the suite "
                  "(--all includes them)")


@app.command()
@user_errors
def compare(
    a: Annotated[str, typer.Argument(help="A method of --results, or a results folder.")],
    b: Annotated[str, typer.Argument(help="Another method of --results, or another folder.")],
    results: Annotated[Path | None, typer.Option(
        help="The results folder holding methods A and B.")] = None,
    all_cells: Annotated[bool, typer.Option(
        "--all", help="Include cells of earlier versions of the suite.")] = False,
) -> None:
    """A against B per env: IQM with CIs and the probability that A does better."""
    from senbench.compare import pairs_across_folders, pairs_in_one_folder, render
    from senbench.errors import ResultsError

    if results is not None:
        pairs = pairs_in_one_folder(results, a, b, include_stale=all_cells)
    elif Path(a).is_dir() and Path(b).is_dir():
        pairs = pairs_across_folders(Path(a), Path(b), include_stale=all_cells)
    else:
        raise ResultsError("name two results folders, or two methods and the folder that "
                           "holds them: senbench compare sen-sarsa sarsa-state --results "
                           "results/paper-mountaincar")
    render(pairs, out)


@app.command()
@user_errors
def show(
    env: Annotated[str, typer.Argument(help="An env plugin's name.")],
    png: Annotated[Path, typer.Option("--out", help="PNG file to write.")] = Path("frames.png"),
    frames: Annotated[int, typer.Option(min=1, max=32, help="States to show.")] = 8,
    height: Annotated[int, typer.Option(min=8, max=512)] = 64,
    width: Annotated[int, typer.Option(min=8, max=512)] = 64,
    seed: Annotated[int, typer.Option(help="Seed of the sampled states.")] = 0,
) -> None:
    """Sample frames of an env, with gymnasium's frame for the same state beside each."""
    from senbench.plugins import registries
    from senbench.show import save_comparison

    spec = registries().envs.get(env)
    difference = save_comparison(spec, png, frames, (height, width), seed)
    out.print(f"{png}: {frames} states of {env}; mean |difference| from gymnasium's resized "
              f"frames: {difference:.2f} grey levels")


@app.command()
@user_errors
def plugins() -> None:
    """Every env, agent, encoder and sampler installed, and which distribution provided it."""
    from senbench.plugins import registries

    regs = registries()
    table = Table(title="senbench plugins")
    for column in ("kind", "name", "provided by", "description"):
        table.add_column(column)
    for registry in (regs.envs, regs.agents, regs.encoders, regs.samplers):
        if not len(registry):
            table.add_row(registry.kind, "[dim]none installed[/]", "", "")
        for name in registry.names():
            spec = registry.get(name)
            table.add_row(registry.kind, name, str(registry.origin(name)), spec.description)
    out.print(table)


encoder_app = typer.Typer(help="State encoders: train, inspect.", no_args_is_help=True)
plot_app = typer.Typer(help="PNG figures.", no_args_is_help=True)
app.add_typer(encoder_app, name="encoder")
app.add_typer(plot_app, name="plot")


@encoder_app.command("train")
@user_errors
def encoder_train(
    env: Annotated[str, typer.Option(help="Env plugin.")],
    arch: Annotated[str, typer.Option(help="Encoder architecture.")] = "sen-resnet",
    sampler: Annotated[str, typer.Option(help="Sampler of labelled frames.")] = "uniform",
    samples: Annotated[int, typer.Option(min=10, help="Labelled pairs in the pool.")] = 50_000,
    fraction: Annotated[float, typer.Option(min=0.0001, max=1.0,
                                            help="Share of the pool trained on (d).")] = 0.2,
    seed: Annotated[int, typer.Option(min=0)] = 0,
    epochs: Annotated[int, typer.Option(min=1)] = 30,
    batch_size: Annotated[int, typer.Option(min=2)] = 128,
    learning_rate: Annotated[float, typer.Option(min=0.0)] = 1e-3,
    patience: Annotated[int, typer.Option(min=1)] = 4,
    test_samples: Annotated[int, typer.Option(min=10)] = 5000,
    height: Annotated[int, typer.Option(min=8, max=512)] = 64,
    width: Annotated[int, typer.Option(min=8, max=512)] = 64,
    stack: Annotated[int, typer.Option(min=1, max=16)] = 2,
    cache: Annotated[Path, typer.Option(help="Encoder cache.")] = Path("results/encoders"),
    threads: Annotated[int, typer.Option(min=0, help="torch threads (0: all cores).")] = 0,
) -> None:
    """Train a state encoder (or load it if this spec was trained before) and print its
    held-out error per dimension."""
    import pandas as pd

    from senbench.encoders import EncoderRequest, Training, cache_dir, complete, load_or_train
    from senbench.pixels import PixelSpec
    from senbench.plugins import registries
    from senbench.runner import set_threads, usable_cores

    regs = registries()
    regs.envs.get(env), regs.encoders.get(arch), regs.samplers.get(sampler)
    set_threads(threads or usable_cores())
    request = EncoderRequest(
        env=env, pixels=PixelSpec(height, width, stack), arch=arch, sampler=sampler,
        samples=samples, fraction=fraction, seed=seed,
        training=Training(epochs=epochs, batch_size=batch_size, learning_rate=learning_rate,
                          patience=patience, test_samples=test_samples))
    request = complete(request, regs)
    load_or_train(cache, request, regs, err.print)
    folder = cache_dir(cache, request)
    metrics = pd.read_parquet(folder / "metrics.parquet")
    errors = metrics[metrics["kind"] == "test"]
    table = Table(title=f"{env}: {arch}, {request.train_size} of {samples} {sampler} samples "
                        f"(d = {100 * fraction:g}%), held-out RMSE on {test_samples}")
    table.add_column("dimension")
    table.add_column("RMSE", justify="right")
    table.add_column("% of range", justify="right")
    for row in errors.itertuples():
        table.add_row(row.dimension, f"{row.rmse:.4g}", f"{row.rmse_pct_of_range:.2f}")
    out.print(table)
    epochs_run = int(metrics["epoch"].max())
    out.print(f"encoder {request.id}: {epochs_run} epochs, trained in "
              f"{errors['wall_s'].iloc[0]:.0f} s → {folder}")


@plot_app.command("curves")
@user_errors
def plot_curves_command(
    results_dir: Annotated[Path, typer.Argument(help="A suite's results folder.")],
    png: Annotated[Path | None, typer.Option(
        "--out", help="PNG file to write (default: RESULTS_DIR/curves.png).")] = None,
    all_cells: Annotated[bool, typer.Option(
        "--all", help="Include cells of earlier versions of the suite.")] = False,
) -> None:
    """Evaluation return against frames, mean and 95% CI band over seeds per method (the
    paper's Figs. 4, 5, 8 and 9)."""
    from senbench.plots import plot_curves
    from senbench.results import read_results

    results = read_results(results_dir, include_stale=all_cells)
    png = png or results_dir / "curves.png"
    suite = results["suite"].iloc[0]
    envs = plot_curves(results, png, f"{suite}: learning curves")
    out.print(f"{png}: {', '.join(envs)}")


@plot_app.command("traces")
@user_errors
def plot_traces_command(
    paths: Annotated[list[Path] | None, typer.Argument(
        help="Encoder folders, or caches holding them.")] = None,
    env: Annotated[str | None, typer.Option(help="Only this env's encoders.")] = None,
    results: Annotated[Path | None, typer.Option(
        help="The encoders a suite's cells used, from its results folder (and the "
        "encoders/ cache beside it).")] = None,
    png: Annotated[Path, typer.Option("--out", help="PNG file to write.")] = Path("traces.png"),
) -> None:
    """Predicted vs true observation along a successful trajectory, one line per encoder
    (the paper's Figs. 6 and 10)."""
    from senbench.errors import ResultsError
    from senbench.plots import find_encoders, plot_traces
    from senbench.results import read_results

    if results is not None:
        frame = read_results(results)
        ids = sorted(set(frame["encoder_id"].dropna()))
        if not ids:
            raise ResultsError(f"no cell in {results} ran on an encoder")
        from senbench.results import find_cell_files

        roots = {f.parent.parent.parent for f in find_cell_files(results)}
        folders = [next((r / "encoders" / i for r in roots if (r / "encoders" / i).exists()),
                        None) for i in ids]
        missing = [i for i, f in zip(ids, folders, strict=True) if f is None]
        if missing:
            raise ResultsError(f"encoders {', '.join(missing)} used by {results} are not in "
                               f"{' or '.join(str(r / 'encoders') for r in sorted(roots))}; "
                               "run the suite again to train them")
        paths = [*(paths or []), *folders]
    encoders = find_encoders(paths or [Path("results/encoders")], env)
    plot_traces(encoders, png)
    out.print(f"{png}: {len(encoders)} encoders")
