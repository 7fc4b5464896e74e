"""The Optuna parts a study runs with: its storage (with heartbeats, so that a killed
trial is marked failed), its sampler and pruner, and the clock ``--time-limit`` keeps."""

from __future__ import annotations

import contextlib
import fcntl
import time
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from senbench.errors import SuiteError

HEARTBEAT_S = 30
GRACE_S = 90


def storage_for(url: str | None, default_file: Path) -> Any:
    """An Optuna storage: RDB URLs (SQLite included) with heartbeats, so that a killed
    trial is marked failed rather than left RUNNING; other URLs as Optuna reads them."""
    import optuna

    if url is None:
        default_file.parent.mkdir(parents=True, exist_ok=True)
        url = f"sqlite:///{default_file}"
    scheme = url.split(":", 1)[0].split("+", 1)[0]
    if scheme in {"sqlite", "postgresql", "mysql", "oracle", "mssql"}:
        import sqlalchemy.exc

        warnings.filterwarnings("ignore", category=optuna.exceptions.ExperimentalWarning)
        def create() -> Any:
            return optuna.storages.RDBStorage(
                url, heartbeat_interval=HEARTBEAT_S, grace_period=GRACE_S,
                engine_kwargs={"connect_args": {"timeout": 60}} if scheme == "sqlite" else None)

        if scheme == "sqlite" and url.startswith("sqlite:///"):
            # Two processes creating a new database's tables at once collide: the first
            # creates them under a lock, the second then finds them.
            with sqlite_lock(url):
                return create()
        for attempt in range(10):  # a server database: retry the same collision
            try:
                return create()
            except sqlalchemy.exc.SQLAlchemyError:
                if attempt == 9:
                    raise
                time.sleep(0.2 + 0.3 * attempt)
    return url


@contextlib.contextmanager
def sqlite_lock(url: str | None) -> Iterator[None]:
    """Held by one process at a time per SQLite file (``url``), across processes; a no-op
    for other storages."""
    if not (url or "").startswith("sqlite:///"):
        yield
        return
    with open(Path(url[len("sqlite:///"):] + ".lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        yield


def make_sampler(name: str, seed: int | None, held: int = 0) -> Any:
    """The ``--sampler`` for a study that already holds ``held`` trials, seeded from
    (``seed``, ``held``): a resumed study seeded as its first run was would draw that run's
    random draws again (TPE draws its first 10 trials at random), trials that only repeat
    ones the study holds. Not ``seed + held``, which would give ``--seed 2`` on a new study
    the draws of ``--seed 0`` resumed after 2 trials. The same study state and seed still
    give the same draws."""
    import numpy as np
    import optuna

    if seed is not None:
        seed = int(np.random.SeedSequence([seed, held]).generate_state(1)[0])
    if name == "tpe":
        return optuna.samplers.TPESampler(seed=seed)
    if name == "random":
        return optuna.samplers.RandomSampler(seed=seed)
    raise SuiteError(f"--sampler must be tpe or random, got {name!r}")


def make_pruner(name: str, tgt: Any) -> Any:
    """The ``--pruner`` for a study of ``tgt`` (a study.Target): its eval frames and budget."""
    import optuna

    every = tgt.template.eval_every
    budget = tgt.template.budget
    if name == "median":
        # as rl-baselines3-zoo: no pruning in the first 5 trials nor the first third of a
        # trial, where returns still say little (MountainCar sits at -200 early on)
        return optuna.pruners.MedianPruner(n_startup_trials=5,
                                           n_warmup_steps=max(every, budget // 3))
    if name == "hyperband":
        return optuna.pruners.HyperbandPruner(min_resource=every, max_resource=budget)
    if name == "none":
        return optuna.pruners.NopPruner()
    raise SuiteError(f"--pruner must be median, hyperband or none, got {name!r}")


def trial_seconds(study: Any) -> float | None:
    """Mean wall time of the study's finished (not pruned) trials: what the next may take."""
    import optuna

    spans = [(t.datetime_complete - t.datetime_start).total_seconds()
             for t in study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.COMPLETE,))
             if t.datetime_start and t.datetime_complete]
    return sum(spans) / len(spans) if spans else None


def fits(study: Any, deadline: float | None) -> bool:
    """Whether another trial is expected to end before ``deadline`` (time.monotonic());
    a study with no finished trial yet has no estimate, and starts one."""
    return deadline is None or time.monotonic() + (trial_seconds(study) or 0.0) <= deadline


def trial_counts(study: Any) -> dict[str, int]:
    """How many of the study's trials finished, were pruned, failed or are running."""
    import optuna

    states = optuna.trial.TrialState
    return {s.name.lower(): sum(t.state == s for t in study.trials)
            for s in (states.COMPLETE, states.PRUNED, states.FAIL, states.RUNNING)}


