"""Console views of what the analysis computed: the report, a comparison, a suite's status,
a study's trials. Each takes a table and prints it; none computes a number."""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from senbench.analysis.compare import LABELS, Side, compare
from senbench.analysis.metrics import FINAL_WINDOW, THRESHOLD_WINDOW
from senbench.analysis.summary import label
from senbench.run.status import Combination
from senbench.tune.study import trial_counts


def _pm(mean: float, std: float, digits: int = 1) -> str:
    if np.isnan(mean):
        return "—"
    return f"{mean:,.{digits}f} ± {std:,.{digits}f}"


def _cell(row, prefix: str, digits: int = 1) -> str:
    """Three lines: the IQM, its interval, mean ± std."""
    value, low, high = (getattr(row, f"{prefix}_{k}") for k in ("iqm", "low", "high"))
    if np.isnan(value):
        return "—"
    interval = "[—]" if np.isnan(low) else f"[{low:,.{digits}f}, {high:,.{digits}f}]"
    spread = _pm(getattr(row, f"{prefix}_mean"), getattr(row, f"{prefix}_std"), digits)
    return f"{value:,.{digits}f}\n{interval}\n{spread}"


def show_report(summary: pd.DataFrame, console: Console) -> None:
    several = summary["suite"].nunique() > 1
    for (suite, env), rows in summary.groupby(["suite", "env"], sort=True):
        where = f"{suite} / {env}" if several else env
        charged = bool(rows["labelled_frames"].any())
        controls = bool(rows["control"].astype(bool).any())
        budgets = sorted(rows["budget"].unique())
        table = Table(
            title=f"{where}: evaluation return; threshold {rows['threshold'].iloc[0]:g}, "
            f"budget {' or '.join(f'{b:,}' for b in budgets)} frames",
            caption="each metric: IQM, its [95% stratified bootstrap CI], mean ± std, over "
            f"finished seeds. final: mean of the last {FINAL_WINDOW} evaluations. frames to "
            f"threshold: from where the trailing mean of {THRESHOLD_WINDOW} evaluations "
            "stays at or above it; a seed that never gets there counts as the budget "
            "(seeds reaching it / finished). AUC: mean return over the budget."
            + (" labelled: the labelled frames an encoded method's encoder was trained on "
               "before its first online frame, and how they were obtained; charged: frames "
               "to threshold + labelled frames." if charged else "")
            + (" reference: the published final return of a positive control; it fails when "
               "the interval of our final return lies wholly below it." if controls else ""),
        )
        table.add_column("method", no_wrap=True)
        table.add_column("at frame 0", justify="right")
        table.add_column("final", justify="right")
        table.add_column("frames to threshold", justify="right")
        table.add_column("AUC", justify="right")
        if charged:
            table.add_column("labelled", justify="right")
            table.add_column("charged", justify="right")
        if controls:
            table.add_column("reference", justify="right")
        table.add_column("seeds ok / failed", justify="right")
        for row in rows.itertuples():
            name = escape(label(row.method, row.variant)
                          + (f" @ {row.budget:,} frames" if len(budgets) > 1 else ""))
            if row.reached:
                steps = f"{_cell(row, 'steps', 0)}\n({row.reached}/{row.seeds_ok} reached)"
            else:
                steps = f"not reached (0/{row.seeds_ok})"
            failed = f"[red]{row.seeds_failed}[/]" if row.seeds_failed else "0"
            extra = []
            if charged:
                extra += [f"{row.labelled_frames:,}\n{escape(row.labelled_by)}"
                          if row.labelled_frames else "0",
                          _cell(row, "charged", 0) if row.reached else "—"]
            if controls:
                extra.append(_reference(row))
            table.add_row(name, _pm(row.initial_mean, row.initial_std),
                          _cell(row, "final"), steps, _cell(row, "auc"), *extra,
                          f"{row.seeds_ok} / {failed}")
        console.print(table)


def _reference(row) -> str:
    if not row.control:
        return ""
    colour = {"pass": "green", "fail": "red"}.get(row.control, "yellow")
    return (f"{row.reference:,.1f} ± {row.reference_spread:,.1f}\n"
            f"[{colour}]{row.control}[/]\n{escape(row.reference_source)}")


def show_returns_at(table: pd.DataFrame, console: Console) -> None:
    """``returns_at``'s table: a row per method, a column per frame."""
    several = table["suite"].nunique() > 1
    for (suite, env), rows in table.groupby(["suite", "env"], sort=True):
        frames = sorted(rows["frame"].unique())
        where = f"{suite} / {env}" if several else env
        out = Table(title=f"{where}: evaluation return at frames",
                    caption="evaluation return at each frame (a seed's last evaluation at or "
                    "before it): mean ± std over finished seeds; (n) when only n seeds had one")
        out.add_column("method", no_wrap=True)
        for frame in frames:
            out.add_column(f"{frame:,}", justify="right")
        seeds = rows.groupby(["method", "variant"])["seeds"].max()
        for (method, variant), by_method in rows.groupby(["method", "variant"], sort=True):
            cells = []
            for frame in frames:
                row = by_method[by_method["frame"] == frame].iloc[0]
                text = _pm(row["mean"], row["std"])
                if 0 < row["seeds"] < seeds[(method, variant)]:
                    text += f" ({row['seeds']})"
                cells.append(text)
            out.add_row(escape(label(method, variant)), *cells)
        console.print(out)


def _value(value: float, ci: tuple[float, float], digits: int) -> str:
    interval = "" if np.isnan(ci[0]) else f" [{ci[0]:,.{digits}f}, {ci[1]:,.{digits}f}]"
    return f"{value:,.{digits}f}{interval}"


def show_comparison(pairs: list[tuple[str, Side, Side]], console: Console) -> None:
    for env, a, b in pairs:
        table = compare(a, b)
        thresholds = sorted(set(a.cells["threshold"]) | set(b.cells["threshold"]))
        out = Table(title=f"{env}: A = {escape(a.name)} ({_seeds(a)}) vs "
                          f"B = {escape(b.name)} ({_seeds(b)}); threshold "
                          f"{' / '.join(f'{t:g}' for t in thresholds)}",
                    caption="IQM [95% bootstrap CI] over seeds. P(A better): the chance that "
                    "a run of A does better than a run of B (higher return or AUC, fewer "
                    "frames to threshold; ties count half), with its 95% bootstrap CI. With "
                    "labelled frames charged, a seed that never reached the threshold needs at "
                    "least its budget plus them: pairs whose order that hides count half.")
        out.add_column("metric")
        out.add_column("A", justify="right")
        out.add_column("B", justify="right")
        out.add_column("P(A better)", justify="right")
        for row in table.itertuples():
            digits = 0 if row.metric == "steps" else 1
            p = f"{row.p_better:.2f}" + ("" if np.isnan(row.p_low)
                                         else f" [{row.p_low:.2f}, {row.p_high:.2f}]")
            out.add_row(LABELS[row.metric], _value(row.a_iqm, row.a_ci, digits),
                        _value(row.b_iqm, row.b_ci, digits), p)
        console.print(out)


def duration(seconds: float) -> str:
    if seconds < 59.5:
        return f"{seconds:.0f} s"
    minutes = round(seconds / 60)
    return f"{minutes // 60} h {minutes % 60:02d} min" if minutes >= 60 else f"{minutes} min"


def show_status(combos: list[Combination], title: str, workers: int, console: Console) -> None:
    """The table of ``combos`` and a line with the cells and the cell time left."""
    table = Table(title=title)
    for name in ("env", "method", "cells", "finished", "failed", "to run", "running",
                 "mean cell", "cell time left"):
        table.add_column(name, justify="left" if name in ("env", "method") else "right")
    for c in combos:
        mean, left = c.mean_wall_s, c.left_s
        table.add_row(escape(c.env), escape(label(c.method, c.variant)),
                      str(c.cells), str(c.ok), str(c.failed) if c.failed else "",
                      str(c.to_run) if c.to_run else "", str(c.running) if c.running else "",
                      "" if mean is None else duration(mean),
                      "?" if left is None else ("" if not left else duration(left)))
    console.print(table)
    known = sum(c.left_s for c in combos if c.left_s is not None)
    unknown = sum(c.to_run for c in combos if c.left_s is None)
    finished = sum(c.ok for c in combos)
    total = sum(c.cells for c in combos)
    line = f"{finished} of {total} cells finished"
    if finished < total:
        if known or not unknown:
            line += f"; cell time left ≈ {duration(known)}"
            if workers > 1:
                line += f" (≈ {duration(known / workers)} on {workers} workers)"
            if unknown:
                line += f", plus {unknown} cells"
        else:
            line += f"; {unknown} cells left"
        if unknown:
            line += " of methods with none finished yet (their time is not known)"
        line += ". Running cells count as to run"
    console.print(line + ".")


def trials_table(study: Any, name: str, objective: str, top: int = 5) -> Any:
    """The study's ``top`` finished trials, best first, with their hyperparameters, as a rich
    Table titled with the trial counts; None while no trial has finished."""
    import optuna

    complete = [t for t in study.trials if t.state == optuna.trial.TrialState.COMPLETE]
    if not complete:
        return None
    reverse = study.direction == optuna.study.StudyDirection.MAXIMIZE
    best = sorted(complete, key=lambda t: t.value, reverse=reverse)[:top]
    table = Table(title=f"study '{name}': best trials by {objective}; "
                        + ", ".join(f"{n} {k}" for k, n in trial_counts(study).items()))
    table.add_column("trial", justify="right")
    table.add_column(objective, justify="right")
    for key in best[0].params:
        table.add_column(key, justify="right")
    for t in best:
        table.add_row(str(t.number), f"{t.value:,.2f}",
                      *(f"{t.params[k]:.4g}" if isinstance(t.params[k], float)
                        else str(t.params[k]) for k in best[0].params))
    return table


def budget_table(studies: list[tuple[str, Any, Any]], seeds: int) -> Any:
    """What each study of one ``senbench tune`` spent, side by side: the same trials, seeds
    and frames per trial for every method is an equal tuning budget. ``studies``: (name,
    study, target)."""
    from senbench.tune.study import trial_counts

    table = Table(title="tuning budget", caption=f"frames: over every trial of the study, "
                  f"pruned ones up to where they stopped; cap: trials x {seeds} seeds x the "
                  "budget. Labelled frames an encoder trains on are not online frames: "
                  "the report charges them")
    for column in ("study", "method", "env", "finished", "pruned", "failed", "frames",
                   "cap"):
        table.add_column(column, justify="left" if column in ("study", "method", "env")
                         else "right")
    for name, study, tgt in studies:
        counts = trial_counts(study)
        frames = sum(int(t.user_attrs.get("frames", 0)) for t in study.trials)
        cap = len(study.trials) * seeds * tgt.template.budget
        table.add_row(escape(name), escape(tgt.method), escape(tgt.env),
                      str(counts["complete"]), str(counts["pruned"]), str(counts["fail"]),
                      f"{frames:,}", f"{cap:,}")
    return table


def show_actions(table: pd.DataFrame, console: Console) -> None:
    """``actions_at``'s table: per method, what its evaluated policy did."""
    several = table["suite"].nunique() > 1
    for (suite, env), rows in table.groupby(["suite", "env"], sort=True):
        where = f"{suite} / {env}" if several else env
        out = Table(title=f"{where}: actions in evaluation episodes",
                    caption="mean over finished seeds of each seed's evaluation at that frame "
                    "(its last at or before it; 'last': its final evaluation): the share of "
                    "each discrete action, or each action dimension's mean ± std")
        out.add_column("method", no_wrap=True)
        out.add_column("frame", justify="right")
        out.add_column("seeds", justify="right")
        out.add_column("actions")
        for row in rows.itertuples():
            frame = "last" if pd.isna(row.frame) else f"{int(row.frame):,}"
            if row.action_share is not None:
                text = "  ".join(f"{i}: {share:.0%}" for i, share in enumerate(row.action_share))
            elif row.action_mean is not None:
                text = "  ".join(f"{m:+.2f} ± {s:.2f}" for m, s in zip(
                    row.action_mean, row.action_std, strict=True))
            else:
                text = "not recorded (results from before action recording)"
            out.add_row(escape(label(row.method, row.variant)), frame, str(row.seeds), text)
        console.print(out)


def _seeds(side) -> str:
    """A side's seeds as the comparison counts them, and its failed ones left out."""
    failed = f", {side.failed} failed and left out" if side.failed else ""
    return f"{len(side.cells)} seeds{failed}"
