"""``senbench report``: a table per env, one row per method (and variant), over seeds."""

from __future__ import annotations

import numpy as np
import pandas as pd
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from senbench.metrics import FINAL_WINDOW, THRESHOLD_WINDOW, cell_metrics


def summarize(results: pd.DataFrame) -> pd.DataFrame:
    """Per env × method × variant: mean and std over finished seeds of each metric, how many
    seeds finished and failed, and how many reached the threshold."""
    per_cell = cell_metrics(results)
    rows = []
    keys = ["suite", "env", "method", "variant"]
    for (suite, env, method, variant), group in per_cell.groupby(keys, sort=True):
        ok = group[group["status"] == "ok"]
        reached = ok["steps_to_threshold"].dropna()
        rows.append({
            "suite": suite, "env": env, "method": method, "variant": variant,
            "threshold": group["threshold"].iloc[0], "budget": int(group["budget"].max()),
            "seeds_ok": len(ok), "seeds_failed": int((group["status"] != "ok").sum()),
            "initial_mean": _mean(ok["initial_return"]),
            "initial_std": _std(ok["initial_return"]),
            "final_mean": _mean(ok["final_return"]), "final_std": _std(ok["final_return"]),
            "reached": len(reached),
            "steps_mean": _mean(reached), "steps_std": _std(reached),
            "auc_mean": _mean(ok["auc"]), "auc_std": _std(ok["auc"]),
        })
    return pd.DataFrame(rows)


def _mean(values: pd.Series) -> float:
    return float(values.mean()) if len(values) else float("nan")


def _std(values: pd.Series) -> float:
    return float(values.std(ddof=0)) if len(values) else float("nan")


def _pm(mean: float, std: float, digits: int = 1) -> str:
    if np.isnan(mean):
        return "—"
    return f"{mean:,.{digits}f} ± {std:,.{digits}f}"


def render(summary: pd.DataFrame, console: Console) -> None:
    several = summary["suite"].nunique() > 1
    for (suite, env), rows in summary.groupby(["suite", "env"], sort=True):
        where = f"{suite} / {env}" if several else env
        table = Table(
            title=f"{where}: evaluation return; threshold {rows['threshold'].iloc[0]:g}, "
            f"budget {rows['budget'].max():,} frames",
            caption=f"mean ± std over finished seeds. final: last {FINAL_WINDOW} evaluations. "
            f"frames to threshold: from where the trailing mean of {THRESHOLD_WINDOW} "
            "evaluations stays at or above it (seeds reaching it / finished). AUC: mean "
            "return over the budget.",
        )
        table.add_column("method", no_wrap=True)
        table.add_column("at frame 0", justify="right")
        table.add_column("final", justify="right")
        table.add_column("frames to threshold", justify="right")
        table.add_column("AUC", justify="right")
        table.add_column("seeds ok / failed", justify="right")
        for row in rows.itertuples():
            name = escape(row.method + (f" [{row.variant}]" if row.variant else ""))
            if row.reached:
                steps = f"{_pm(row.steps_mean, row.steps_std, 0)} ({row.reached}/{row.seeds_ok})"
            else:
                steps = f"not reached (0/{row.seeds_ok})"
            failed = f"[red]{row.seeds_failed}[/]" if row.seeds_failed else "0"
            table.add_row(name, _pm(row.initial_mean, row.initial_std),
                          _pm(row.final_mean, row.final_std), steps,
                          _pm(row.auc_mean, row.auc_std), f"{row.seeds_ok} / {failed}")
        console.print(table)
