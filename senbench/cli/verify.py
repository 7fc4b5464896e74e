"""``senbench verify``: do committed results still come out of today's code?"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.markup import escape
from rich.table import Table

from senbench.cli.common import (
    PickEnvs,
    PickMethods,
    PickSeeds,
    PickVariants,
    err,
    load_suite_file,
    out,
    user_errors,
)

OUTCOME_STYLE = {"same": "green", "different": "bold red", "failed": "bold red",
                 "not run": "yellow"}


@user_errors
def verify(
    suite_file: Annotated[Path, typer.Argument(help="Suite YAML file.")],
    frames: Annotated[int, typer.Option(
        min=1, help="Frames of each cell to run again: the first part of its curve (its "
                    "schedules still span its budget). Every training episode and "
                    "evaluation that ends before the last of them is compared.")],
    results: Annotated[Path, typer.Option(help="Results root the suite ran under.")]
    = Path("results"),
    method: PickMethods = None,
    env: PickEnvs = None,
    seed: PickSeeds = None,
    variant: PickVariants = None,
) -> None:
    """Run the first --frames frames of a suite's finished cells again, one at a time, and
    compare each curve with its result file, row for row. Exit 1 if any differs or fails
    to run; nothing is written."""
    from senbench.results.store import cells_dir
    from senbench.run.execute import RunInfo
    from senbench.run.verify import verify_cells

    suite = load_suite_file(suite_file)
    cells = suite.select(method or [], env or [], seed or [], variant or [])
    directory = cells_dir(results, suite.name)
    info = RunInfo.gather(results / "encoders")

    def said(verdict) -> None:
        colour = OUTCOME_STYLE[verdict.outcome]
        err.print(f"{escape(verdict.cell.label)}: [{colour}]{verdict.outcome}[/]"
                  + (f" — {escape(verdict.detail)}" if verdict.detail else ""),
                  highlight=False)

    verdicts = verify_cells(cells, directory, frames, info, done=said)
    table = Table(title=f"suite '{suite.name}': the first {frames:,} frames run again")
    for name in ("env", "method", "seed", "committed by", "rows compared", "outcome"):
        table.add_column(name, justify="right" if name in ("seed", "rows compared") else "left")
    for v in verdicts:
        variant = f"[{v.cell.variant}]" if v.cell.variant else ""
        table.add_row(escape(v.cell.env), escape(v.cell.method + variant), str(v.cell.seed),
                      escape(_commit(v.git_commit)),
                      str(v.compared) if v.outcome in ("same", "different") else "",
                      f"[{OUTCOME_STYLE[v.outcome]}]{v.outcome}[/]")
    out.print(table)
    bad = [v for v in verdicts if v.outcome in ("different", "failed")]
    unrun = sum(v.outcome == "not run" for v in verdicts)
    out.print(f"{sum(v.outcome == 'same' for v in verdicts)} same, {len(bad)} different or "
              f"failed, {unrun} with no finished result to compare")
    if bad:
        raise typer.Exit(1)


def _commit(described: str | None) -> str:
    """A result file's git_commit, short: 12 hex digits, and 'dirty' when its code differed
    from that commit (then no commit holds the code that ran)."""
    if not described:
        return ""
    return described[:12] + (" dirty" if described.endswith("-dirty") else "")
