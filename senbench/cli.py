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
from rich.table import Table

from senbench.errors import SenbenchError

app = typer.Typer(
    help="Benchmark data-efficient RL from images: state encoders (SEN-DRL) vs pixel RL.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
)
# Piped output (make demo, CI logs) gets tables 120 columns wide rather than rich's 80;
# COLUMNS still wins. Messages are never hard-wrapped, so they stay greppable.
_width = None if sys.stdout.isatty() or os.environ.get("COLUMNS") else 120
out = Console(width=_width, soft_wrap=True)
err = Console(stderr=True, soft_wrap=True)


def user_errors(command):
    """A user's mistake prints its message and exits 2; a traceback would be a bug."""

    @functools.wraps(command)
    def wrapper(*args, **kwargs):
        try:
            return command(*args, **kwargs)
        except SenbenchError as exc:
            err.print(f"[bold red]error:[/] {exc}", highlight=False, markup=True)
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
        err.print(f"[red]failed[/] {outcome.label} ({outcome.cell_id}): {last[0]}",
                  highlight=False)
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


def main() -> None:  # pragma: no cover - console entry for `python -m senbench`
    sys.exit(app())
