"""Running cells one process each, ``workers`` at a time, and what a cell process needs.

A cell that dies (killed, out of memory, ``os._exit``) is recorded as failed from its exit
status and takes nothing else with it. Cells ignore SIGINT; on Ctrl-C or SIGTERM the runner
kills them, so only finished cells remain; a cell whose runner was SIGKILLed notices and
exits.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import signal
import sys
import threading
import time
from contextlib import contextmanager
from datetime import UTC, datetime
from multiprocessing.connection import wait as connection_wait
from pathlib import Path
from typing import Any

import psutil

from senbench.plugin import manager as plugins
from senbench.results.store import remove_stray_temp_files
from senbench.run.batch import run_cells
from senbench.run.execute import CellOutcome, RunInfo, record_lost_cell
from senbench.run.progress import Progress
from senbench.run.schedule import Schedule
from senbench.run.summary import RunSummary
from senbench.suite import Cell


def usable_cores() -> int:
    """Cores this process may run on (its affinity mask: a batch scheduler's share)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def run_serial(schedule: Schedule, directory: Path, info: RunInfo, progress: Progress,
                summary: RunSummary) -> None:
    while batch := schedule.next_batch():
        for cell in batch:
            progress.started(cell.id, cell.label, cell.budget)
        set_threads(batch[0].threads)
        by_id = {cell.id: cell for cell in batch}

        def written(outcome: CellOutcome, by_id: dict[str, Cell] = by_id) -> None:
            summary.outcomes.append(outcome)
            schedule.finished(by_id.pop(outcome.cell_id), outcome.status, outcome.wall_s)
            progress.finished(outcome)

        try:
            run_cells(batch, directory, info, progress.update, written)
        except Exception as exc:  # outside the agents: those not yet written are lost
            for cell in list(by_id.values()):
                written(record_lost_cell(cell, directory, info, f"crashed: {exc!r}"))


def _context() -> Any:
    """Fork cells from a server that imported senbench, torch and the plugins once: a cell
    starts in milliseconds, not the seconds a fresh interpreter needs to import torch. The
    server imports this module too (and with it everything a cell runs), so a cell runs the
    code its run started with: source edited while a long run or study goes on is not
    imported half-new into its later cells (a new module beside an old one it imports
    from failed every cell of a study that way)."""
    if sys.platform != "linux":
        return mp.get_context("spawn")
    context = mp.get_context("forkserver")
    modules = [__name__, "senbench.run.execute", "torch"]
    modules += plugins.entry_point_modules()  # not a broken one: it would stop the server
    context.set_forkserver_preload(modules)
    _start_server_deaf_to_ctrl_c()
    return context


def _start_server_deaf_to_ctrl_c() -> None:
    """Start the fork server with SIGINT blocked, as multiprocessing starts its resource
    tracker: a Ctrl-C to the terminal's process group reaches the server too, and in its
    first second (before it ignores SIGINT itself) printed its own KeyboardInterrupt
    traceback under the runner's clean stop. Its cells ignore SIGINT anyway; a Ctrl-C
    during the spawn reaches the runner once the mask is restored."""
    from multiprocessing import forkserver, resource_tracker

    resource_tracker.ensure_running()  # first: starting it unblocks SIGINT
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        forkserver.ensure_running()
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


def _cell_process(cells: list[Cell], directory: Path, info: RunInfo, events: Any,
                  extra_plugins: list[tuple[str, str, str]], parent: int) -> None:
    """Run a cell, or the seeds of one batch, and tell the runner each outcome once that
    cell's file is written."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    threading.Thread(target=_exit_with_parent, args=(parent,), daemon=True).start()
    set_threads(cells[0].threads)
    plugins.register_modules(extra_plugins)
    told: set[str] = set()

    def written(outcome: CellOutcome) -> None:
        told.add(outcome.cell_id)
        _tell(events, ("outcome", outcome))

    try:
        run_cells(cells, directory, info, lambda *args: _tell(events, ("update", *args)),
                  written)
    except Exception as exc:  # outside the agents: record it as their failure
        for cell in cells:
            if cell.id not in told:
                written(record_lost_cell(cell, directory, info, f"crashed: {exc!r}"))
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


def run_processes(todo: list[Cell], directory: Path, info: RunInfo, workers: int,
                   progress: Progress, summary: RunSummary,
                   schedule: Schedule | None = None) -> None:
    """Run ``todo`` in ``workers`` processes at a time, in the order ``schedule`` (default:
    ``todo``'s, all of them) hands them out: a process per cell, or per seed batch."""
    context = _context()
    schedule = schedule or Schedule(todo)
    running: dict[str, tuple[list[Cell], Any]] = {}  # by the first cell's id
    launched: dict[str, datetime] = {}  # when each process was started
    pipes: dict[str, Any] = {}
    outcomes: dict[str, CellOutcome] = {}
    extra = plugins.registered_module_names()

    def finish(cell: Cell, outcome: CellOutcome) -> None:
        summary.outcomes.append(outcome)
        schedule.finished(cell, outcome.status, outcome.wall_s)
        progress.finished(outcome)

    try:
        while True:
            while len(running) < workers and (batch := schedule.next_batch()):
                # A pipe per process, not a shared Queue: a Queue's semaphore vanishes with
                # the runner, and a cell still unpacking its arguments then dies with a
                # traceback.
                reader, writer = context.Pipe(duplex=False)
                key = batch[0].id
                process = context.Process(
                    target=_cell_process, daemon=True, name=f"senbench-cell-{key}",
                    args=(batch, directory, info, writer, extra, os.getpid()))
                launched[key] = datetime.now(UTC)
                with signals_held():  # a Ctrl-C mid-start would orphan a half-made cell
                    process.start()
                    running[key] = (batch, process)
                    pipes[key] = reader
                writer.close()
                for cell in batch:
                    progress.started(cell.id, cell.label, cell.budget)
            if not running:
                break
            _drain(pipes, progress, outcomes, timeout=0.2)
            for key, (batch, process) in list(running.items()):
                for cell in [c for c in batch if c.id in outcomes]:  # a seed that finished
                    finish(cell, outcomes.pop(cell.id))
                    batch.remove(cell)
                if process.exitcode is None and batch:
                    continue
                deadline = time.monotonic() + 2.0
                while (any(c.id not in outcomes for c in batch)
                       and time.monotonic() < deadline):
                    _drain(pipes, progress, outcomes, timeout=0.05)
                for cell in batch:
                    outcome = outcomes.pop(cell.id, None)
                    if outcome is None:
                        outcome = record_lost_cell(cell, directory, info,
                                                   _death(process.exitcode), launched[key])
                    finish(cell, outcome)
                process.join(timeout=5)
                del running[key]
                launched.pop(key)
                pipes.pop(key).close()
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


def _drain(pipes: dict[str, Any], progress: Progress, outcomes: dict[str, CellOutcome],
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
