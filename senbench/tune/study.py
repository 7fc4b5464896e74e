"""``senbench tune``: an Optuna study over one method of a suite.

A trial is the method on one env with hyperparameters drawn from its agent's declared
``search_space`` (minus whatever the suite fixes in the method's ``hyperparams``), run over
K seeds at once, one process each, exactly as ``senbench run`` runs cells. As the seeds
evaluate, the seed mean of the objective's running value at each evaluation frame goes to
the pruner (``PruningProgress``), which can stop the trial there (its cells are killed).
The objective, once every seed has finished, is the mean over seeds of the chosen metric:
AUC, final return, frames to threshold (a seed that never reaches it counts as the budget),
or the mean return of the training episodes.

Tuning seeds are 1,000,000 + i, apart from any suite's own seeds, so that a method is not
tuned on the seeds it is then reported on; a method's state encoder is trained on encoder
seed 1,000,000 in every trial, apart from the encoder its reports use.

The study lives in Optuna storage: by default a SQLite file, ``results/<suite>/tune.db``.
Running the command again resumes the study (``--trials`` is the total to reach, counting
finished and pruned trials), and several processes on one storage share it. On an RDB
storage (SQLite included) each running trial sends a heartbeat; a trial whose process was
killed is marked failed by the next process that starts, instead of staying RUNNING. A trial
stopped by Ctrl-C (or SIGTERM, which ``senbench tune`` turns into one) is marked failed at
once.
"""

from __future__ import annotations

import copy
import dataclasses
import os
import platform
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from senbench.errors import SuiteError
from senbench.plugin.specs import Choice, Float, Int, Param, narrow  # noqa: F401 - re-exported
from senbench.results.store import remove_stray_temp_files
from senbench.run.execute import RunInfo
from senbench.run.processes import run_processes
from senbench.run.progress import NullProgress
from senbench.run.runner import prepare_encoders
from senbench.run.summary import RunSummary
from senbench.suite import Cell, Suite
from senbench.tune.optuna_parts import (  # noqa: F401 - re-exported
    fits,
    make_pruner,
    make_sampler,
    sqlite_lock,
    storage_for,
    trial_counts,
    trial_seconds,
)
from senbench.tune.space import check_same_space, suggest
from senbench.tune.trial import PruningProgress, objective_value  # noqa: F401 - re-exported

TUNE_SEED_OFFSET = 1_000_000
ENCODER = "encoder."
"""Prefix of the encoder architecture's parameters in a study."""
OBJECTIVES = {"auc": "maximize", "final": "maximize", "steps-to-threshold": "minimize",
              "train-return": "maximize"}
"""train-return: the mean return of the trial's training episodes, exploration included. It
has signal where every evaluation of a short trial scores the same (a greedy pixel DQN on
MountainCar plays one action from the start states and scores -1,000 for 100k frames and
more while its training episodes reach the flag: REPRODUCTION.md, Positive controls)."""


def check_objective(objective: str) -> None:
    if objective not in OBJECTIVES:
        raise SuiteError(f"--objective must be one of {', '.join(OBJECTIVES)}, got {objective!r}")


@dataclass(frozen=True)
class Target:
    """What a study tunes: one method of a suite on one env, with a cell to copy."""

    suite: Suite
    method: str
    env: str
    template: Cell
    space: dict[str, Param]
    fixed: dict[str, Any]
    agent_config: Any
    """The template's agent config: every setting's own value, including those a cell's
    hyperparams leave out at their defaults (an agent's ``LATE_FIELDS``)."""


def target(suite: Suite, method: str, env: str | None, regs: Any) -> Target:
    cells = suite.select(methods=[method])
    envs = sorted({c.env for c in cells})
    if env is None:
        if len(envs) > 1:
            raise SuiteError(f"method '{method}' runs on {', '.join(envs)}: pick one with --env")
        env = envs[0]
    cells = [c for c in cells if c.env == env]
    if not cells:
        raise SuiteError(f"method '{method}' does not run on env '{env}'; it runs on "
                         f"{', '.join(envs)}")
    if any(c.variant for c in cells):
        raise SuiteError(f"method '{method}' has variants; tune a method without variants "
                         "(copy it under another name with the values fixed)")
    template = cells[0]
    agent = regs.agents.get(template.agent)
    entry = suite.model.methods[method]
    fixed = dict(entry.hyperparams)
    space = {name: param for name, param in agent.search_space.items() if name not in fixed}
    if entry.encoder is not None:  # the encoder's own settings, unless the suite sets them
        arch = regs.encoders.get(entry.encoder.arch)
        space.update({f"{ENCODER}{name}": param for name, param in arch.search_space.items()
                      if name not in entry.encoder.config})
    # the tune: block, which load_suite has checked (suite.resolve.check_tune)
    for name, narrower in suite.model.tune.get(method, {}).items():
        space[name] = narrow(space[name], narrower.low, narrower.high, narrower.values)
    if not space:
        raise SuiteError(f"agent '{agent.name}' declares no search space"
                         + (" left once the suite's hyperparams are fixed" if fixed else ""))
    return Target(suite, method, env, template, space, fixed,
                  agent.config(**template.hyperparams))


def tune_targets(suite: Suite, methods: list[str] | None, env: str | None, regs: Any, *,
                 named_study: bool, export: bool) -> list[Target]:
    """Every (method, env) a ``senbench tune`` studies: the methods named (default: all of
    the suite's), each on ``env`` or on every env it runs on; all checked before any runs."""
    names = methods or list(suite.model.methods)
    unknown = [m for m in names if m not in suite.model.methods]
    if unknown:
        raise SuiteError(f"--method {', '.join(unknown)}: not a method of suite "
                         f"'{suite.name}' ({', '.join(suite.model.methods)})")
    pairs = []
    for method in dict.fromkeys(names):
        envs = sorted({c.env for c in suite.select(methods=[method])})
        if env is not None and env not in envs and methods is None:
            continue  # every method: those that run on the env
        for one in ([env] if env is not None else envs):
            pairs.append((method, one))
    if not pairs:
        raise SuiteError(f"no method of suite '{suite.name}' runs on env '{env}'")
    if named_study and len(pairs) > 1:
        raise SuiteError(f"--study names one study, but this tunes {len(pairs)} (method, env) "
                         "pairs: drop --study, or pick one --method and --env")
    several = [m for m in dict.fromkeys(m for m, _ in pairs) if sum(x == m for x, _ in pairs) > 1]
    if export and several:
        raise SuiteError(f"--export writes one block per method, but {', '.join(several)} "
                         "runs on several envs: pick one with --env")
    return [target(suite, method, one, regs) for method, one in pairs]


def own_setting(tgt: Target, name: str) -> Any:
    """The method's own value of a searched setting: its agent config's, or its encoder
    config's for an ``encoder.`` name."""
    return (tgt.template.encoder["config"][name.removeprefix(ENCODER)]
            if name.startswith(ENCODER) else getattr(tgt.agent_config, name))


def default_params(tgt: Target) -> tuple[dict[str, Any], list[str]]:
    """The method's own settings (its agent's defaults for the env and observation, the
    suite's hyperparams, its encoder's config) as a trial's parameters, numbers clipped into
    the searched range (PPO's ent_coef 0.0 into [1e-8, 0.1]); and the choices whose setting
    is not among the searched values, which leave the defaults out of the study."""
    params, outside = {}, []
    for name, param in tgt.space.items():
        value = own_setting(tgt, name)
        if isinstance(param, Choice):
            if value in param.values:
                params[name] = value
            else:
                outside.append(f"{name} {value!r} not among {list(param.values)}")
        else:
            params[name] = type(param.low)(min(max(value, param.low), param.high))
    return params, outside


def moved_defaults(tgt: Target) -> list[str]:
    """The defaults that :func:`default_params` had to move into the searched range, other
    than a 0.0 on a log-scaled range (whose low end is as near 0 as it can get): where
    there are none, the defaults trial ran the method's own settings."""
    params, _ = default_params(tgt)
    moved = []
    for name, value in params.items():
        own = own_setting(tgt, name)
        if value != own and not (own == 0 and getattr(tgt.space[name], "log", False)):
            moved.append(f"{name} {own!r} -> {value!r}")
    return moved


def enqueue_defaults(study: Any, tgt: Target, log: Any) -> None:
    """A study runs the method's own settings as a trial, first, so that its best trial is
    never worse than the defaults on the tuning seeds (rl-baselines3-zoo's studies do not
    do this; a tuned rival that lost to its own defaults would prove nothing). A defaults
    trial that failed (its process killed: marked failed here first) is queued again; a
    study that holds finished trials but never ran the defaults gets them next."""
    import optuna

    with warnings.catch_warnings():  # experimental in Optuna; a no-op without heartbeats
        warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
        optuna.storages.fail_stale_trials(study)  # a killed defaults trial is not running
    states = optuna.trial.TrialState
    live = (states.COMPLETE, states.PRUNED, states.RUNNING, states.WAITING)
    if any(t.user_attrs.get("defaults") and t.state in live for t in study.trials):
        return
    params, outside = default_params(tgt)
    if outside:
        log(f"{tgt.method}: its defaults are not a trial of the study ({'; '.join(outside)})")
        return
    study.enqueue_trial(params, user_attrs={"defaults": True})


def trial_cells(tgt: Target, params: dict[str, Any], seeds: int, regs: Any) -> list[Cell]:
    """The K cells of a trial: the template's config with the trial's hyperparameters, on
    the tuning seeds. Hyperparameters the agent refuses (its own range checks, e.g. a
    batch larger than a rollout) raise ValueError."""
    agent = regs.agents.get(tgt.template.agent)
    encoder_params = {k[len(ENCODER):]: v for k, v in params.items() if k.startswith(ENCODER)}
    hyperparams = {**tgt.template.hyperparams,
                   **{k: v for k, v in params.items() if not k.startswith(ENCODER)}}
    resolved = agent.config(**hyperparams)  # raises on a bad combination
    hyperparams = {k: getattr(resolved, k) for k in hyperparams}
    encoder = copy.deepcopy(tgt.template.encoder)
    if encoder is not None:  # its labelled frames and weights drawn apart from the reported
        encoder["seed"] = TUNE_SEED_OFFSET
    if encoder_params:
        arch = regs.encoders.get(encoder["arch"])
        encoder["config"] = dataclasses.asdict(arch.config(**{**encoder["config"],
                                                              **encoder_params}))
    return [tgt.template.replace(hyperparams=dict(hyperparams), encoder=copy.deepcopy(encoder),
                                 seed=TUNE_SEED_OFFSET + i) for i in range(seeds)]


def run_study(tgt: Target, *, trials: int, seeds: int, objective: str, storage: Any,
              study_name: str, sampler: str, seed: int | None, pruner: Any,
              results_root: Path, workers: int, regs: Any, log: Any,
              deadline: float | None = None) -> Any:
    """The study, run until it holds ``trials`` finished or pruned trials, or until the
    next trial is not expected to end before ``deadline`` (``--time-limit``). ``sampler``
    and ``seed``: :func:`make_sampler`'s, seeded after the trials the study holds."""
    import optuna

    check_objective(objective)
    optuna.logging.set_verbosity(optuna.logging.WARNING)  # senbench logs each trial itself
    study = optuna.create_study(study_name=study_name, storage=storage, pruner=pruner,
                                direction=OBJECTIVES[objective], load_if_exists=True)
    study.sampler = make_sampler(sampler, seed, held=len(study.trials))
    # What makes its trials comparable, and how to resume it as it ran: another objective,
    # seeds, frames, evaluations, pruner or encoder seed would rank trials that did not have
    # the same budget. (Studies from before these were kept take them from their next run,
    # but trials from before the encoder had a tuning seed ran on the suite's own, 0.)
    budget = {"objective": objective, "seeds": seeds, "frames": tgt.template.budget,
              "eval_every": tgt.template.eval_every,
              "eval_episodes": tgt.template.eval_episodes, "pruner": type(pruner).__name__,
              "encoder_seed": TUNE_SEED_OFFSET if tgt.template.encoder else None}
    how = {"objective": "pass --objective {ran}", "seeds": "pass --seeds {ran}",
           "frames": "give the suite its budget back", "eval_every": "give the suite its "
           "eval back", "eval_episodes": "give the suite its eval back",
           "pruner": "pass the --pruner it ran",
           "encoder_seed": "its encoders were trained on the suite's encoder seed, before "
           "trials had one of their own, so it cannot be resumed"}
    before = {"encoder_seed": 0 if tgt.template.encoder else None} if study.trials else {}
    for key, value in budget.items():
        ran = study.user_attrs.get(key, before.get(key, value))
        if ran != value:
            raise SuiteError(f"study '{study_name}' ran its trials with {key} {ran}, not "
                             f"{value}: {how[key].format(ran=ran)}; or tune the method as "
                             "a new study with --study NAME")
    check_same_space(study, tgt.space, study_name)  # before the study is written to
    for key, value in {"suite": tgt.suite.name, "method": tgt.method, "env": tgt.env,
                       **budget}.items():
        study.set_user_attr(key, value)
    # two processes opening a new study at once would both queue the defaults
    with sqlite_lock(getattr(storage, "url", storage if isinstance(storage, str) else None)):
        enqueue_defaults(study, tgt, log)
    info = RunInfo.gather(results_root / "encoders")
    base = results_root / tgt.suite.name / "tune" / study_name
    counted = (optuna.trial.TrialState.COMPLETE, optuna.trial.TrialState.PRUNED)

    def run_trial(trial: optuna.Trial) -> float:
        try:
            return trial_value(trial)
        except KeyboardInterrupt:  # Ctrl-C, or SIGTERM as senbench tune handles it
            # Optuna marks the trial failed and logs that with the interrupt's traceback;
            # one line says it instead
            optuna.logging.set_verbosity(optuna.logging.ERROR)
            log(f"trial {trial.number}: stopped, marked failed")
            raise

    def trial_value(trial: optuna.Trial) -> float:
        trial.set_user_attr("host", platform.node())
        trial.set_user_attr("pid", os.getpid())
        params = suggest(trial, tgt.space)
        try:
            cells = trial_cells(tgt, params, seeds, regs)
        except ValueError as exc:  # the agent refuses this combination
            trial.set_user_attr("refused", str(exc))
            raise optuna.TrialPruned(f"refused by the agent: {exc}") from None
        directory = base / f"trial-{trial.number}" / "cells"
        directory.mkdir(parents=True, exist_ok=True)
        remove_stray_temp_files(directory)
        summary = RunSummary(total=len(cells))
        cells = prepare_encoders(cells, directory, info, NullProgress(), summary)
        if summary.failed:  # the trial's encoder could not be trained
            raise RuntimeError(f"{summary.failed[0].error}")
        progress = PruningProgress(trial, [c.id for c in cells], log, objective)
        trial.set_user_attr("frames", 0)
        try:
            run_processes(cells, directory, info, min(workers, len(cells)), progress,
                          summary)
            progress.frames = {c.id: c.budget for c in cells}  # ran to the end
        finally:  # the tuning budget spent, pruned or not (senbench tune's budget table)
            trial.set_user_attr("frames", int(sum(progress.frames.values())))
        if summary.failed:
            raise RuntimeError(f"{len(summary.failed)} cells failed: "
                               f"{summary.failed[0].error}")
        value = objective_value(directory.parent, objective, [c.id for c in cells])
        named = " (the defaults)" if trial.user_attrs.get("defaults") else ""
        log(f"trial {trial.number}{named}: {objective} {value:,.1f}")
        return value

    def stop_at_deadline(study: optuna.Study, trial: Any) -> None:
        if not fits(study, deadline):
            study.stop()

    # Optuna counts a failed trial against n_trials, so a failure would leave the study
    # short of --trials: go on until it holds them, at most --trials failures in this run.
    def failed_here() -> int:
        return sum(t.state == optuna.trial.TrialState.FAIL
                   and t.user_attrs.get("pid") == os.getpid() for t in study.trials)

    while True:
        already = len(study.get_trials(deepcopy=False, states=counted))
        if already >= trials or not fits(study, deadline) or failed_here() >= trials:
            return study
        study.optimize(run_trial, n_trials=trials - already, catch=(RuntimeError,),
                       callbacks=[optuna.study.MaxTrialsCallback(trials, states=counted),
                                  stop_at_deadline])
