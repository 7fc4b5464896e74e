"""A study's search space as Optuna sees it: each trial draws its parameters here, and a
study resumed over another space is refused, since its trials would not be comparable."""

from __future__ import annotations

from typing import Any

from senbench.errors import SuiteError
from senbench.plugin.specs import Choice, Float, Int, Param


def suggest(trial: Any, space: dict[str, Param]) -> dict[str, Any]:
    params: dict[str, Any] = {}
    for name, param in space.items():
        if isinstance(param, Float):
            params[name] = trial.suggest_float(name, param.low, param.high, log=param.log)
        elif isinstance(param, Int):
            params[name] = trial.suggest_int(name, param.low, param.high, log=param.log)
        elif isinstance(param, Choice):
            params[name] = trial.suggest_categorical(name, list(param.values))
        else:
            raise TypeError(f"{name}: not a Float, Int or Choice: {param!r}")
    return params


def distributions(space: dict[str, Param]) -> dict[str, Any]:
    """The Optuna distribution :func:`suggest` draws each parameter from."""
    import optuna.distributions as dist

    out: dict[str, Any] = {}
    for name, param in space.items():
        if isinstance(param, Float):
            out[name] = dist.FloatDistribution(param.low, param.high, log=param.log)
        elif isinstance(param, Int):
            out[name] = dist.IntDistribution(param.low, param.high, log=param.log)
        else:
            out[name] = dist.CategoricalDistribution(list(param.values))
    return out


def check_same_space(study: Any, space: dict[str, Param], study_name: str) -> None:
    """Refuse to resume a study whose finished trials drew from another space (an agent's
    ``search_space`` or the suite's ``tune:`` block changed since): TPE would model the old
    trials as if drawn from the new space, and the best trial would be chosen among
    trials that could not have met. A new space is a new study (``--study NAME``)."""
    import optuna

    done = (optuna.trial.TrialState.COMPLETE, optuna.trial.TrialState.PRUNED)
    wanted = distributions(space)
    for trial in study.get_trials(deepcopy=False, states=done):
        if not trial.distributions or trial.distributions == wanted:
            continue  # a trial pruned before it drew anything says nothing of its space
        had = trial.distributions
        changed = sorted(name for name in set(had) | set(wanted)
                         if had.get(name) != wanted.get(name))
        details = "; ".join(f"{name}: {_show(had.get(name))} -> {_show(wanted.get(name))}"
                            for name in changed)
        raise SuiteError(f"study '{study_name}': its trial {trial.number} was drawn from "
                         f"another search space ({details}); tune this space as a new "
                         "study with --study NAME, or restore the old space")


def _show(distribution: Any) -> str:
    if distribution is None:
        return "absent"
    if hasattr(distribution, "choices"):
        return str(list(distribution.choices))
    log = ", log" if getattr(distribution, "log", False) else ""
    return f"[{distribution.low}, {distribution.high}{log}]"
