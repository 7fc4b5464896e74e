"""Running a suite's cells: resume, serial or one process per cell, progress, Ctrl-C.

Resume: a cell whose file records ``ok`` is skipped (``force`` redoes it); a failed cell is
tried again. With ``workers`` > 1 every cell runs in a process of its own, forked from a
server that has imported senbench and torch once: a cell that dies (killed, out of memory,
``os._exit``) is recorded as failed from its exit status and takes nothing else with it.
Cells ignore SIGINT; on Ctrl-C or SIGTERM the runner kills them, so only finished cells
remain; a cell whose runner was SIGKILLed notices and exits.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import signal
import sys
import threading
import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from importlib.metadata import entry_points
from multiprocessing.connection import wait as connection_wait
from pathlib import Path
from typing import Any

import psutil

from senbench import plugins
from senbench.cell import CellOutcome, RunInfo, record_lost_cell, run_cell
from senbench.claims import CellClaims, running_cells
from senbench.errors import SenbenchError
from senbench.progress import GridProgress
from senbench.results import (
    cell_path,
    cells_dir,
    finished_status,
    remove_stray_temp_files,
    write_manifest,
)
from senbench.reuse import copy_cell, curve_key, finished_cells
from senbench.schedule import Schedule
from senbench.suite import Cell, Suite

EXIT_NOT_DONE = 75
"""sysexits' EX_TEMPFAIL: not done, run again later (a batch job's requeue)."""


@dataclass
class RunSummary:
    total: int
    skipped: int = 0
    outcomes: list[CellOutcome] = field(default_factory=list)
    interrupted: bool = False
    reused: int = 0
    """Cells copied from another suite's results (``reuse``), not run."""
    not_started: int = 0
    """Cells a time limit left for a later run: none was expected to fit in the time left."""
    elsewhere: list[str] = field(default_factory=list)
    """Cells passed over because another run of the suite held them, or wrote their files
    since this run started (see :mod:`senbench.claims`)."""
    elsewhere_running: int = 0
    """Of those, the cells another run still held when this run ended."""
    elsewhere_unfinished: int = 0
    """Of those, the cells neither finished nor held when this run ended: the other run
    failed them or was stopped, so they are left to the next run."""

    @property
    def failed(self) -> list[CellOutcome]:
        return [o for o in self.outcomes if o.status != "ok"]

    @property
    def ok(self) -> int:
        return sum(o.status == "ok" for o in self.outcomes)

    @property
    def exit_code(self) -> int:
        """130 interrupted; 1 a cell failed; 75 cells left for a later run; else 0."""
        if self.interrupted:
            return 130
        if self.failed:
            return 1
        return EXIT_NOT_DONE if self.not_started or self.elsewhere_unfinished else 0


def usable_cores() -> int:
    """Cores this process may run on (its affinity mask: a batch scheduler's share)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def pending_cells(cells: list[Cell], directory: Path, force: bool) -> list[Cell]:
    if force:
        return list(cells)
    return [c for c in cells if finished_status(cell_path(directory, c.id)) != "ok"]


EXECUTORS = ("local", "ray")


def run_suite(suite: Suite, results_root: str | Path, workers: int | None = None,
              force: bool = False,
              progress: GridProgress | None = None, executor: str = "local",
              address: str | None = None, retries: int = 2,
              cells: list[Cell] | None = None, reuse: list[Path] = (),
              time_limit_s: float | None = None) -> RunSummary:
    """Run the cells of ``suite`` not yet finished under ``results_root``; with ``cells``
    (from :meth:`Suite.select`), only those. The manifest names the whole suite all the
    same, so ``report`` shows every finished cell of this version. A cell that one of the
    ``reuse`` folders (other suites' results) holds finished, identical in all but its
    method and variant names, is copied from there instead (see :mod:`senbench.reuse`).
    With ``time_limit_s``, a cell starts only if it is expected to end within that many
    seconds of the call (see :mod:`senbench.schedule`); ``summary.not_started`` counts the
    cells left for a later run. A cell that another run of the suite holds is passed over
    (``summary.elsewhere``), so several runs can share one grid (see :mod:`senbench.claims`).

    ``executor="local"``: serially, or ``workers`` processes. ``"ray"``: as Ray tasks, on the
    cluster at ``address`` or on a local instance of ``workers`` CPUs (default: all usable)
    started for the run; a task whose worker dies is retried ``retries`` times (see
    :mod:`senbench.ray_runner`)."""
    if executor not in EXECUTORS:
        raise SenbenchError(f"unknown executor {executor!r}: use one of {', '.join(EXECUTORS)}")
    if executor == "ray":
        from senbench.ray_runner import import_ray

        import_ray()  # before anything is written: a missing extra is a clear error
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
    progress = progress or GridProgress(None)
    threads = max((c.config["threads"] for c in todo), default=1)
    if executor == "local":
        workers = workers or 1
    if executor == "local" and workers * threads > usable_cores():
        progress.warn(f"{workers} workers × {threads} torch threads per cell > "
                      f"{usable_cores()} cores: cells will compete for them")
    info = RunInfo.gather(Path(results_root) / "encoders")
    claims = CellClaims(directory, force)
    with progress.grid(len(cells), summary.skipped):
        try:
            todo = _copy_reused(todo, directory, info, found, progress, summary, claims)
            todo = _prepare_encoders(todo, directory, info, progress, summary)
            left = None if time_limit_s is None else time_limit_s - (time.monotonic() - started)
            if left is not None and left <= 0 and todo:
                progress.warn("the time limit ran out while state encoders were trained; "
                              "they are cached, so the next run starts cells at once")
            if executor == "ray":
                from senbench.ray_runner import run_cells

                summary.elsewhere = [c.id for c in todo if not claims.take(c.id)]
                passed = set(summary.elsewhere)
                for cell in todo:
                    if cell.id in passed:
                        progress.passed_over(cell.label)
                todo = [c for c in todo if c.id not in passed]
                run_cells(todo, directory, info, progress, summary, address=address,
                          workers=workers, retries=retries, written=claims.release)
            else:
                schedule = Schedule(todo, left, suite, results_root, claims,
                                    lambda cell: progress.passed_over(cell.label))
                if workers <= 1:
                    _run_serial(schedule, directory, info, progress, summary)
                else:
                    _run_processes(todo, directory, info, workers, progress, summary, schedule)
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
                 progress: GridProgress, summary: RunSummary, claims: CellClaims) -> list[Cell]:
    """Copy the cells ``found`` holds (``--reuse``), each under its lock, as a run would
    compute it; the cells still to run (a cell another run holds among them: the schedule
    passes it over)."""
    left, other_code = [], 0
    for cell in todo:
        source = found.get(curve_key(cell.config))
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


def _prepare_encoders(todo: list[Cell], directory: Path, info: RunInfo,
                      progress: GridProgress, summary: RunSummary) -> list[Cell]:
    """Train each state encoder the cells need once, here, before any cell starts (cells
    then load it), on its spec's ``training.threads``. A cell whose encoder cannot be trained
    fails, with why."""
    from senbench.encoders import encoder_request, load_or_train
    from senbench.plugins import registries

    needed: dict[str, list[Cell]] = {}
    for cell in todo:
        if cell.config.get("encoder"):
            needed.setdefault(encoder_request(cell.config).id, []).append(cell)
    if not needed:
        return todo
    lost: set[str] = set()
    for cells in needed.values():
        try:
            load_or_train(info.encoder_cache, encoder_request(cells[0].config), registries(),
                          progress.log)
        except Exception as exc:
            for cell in cells:
                outcome = record_lost_cell(cell, directory, info,
                                           f"could not train its encoder: {exc!r}")
                summary.outcomes.append(outcome)
                progress.finished(outcome)
                lost.add(cell.id)
    return [c for c in todo if c.id not in lost]


def _run_serial(schedule: Schedule, directory: Path, info: RunInfo, progress: GridProgress,
                summary: RunSummary) -> None:
    while (cell := schedule.next()) is not None:
        progress.started(cell.id, cell.label, cell.config["budget"])
        set_threads(cell.config["threads"])
        try:
            outcome = run_cell(cell, directory, info, progress.update)
        except Exception as exc:  # outside the agent: e.g. the result could not be written
            outcome = record_lost_cell(cell, directory, info, f"crashed: {exc!r}")
        summary.outcomes.append(outcome)
        schedule.finished(cell, outcome.status, outcome.wall_s)
        progress.finished(outcome)


# --- one process per cell ------------------------------------------------------------------


def _context() -> Any:
    """Fork cells from a server that imported senbench, torch and the plugins once: a cell
    starts in milliseconds, not the seconds a fresh interpreter needs to import torch."""
    if sys.platform != "linux":
        return mp.get_context("spawn")
    context = mp.get_context("forkserver")
    modules = ["senbench.cell", "torch"]
    modules += sorted({ep.value.split(":")[0] for ep in entry_points(group=plugins.GROUP)})
    context.set_forkserver_preload(modules)
    return context


def _cell_process(cell: Cell, directory: Path, info: RunInfo, events: Any,
                  extra_plugins: list[tuple[str, str, str]], parent: int) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    threading.Thread(target=_exit_with_parent, args=(parent,), daemon=True).start()
    set_threads(cell.config["threads"])
    plugins.register_modules(extra_plugins)
    try:
        outcome = run_cell(cell, directory, info,
                           lambda *args: _tell(events, ("update", *args)))
    except Exception as exc:  # outside the agent: record it as this cell's failure
        outcome = record_lost_cell(cell, directory, info, f"crashed: {exc!r}")
    _tell(events, ("outcome", outcome))  # written before this process exits
    events.close()


def _tell(events: Any, message: tuple) -> None:
    """Send to the runner; if it is gone (killed, stopped), this cell has no one to tell."""
    try:
        events.send(message)
    except (BrokenPipeError, ConnectionError):
        os._exit(1)


def _exit_with_parent(runner: int) -> None:
    """A cell whose runner was killed (SIGKILL cannot be caught) stops too, rather than
    finishing for nobody. (The runner is not the parent: cells fork from a server.)"""
    try:
        process = psutil.Process(runner)
        while process.is_running():  # compares start times: a reused pid is not the runner
            time.sleep(0.5)
    except psutil.Error:
        pass
    os._exit(1)


def _run_processes(todo: list[Cell], directory: Path, info: RunInfo, workers: int,
                   progress: GridProgress, summary: RunSummary,
                   schedule: Schedule | None = None) -> None:
    """Run ``todo`` in ``workers`` processes at a time, in the order ``schedule`` (default:
    ``todo``'s, all of them) hands them out."""
    context = _context()
    schedule = schedule or Schedule(todo)
    running: dict[str, tuple[Cell, Any]] = {}
    pipes: dict[str, Any] = {}
    outcomes: dict[str, CellOutcome] = {}
    extra = plugins.registered_module_names()
    try:
        while True:
            while len(running) < workers and (cell := schedule.next()) is not None:
                # A pipe per cell, not a shared Queue: a Queue's semaphore vanishes with the
                # runner, and a cell still unpacking its arguments then dies with a traceback.
                reader, writer = context.Pipe(duplex=False)
                process = context.Process(
                    target=_cell_process, daemon=True, name=f"senbench-cell-{cell.id}",
                    args=(cell, directory, info, writer, extra, os.getpid()))
                with signals_held():  # a Ctrl-C mid-start would orphan a half-made cell
                    process.start()
                    running[cell.id] = (cell, process)
                    pipes[cell.id] = reader
                writer.close()
                progress.started(cell.id, cell.label, cell.config["budget"])
            if not running:
                break
            _drain(pipes, progress, outcomes, timeout=0.2)
            for cell_id, (cell, process) in list(running.items()):
                if process.exitcode is None:
                    continue
                deadline = time.monotonic() + 2.0
                while cell_id not in outcomes and time.monotonic() < deadline:
                    _drain(pipes, progress, outcomes, timeout=0.05)
                outcome = outcomes.pop(cell_id, None)
                if outcome is None:
                    outcome = record_lost_cell(cell, directory, info, _death(process.exitcode))
                del running[cell_id]
                pipes.pop(cell_id).close()
                summary.outcomes.append(outcome)
                schedule.finished(cell, outcome.status, outcome.wall_s)
                progress.finished(outcome)
    except BaseException:
        for _, process in running.values():
            process.kill()
        for _, process in running.values():
            process.join(timeout=5)
        remove_stray_temp_files(directory)
        raise


@contextmanager
def signals_held():
    """Defer SIGINT and SIGTERM until the block ends; they are then delivered as usual.

    Deferred in Python, not masked: masking blocks them in this thread only, and the kernel
    then hands them to another thread (rich's refresh thread), whose flag Python still turns
    into a KeyboardInterrupt here, mid-block."""
    if threading.current_thread() is not threading.main_thread():
        yield  # only the main thread handles signals
        return
    received: list[int] = []
    previous: dict[int, Any] = {}
    try:
        for sig in (signal.SIGINT, signal.SIGTERM):  # one at a time: each is put back below
            previous[sig] = signal.signal(sig, lambda signum, frame: received.append(signum))
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, signal.SIG_DFL if handler is None else handler)
        for sig in received:
            signal.raise_signal(sig)


def _drain(pipes: dict[str, Any], progress: GridProgress, outcomes: dict[str, CellOutcome],
           timeout: float) -> None:
    """Read whatever the running cells have sent, waiting up to ``timeout`` for the first."""
    for reader in connection_wait(list(pipes.values()), timeout):
        try:
            while reader.poll():
                event, *args = reader.recv()
                if event == "outcome":
                    outcomes[args[0].cell_id] = args[0]
                else:
                    progress.update(*args)
        except (EOFError, OSError):  # the cell ended; its exit status tells how
            continue


def _death(code: int | None) -> str:
    """How a cell's process ended without reporting an outcome."""
    if code is not None and code < 0:
        name = signal.Signals(-code).name
        hint = "; out of memory?" if -code == signal.SIGKILL else ""
        return f"was killed by signal {-code} ({name}{hint})"
    return f"exited with code {code} before reporting"


def set_threads(threads: int) -> None:
    os.environ["OMP_NUM_THREADS"] = str(threads)
    os.environ["MKL_NUM_THREADS"] = str(threads)
    try:
        import torch
    except ImportError:
        return
    if torch.get_num_threads() != threads:
        torch.set_num_threads(threads)
