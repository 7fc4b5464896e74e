"""Running one cell: build its observation pipeline and agent, learn, evaluate.

A cell that raises is recorded as ``failed`` with its error text and the rows it had; a
KeyboardInterrupt is not caught, so an interrupted cell writes nothing.
"""

from __future__ import annotations

import json
import os
import platform
import random
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from datetime import UTC, datetime
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Any

import numpy as np

from senbench.encoders import load_or_train
from senbench.errors import SenbenchError
from senbench.observe.observations import make_env
from senbench.plugin.manager import registries
from senbench.plugin.specs import AgentContext
from senbench.results.store import cell_path, cell_row, last_eval_return, write_cell
from senbench.run.evaluation import CellRecorder, DecisionRecorder, Evaluator
from senbench.run.provenance import cpu_description, git_commit
from senbench.suite.cell import Cell

ProgressCallback = Callable[[str, int, float, float | None, int | None, float | None],
                            None]
"""(cell id, frames so far, frames/s, last evaluation return, the frame it was taken at,
the mean return of the training episodes so far)."""


@dataclass(frozen=True)
class RunInfo:
    """What is the same for every cell of one run, gathered once."""

    versions: dict[str, str]
    git_commit: str | None
    host: str
    encoder_cache: Path = Path("results") / "encoders"
    """Where trained state encoders are kept, shared by every suite under one results root."""

    @classmethod
    def gather(cls, encoder_cache: Path = Path("results") / "encoders") -> RunInfo:
        def ver(dist: str) -> str:
            try:
                return version(dist)
            except PackageNotFoundError:
                return ""

        dists = {"senbench": "senbench", "torch": "torch", "gymnasium": "gymnasium",
                 "sb3": "stable-baselines3", "numpy": "numpy"}
        return cls({k: ver(d) for k, d in dists.items()},
                   git_commit(Path(encoder_cache).parent), platform.node(),
                   Path(encoder_cache))


def failure_text(exc: BaseException) -> str:
    """What a cell's result records of why it failed: a senbench error's message, which says
    what to change; else the end of the traceback, which names the plugin's file and line."""
    if isinstance(exc, SenbenchError):
        return f"{type(exc).__name__}: {exc}"
    return "".join(traceback.format_exception(exc)[-12:]).strip()


@dataclass(frozen=True)
class CellOutcome:
    cell_id: str
    label: str
    status: str
    error: str | None
    final_eval: float | None
    wall_s: float


def agent_context(cell: Cell, encoder: Any = None) -> AgentContext:
    """What the cell's agent is built from: its resolved config, env, a maker of envs with
    the cell's observation pipeline (``encoder``: the trained state encoder of an
    ``encoded`` cell), seed, threads and precision. A benchmark or test that builds a
    cell's agent outside a run builds it from this too, so it is the agent a run builds."""
    regs = registries()
    env_spec = regs.envs.get(cell.env)

    def make() -> Any:
        return make_env(env_spec, cell.observation, cell.max_episode_steps, cell.env_options,
                        cell.pixels, encoder, cell.action_repeat)

    return AgentContext(regs.agents.get(cell.agent).config(**cell.hyperparams), env_spec,
                        make, cell.seed, cell.threads, cell.precision, cell.memory_format)


def execute_cell(cell: Cell, info: RunInfo, progress: ProgressCallback | None = None,
                 encoder: Any = None, stop_at: int | None = None
                 ) -> tuple[list[dict[str, Any]], CellOutcome]:
    """Run a cell: its result rows, and its outcome. Nothing is written here, so a cell can
    run where the results are not (a Ray worker) and the caller writes them.

    ``encoder``: a state encoder the seeds of a batch share (senbench.run.batch), the cell
    running in a thread beside them: the process-wide generators are then left unseeded (a
    batching agent draws from none) and the peak memory is the batch's (reset once, by
    the batch).

    ``stop_at``: stop after this many frames, the cell's schedules still spanning its
    budget, so the rows are the first part of the cell's curve (``senbench verify``)."""
    started = datetime.now(UTC)
    alone = encoder is None
    if alone:
        reset_peak_rss()
    recorder: CellRecorder | None = None
    status, error = "ok", None
    try:
        request = cell.encoder_request()
        if alone and request is not None:
            encoder = load_or_train(info.encoder_cache, request,
                                    registries()).laid_out(cell.memory_format)
        if alone:
            seed_everything(cell.seed)
        ctx = agent_context(cell, encoder)
        agent = registries().agents.get(cell.agent).make(ctx)
        evaluator = Evaluator(ctx.make_env(), cell.eval_episodes, cell.seed, cell.eval_epsilon)
        report = None if progress is None else (lambda *a: progress(cell.id, *a))
        recorder = CellRecorder(cell.budget, cell.eval_every,
                                lambda: evaluator(agent.act), report, stop_at)
        # with an action repeat of k the agent counts its decisions, k frames each
        agent.learn(cell.budget // cell.action_repeat,
                    recorder if cell.action_repeat == 1
                    else DecisionRecorder(recorder, cell.action_repeat))
        wanted = min(cell.budget, stop_at or cell.budget)
        if recorder.steps < wanted:
            raise RuntimeError(f"agent '{cell.agent}' stopped after {recorder.steps} of "
                               f"{wanted} frames")
    except KeyboardInterrupt:
        raise  # an interrupted cell writes nothing
    except BaseException as exc:  # a cell's failure, even sys.exit, must not stop the grid
        status = "failed"
        error = failure_text(exc)
    ended = datetime.now(UTC)
    wall = (ended - started).total_seconds()
    rows = list(recorder.rows) if recorder else []
    steps = recorder.steps if recorder else 0
    rows.append({"kind": "cell", "step": steps, "return": None, "return_std": None,
                 "length": None, "wall_s": wall})
    common = cell_metadata(cell, info, status, error, started, ended, wall)
    final = recorder.last_eval if recorder else None
    return ([{**common, **row} for row in rows],
            CellOutcome(cell.id, cell.label, status, error, final, wall))


def cell_metadata(cell: Cell, info: RunInfo, status: str, error: str | None,
                  started: datetime, ended: datetime, wall: float) -> dict[str, Any]:
    request = cell.encoder_request()
    return {
        "cell_id": cell.id, "suite": cell.suite, "env": cell.env, "method": cell.method,
        "variant": cell.variant, "agent": cell.agent, "observation": cell.observation,
        "seed": cell.seed, "threshold": cell.threshold, "budget": cell.budget,
        "status": status, "error": error, "config": json.dumps(cell.config(), sort_keys=True),
        "hyperparams_source": cell.hyperparams_source,
        "encoder_id": None if request is None else request.id,
        **{f"{k}_version": v for k, v in info.versions.items()},
        "git_commit": info.git_commit, "host": info.host, "threads": cell.threads,
        "seed_batch": cell.seed_batch,
        "cpu": cpu_description(),  # where the cell runs (a Ray node may differ)
        "started_at": started, "ended_at": ended, "cell_wall_s": wall,
        "peak_rss_mb": _peak_rss_mb(),
    }


def seed_everything(seed: int) -> None:
    """Seed the process-wide generators (random, NumPy, torch) as a cell run alone is
    seeded, so a benchmark that builds a cell's agent with `agent_context` replays it."""
    random.seed(seed)
    np.random.seed(seed)
    try:
        import torch
    except ImportError:
        return
    torch.manual_seed(seed)


def reset_peak_rss() -> None:
    """Linux lets a process reset its high-water mark, so the peak is per cell even when a
    worker process runs many cells."""
    try:
        with open(f"/proc/{os.getpid()}/clear_refs", "w") as handle:
            handle.write("5")
    except OSError:
        pass


def _peak_rss_mb() -> float:
    try:
        with open(f"/proc/{os.getpid()}/status") as handle:
            for line in handle:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024
    except OSError:
        pass
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def record_lost_cell(cell: Cell, directory: Path, info: RunInfo, how: str,
                     since: datetime | None = None) -> CellOutcome:
    """A cell that ended without telling its outcome (its process died, or writing its
    result failed): record it as failed, with no curve — unless its file holds a finished
    result started since ``since`` (when its process started): the process died between
    writing it and telling, and its outcome is read from it. An older file (an earlier
    run's, under --force) is replaced, as a rerun that raises replaces it."""
    row = cell_row(cell_path(directory, cell.id), ["status", "started_at", "cell_wall_s"])
    if (row is not None and row["status"] == "ok" and since is not None
            and row["started_at"] >= since):
        return CellOutcome(cell.id, cell.label, "ok", None,
                           last_eval_return(cell_path(directory, cell.id)), row["cell_wall_s"])
    rows, outcome = lost_cell(cell, info, how)
    write_cell(directory, cell.id, rows)
    return outcome


def lost_cell(cell: Cell, info: RunInfo, how: str) -> tuple[list[dict[str, Any]], CellOutcome]:
    """The rows and outcome of a cell that ended without a result of its own."""
    error = f"the process running this cell {how}"
    now = datetime.now(UTC)
    row = {"kind": "cell", "step": 0, "return": None, "return_std": None, "length": None,
           "wall_s": 0.0}
    meta = cell_metadata(cell, info, "failed", error, now, now, 0.0)
    return ([{**meta, **row, "peak_rss_mb": None}],
            CellOutcome(cell.id, cell.label, "failed", error, None, 0.0))
