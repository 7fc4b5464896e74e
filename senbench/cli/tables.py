"""Tables of things other than results: installed plugins, a trained encoder's error.
Only rich at import time, so ``senbench plugins`` stays quick."""

from __future__ import annotations

from typing import Any

from rich.console import Console
from rich.markup import escape
from rich.table import Table


def show_encoder(metrics: Any, title: str, console: Console) -> None:
    """An encoder's ``metrics.parquet``: held-out RMSE per state dimension, then its epochs
    and training time."""
    errors = metrics[metrics["kind"] == "test"]
    table = Table(title=title)
    table.add_column("dimension")
    table.add_column("RMSE", justify="right")
    table.add_column("% of range", justify="right")
    for row in errors.itertuples():
        table.add_row(escape(str(row.dimension)), f"{row.rmse:.4g}",
                      f"{row.rmse_pct_of_range:.2f}")
    console.print(table)
    console.print(f"{int(metrics['epoch'].max())} epochs, trained in "
                  f"{errors['wall_s'].iloc[0]:.0f} s")


def show_plugins(registries, console: Console) -> None:
    """Every registered env, agent, encoder and sampler with the distribution it came from."""
    table = Table(title="senbench plugins")
    for column in ("kind", "name", "provided by", "description"):
        table.add_column(column)
    for registry in (registries.envs, registries.agents, registries.encoders,
                     registries.samplers):
        if not len(registry):
            table.add_row(registry.kind, "[dim]none installed[/]", "", "")
        for name in registry.names():
            spec = registry.get(name)
            table.add_row(registry.kind, escape(name), escape(str(registry.origin(name))),
                          escape(spec.description))
    console.print(table)
    if registries.problems:  # disabled on purpose too: what is not there, and why
        left = Table(title="left out")
        for column in ("plugin", "provided by", "what", "why"):
            left.add_column(column)
        for problem in registries.problems:
            left.add_row(escape(problem.plugin), escape(str(problem.origin)),
                         escape(problem.thing or "all of it"), escape(problem.reason))
        console.print(left)
