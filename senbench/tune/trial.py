"""What one trial of a study reports while it runs (``PruningProgress``, to the pruner) and
the value it is ranked by once it has finished (``objective_value``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from senbench.analysis.summary import per_cell
from senbench.results.store import read_results


class PruningProgress:
    """Receives the cells' progress; when every seed has evaluated at a frame, reports the
    seed mean of the objective's running value to the trial and raises TrialPruned if the
    pruner says so. That value runs the objective's way: the evaluation return for auc and
    final, its negative for steps-to-threshold (a study that minimises frames prunes the
    trials whose returns are lower), and the mean return of the training episodes so far
    for train-return (the objective itself at the trial's last frame)."""

    def __init__(self, trial: Any, cell_ids: list[str], log: Any, objective: str = "auc"):
        self.trial = trial
        self.objective = objective
        self.evals: dict[str, dict[int, float]] = {cell_id: {} for cell_id in cell_ids}
        self.frames: dict[str, int] = {}
        """Frames each cell reported last: what a pruned trial spent."""
        self.reported: set[int] = set()
        self._log = log

    def log(self, message: str) -> None:
        self._log(message)

    def warn(self, message: str) -> None:
        self._log(f"warning: {message}")

    def started(self, cell_id: str, label: str, budget: int) -> None:
        pass

    def finished(self, outcome: Any) -> None:
        pass

    def running_value(self, last_eval: float, train_return: float | None) -> float:
        if self.objective == "train-return":
            return np.nan if train_return is None else train_return
        return -last_eval if self.objective == "steps-to-threshold" else last_eval

    def update(self, cell_id: str, steps: int, rate: float, last_eval: float | None,
               eval_step: int | None = None, train_return: float | None = None) -> None:
        import optuna

        self.frames[cell_id] = max(steps, self.frames.get(cell_id, 0))
        if (last_eval is None or eval_step is None or cell_id not in self.evals
                or eval_step in self.evals[cell_id]):  # the value as of its evaluation
            return
        self.evals[cell_id][eval_step] = self.running_value(last_eval, train_return)
        shared = set.intersection(*(set(curve) for curve in self.evals.values()))
        for step in sorted(shared - self.reported):
            self.reported.add(step)
            values = [curve[step] for curve in self.evals.values()]
            if np.isnan(values).all():  # no seed has ended a training episode yet
                continue
            value = float(np.nanmean(values))
            self.trial.report(value, step)
            # the frames spent so far, kept should the process be killed before the end
            self.trial.set_user_attr("frames", int(sum(self.frames.values())))
            if self.trial.should_prune():
                raise optuna.TrialPruned(f"pruned at frame {step:,} (seed mean {value:.1f})")


def objective_value(directory: Path, objective: str, cell_ids: list[str]) -> float:
    """The mean over the trial's seeds (``cell_ids``, each of which must have a result) of
    the objective. Only those cells: a file another trial left in the folder (a study
    name used again after its storage was deleted) must not count."""
    cells = per_cell(read_results(directory))
    cells = cells[cells["cell_id"].isin(cell_ids)]
    if len(cells) != len(set(cell_ids)):
        raise RuntimeError(f"{len(set(cell_ids)) - len(cells)} of the trial's "
                           f"{len(set(cell_ids))} cells have no result; see {directory}")
    failed = cells[cells["status"] != "ok"]
    if len(failed):
        raise RuntimeError(f"{len(failed)} of the trial's cells failed; see {directory}")
    column = {"auc": "auc", "final": "final_return", "steps-to-threshold": "steps_to_threshold",
              "train-return": "train_return"}[objective]
    values = cells[column].to_numpy(dtype=float)
    if np.isnan(values).all():
        raise RuntimeError(f"no seed of the trial has a {objective} (no training episode "
                           f"ended within its frames?); see {directory}")
    return float(np.nanmean(values))
