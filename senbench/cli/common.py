"""What every command shares: the consoles, the user-error wrapper, option types."""

from __future__ import annotations

import functools
import os
import sys
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.markup import escape

from senbench.errors import SenbenchError

# Piped output (make demo, CI logs) gets tables 140 columns wide rather than rich's 80;
# COLUMNS still wins. Messages are never hard-wrapped, so they stay greppable.
_width = None if sys.stdout.isatty() or os.environ.get("COLUMNS") else 140
out = Console(width=_width, soft_wrap=True)
err = Console(stderr=True, soft_wrap=True)


def user_errors(command):
    """A user's mistake prints its message and exits 2; a traceback would be a bug. A
    plugin left out (it failed to import, its hook raised, it registers a name taken) is
    a warning, printed once, when the command first asks for the plugins."""

    @functools.wraps(command)
    def wrapper(*args, **kwargs):
        from senbench.plugin.manager import report_problems

        report_problems(warn)
        try:
            return command(*args, **kwargs)
        except SenbenchError as exc:
            err.print(f"[bold red]error:[/] {escape(str(exc))}", highlight=False)
            raise typer.Exit(exc.exit_code) from None

    return wrapper


def load_suite_file(suite_file: Path):
    """A suite file, loaded and validated against the installed plugins."""
    from senbench.plugin.manager import registries
    from senbench.suite import load_suite

    return load_suite(suite_file, registries())


def warn(message: str) -> None:
    err.print(f"[yellow]warning:[/] {escape(message)}", highlight=False)


FIGURE_HELP = "Figure to write: a .png, .pdf or .svg file."
Table = Annotated[Path | None, typer.Option(
    "--out", help="Also write the numbers shown to this .csv or .parquet file (replacing it).")]
Threshold = Annotated[list[str] | None, typer.Option(
    help="Frames to threshold (and the plots' dashed line) at this return instead of the "
         "env's: -150 (results of one env) or mountaincar=-150 (repeat for several envs).")]


# A part of a suite's grid, for the commands that run cells (run, verify).
PickMethods = Annotated[list[str] | None, typer.Option(
    "--method", help="Only this method's cells (repeat for several).")]
PickEnvs = Annotated[list[str] | None, typer.Option(
    "--env", help="Only this env's cells (repeat for several).")]
PickSeeds = Annotated[list[int] | None, typer.Option(
    "--seed", help="Only this seed's cells (repeat for several).")]
PickVariants = Annotated[list[str] | None, typer.Option(
    "--variant", help="Only this variant's cells, as the report names it, e.g. "
    "encoder.fraction=0.5 (repeat for several).")]
