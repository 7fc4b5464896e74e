"""Running a suite's cells: resume, serial or one process per cell, progress, Ctrl-C.

Resume: a cell whose file records ``ok`` is skipped (``force`` redoes it); a failed cell is
tried again. With ``workers`` > 1 every cell runs in a process of its own, forked from a
server that has imported senbench and torch once: a cell that dies (killed, out of memory,
``os._exit``) is recorded as failed from its exit status and takes nothing else with it.
Cells ignore SIGINT; on Ctrl-C or SIGTERM the runner kills them, so only finished cells
remain; a cell whose runner was SIGKILLed notices and exits.
"""

from __future__ import annotations

import time
from pathlib import Path

from senbench.encoders import load_or_train
from senbench.errors import SenbenchError
from senbench.plugin.manager import registries
from senbench.results.store import (
    cell_path,
    cells_dir,
    finished_status,
    remove_stray_temp_files,
    write_manifest,
)
from senbench.run import ray_executor
from senbench.run.claims import CellClaims, running_cells
from senbench.run.execute import RunInfo, failure_text, record_lost_cell
from senbench.run.processes import run_processes, run_serial, usable_cores
from senbench.run.progress import NullProgress, Progress
from senbench.run.reuse import copy_cell, finished_cells
from senbench.run.schedule import Schedule
from senbench.run.summary import RunSummary
from senbench.suite import Cell, Suite


def pending_cells(cells: list[Cell], directory: Path, force: bool) -> list[Cell]:
    if force:
        return list(cells)
    return [c for c in cells if finished_status(cell_path(directory, c.id)) != "ok"]


EXECUTORS = ("local", "ray")


def run_suite(suite: Suite, results_root: str | Path, workers: int | None = None,
              force: bool = False,
              progress: Progress | None = None, executor: str = "local",
              address: str | None = None, retries: int = 2,
              cells: list[Cell] | None = None, reuse: list[Path] = (),
              time_limit_s: float | None = None) -> RunSummary:
    """Run the cells of ``suite`` not yet finished under ``results_root``; with ``cells``
    (from :meth:`Suite.select`), only those. The manifest names the whole suite all the
    same, so ``report`` shows every finished cell of this version. A cell that one of the
    ``reuse`` folders (other suites' results) holds finished under its id (the same
    computation, whatever its names there) is copied from there instead (see
    :mod:`senbench.run.reuse`).
    With ``time_limit_s``, a cell starts only if it is expected to end within that many
    seconds of the call (see :mod:`senbench.run.schedule`); ``summary.not_started`` counts the
    cells left for a later run. A cell that another run of the suite holds is passed over
    (``summary.elsewhere``), so several runs can share one grid (see :mod:`senbench.run.claims`).

    ``executor="local"``: serially, or ``workers`` processes. ``"ray"``: as Ray tasks, on the
    cluster at ``address`` or on a local instance of ``workers`` CPUs (default: all usable)
    started for the run; a task whose worker dies is retried ``retries`` times (see
    :mod:`senbench.run.ray_executor`)."""
    if executor not in EXECUTORS:
        raise SenbenchError(f"unknown executor {executor!r}: use one of {', '.join(EXECUTORS)}")
    if executor == "ray":
        ray_executor.import_ray()  # before anything is written: a missing extra is a clear error
        if time_limit_s is not None:
            raise SenbenchError("--time-limit works with the local executor; on Ray, give "
                                "the job a scheduler's limit and resume after it")
    started = time.monotonic()
    if force and reuse:
        raise SenbenchError("--force runs finished cells again and --reuse copies them: "
                            "use one of the two")
    directory = cells_dir(results_root, suite.name)
    found = finished_cells(list(reuse), exclude=directory) if reuse else {}  # before writing
    try:
        directory.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise SenbenchError(f"cannot write results under {results_root}: {exc}") from None
    remove_stray_temp_files(directory)
    (directory.parent / "suite.yaml").write_bytes(suite.source.path.read_bytes())
    write_manifest(directory.parent, [c.id for c in suite.cells])
    cells = suite.cells if cells is None else cells
    todo = pending_cells(cells, directory, force)
    summary = RunSummary(total=len(cells), skipped=len(cells) - len(todo))
    progress = progress or NullProgress()
    threads = max((c.threads for c in todo), default=1)
    if executor == "local":
        workers = workers or 1
    if executor == "local" and workers * threads > usable_cores():
        progress.warn(f"{workers} workers × {threads} torch threads per cell > "
                      f"{usable_cores()} cores: cells will compete for them")
    info = RunInfo.gather(Path(results_root) / "encoders")
    if todo and (info.git_commit or "").endswith("-dirty"):
        progress.warn(f"the working tree has uncommitted changes ({info.git_commit}): these "
                      "cells' git_commit will name no code that can compute them again; "
                      "commit first to keep them reproducible (senbench verify checks)")
    claims = CellClaims(directory, force)
    with progress.grid(len(cells), summary.skipped):
        try:
            todo = _copy_reused(todo, directory, info, found, progress, summary, claims)
            todo = prepare_encoders(todo, directory, info, progress, summary)
            left = None if time_limit_s is None else time_limit_s - (time.monotonic() - started)
            if left is not None and left <= 0 and todo:
                progress.warn("the time limit ran out while state encoders were trained; "
                              "they are cached, so the next run starts cells at once")
            if executor == "ray":
                summary.elsewhere = [c.id for c in todo if not claims.take(c.id)]
                passed = set(summary.elsewhere)
                for cell in todo:
                    if cell.id in passed:
                        progress.passed_over(cell.label)
                todo = [c for c in todo if c.id not in passed]
                ray_executor.run_cells(todo, directory, info, progress, summary, address=address,
                          workers=workers, retries=retries, written=claims.release)
            else:
                schedule = Schedule(todo, left, suite, results_root, claims,
                                    lambda cell: progress.passed_over(cell.label))
                if workers <= 1:
                    run_serial(schedule, directory, info, progress, summary)
                else:
                    run_processes(todo, directory, info, workers, progress, summary, schedule)
                summary.not_started = len(schedule.waiting)
                summary.elsewhere = schedule.elsewhere
        except KeyboardInterrupt:
            summary.interrupted = True
        finally:
            claims.release_all()
    running = running_cells(directory) if summary.elsewhere else set()
    for cell_id in summary.elsewhere:
        if cell_id in running:
            summary.elsewhere_running += 1
        elif not claims.finished_elsewhere(cell_id):
            summary.elsewhere_unfinished += 1
    return summary


def _copy_reused(todo: list[Cell], directory: Path, info: RunInfo, found: dict[str, Path],
                 progress: Progress, summary: RunSummary, claims: CellClaims) -> list[Cell]:
    """Copy the cells ``found`` holds (``--reuse``), each under its lock, as a run would
    compute it; the cells still to run (a cell another run holds among them: the schedule
    passes it over)."""
    left, other_code = [], 0
    for cell in todo:
        source = found.get(cell.id)
        copy = None
        if source is not None and claims.take(cell.id):  # held elsewhere: left to schedule
            try:
                copy = copy_cell(cell, source, directory, info.encoder_cache)
            finally:
                claims.release(cell.id)
        if copy is None:
            left.append(cell)
            continue
        summary.reused += 1
        progress.copied(cell.label, copy.source, copy.final_eval)
        if (copy.git_commit, copy.senbench_version) != (info.git_commit,
                                                        info.versions.get("senbench")):
            other_code += 1
    if other_code:
        progress.warn(f"{other_code} copied cells were computed by another senbench commit or "
                      "version (their git_commit column says which): if the agents or the "
                      "evaluation changed since, a run now could give other curves")
    return left


def prepare_encoders(todo: list[Cell], directory: Path, info: RunInfo,
                      progress: Progress, summary: RunSummary) -> list[Cell]:
    """Train each state encoder the cells need once, here, before any cell starts (cells
    then load it), on its spec's ``training.threads``. A cell whose encoder cannot be trained
    fails, with why."""
    needed: dict[str, list[Cell]] = {}
    for cell in todo:
        if (request := cell.encoder_request()) is not None:
            needed.setdefault(request.id, []).append(cell)
    if not needed:
        return todo
    lost: set[str] = set()
    for cells in needed.values():
        try:
            load_or_train(info.encoder_cache, cells[0].encoder_request(), registries(),
                          progress.log)
        except Exception as exc:
            why = failure_text(exc)
            for cell in cells:
                outcome = record_lost_cell(cell, directory, info,
                                           f"could not load or train its encoder: {why}")
                summary.outcomes.append(outcome)
                progress.finished(outcome)
                lost.add(cell.id)
    return [c for c in todo if c.id not in lost]


# --- one process per cell ------------------------------------------------------------------


