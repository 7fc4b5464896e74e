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
from multiprocessing.connection import wait as connection_wait
from pathlib import Path
from typing import Any

import psutil

from senbench.plugin import manager as plugins
from senbench.results.store import remove_stray_temp_files
from senbench.run.execute import CellOutcome, RunInfo, record_lost_cell, run_cell
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
    while (cell := schedule.next()) is not None:
        progress.started(cell.id, cell.label, cell.budget)
        set_threads(cell.threads)
        try:
            outcome = run_cell(cell, directory, info, progress.update)
        except Exception as exc:  # outside the agent: e.g. the result could not be written
            outcome = record_lost_cell(cell, directory, info, f"crashed: {exc!r}")
        summary.outcomes.append(outcome)
        schedule.finished(cell, outcome.status, outcome.wall_s)
        progress.finished(outcome)


def _context() -> Any:
    """Fork cells from a server that imported senbench, torch and the plugins once: a cell
    starts in milliseconds, not the seconds a fresh interpreter needs to import torch."""
    if sys.platform != "linux":
        return mp.get_context("spawn")
    context = mp.get_context("forkserver")
    modules = ["senbench.run.execute", "torch"]
    modules += plugins.entry_point_modules()  # not a broken one: it would stop the server
    context.set_forkserver_preload(modules)
    return context


def _cell_process(cell: Cell, directory: Path, info: RunInfo, events: Any,
                  extra_plugins: list[tuple[str, str, str]], parent: int) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    threading.Thread(target=_exit_with_parent, args=(parent,), daemon=True).start()
    set_threads(cell.threads)
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


def run_processes(todo: list[Cell], directory: Path, info: RunInfo, workers: int,
                   progress: Progress, summary: RunSummary,
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
                progress.started(cell.id, cell.label, cell.budget)
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
