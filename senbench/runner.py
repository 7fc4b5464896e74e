"""Running a suite's cells: resume, serial or process executors, progress, Ctrl-C.

Resume: a cell whose file records ``ok`` is skipped (``force`` redoes it); a failed cell is
tried again. Each worker process gets ``cores // workers`` torch threads, so N workers
never oversubscribe the machine. Workers ignore SIGINT; on Ctrl-C the runner kills them, so
only finished cells remain. A worker that dies (killed, out of memory) takes its cell down
as ``failed``; the remaining cells go on in a fresh pool.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import signal
import threading
import time
from collections import Counter
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from pathlib import Path
from queue import Empty
from typing import Any

from senbench import plugins
from senbench.cell import CellOutcome, RunInfo, record_lost_cell, run_cell
from senbench.progress import GridProgress
from senbench.results import cell_path, cells_dir, finished_status, remove_stray_temp_files
from senbench.suite import Cell, Suite


@dataclass
class RunSummary:
    total: int
    skipped: int = 0
    outcomes: list[CellOutcome] = field(default_factory=list)
    interrupted: bool = False

    @property
    def failed(self) -> list[CellOutcome]:
        return [o for o in self.outcomes if o.status != "ok"]

    @property
    def ok(self) -> int:
        return sum(o.status == "ok" for o in self.outcomes)


def threads_per_worker(workers: int) -> int:
    return max(1, (os.cpu_count() or 1) // workers)


def pending_cells(suite: Suite, directory: Path, force: bool) -> list[Cell]:
    if force:
        return list(suite.cells)
    return [c for c in suite.cells if finished_status(cell_path(directory, c.id)) != "ok"]


def run_suite(suite: Suite, results_root: str | Path, workers: int = 1, force: bool = False,
              progress: GridProgress | None = None) -> RunSummary:
    directory = cells_dir(results_root, suite.name)
    directory.mkdir(parents=True, exist_ok=True)
    remove_stray_temp_files(directory)
    (directory.parent / "suite.yaml").write_bytes(suite.source.path.read_bytes())
    todo = pending_cells(suite, directory, force)
    summary = RunSummary(total=len(suite.cells), skipped=len(suite.cells) - len(todo))
    progress = progress or GridProgress(None)
    info = RunInfo.gather()
    with progress.grid(len(suite.cells), summary.skipped):
        try:
            if workers <= 1:
                _run_serial(todo, directory, info, progress, summary)
            else:
                _run_processes(todo, directory, info, workers, progress, summary)
        except KeyboardInterrupt:
            summary.interrupted = True
    return summary


def _run_serial(todo: list[Cell], directory: Path, info: RunInfo, progress: GridProgress,
                summary: RunSummary) -> None:
    threads = threads_per_worker(1)
    _set_threads(threads)
    for cell in todo:
        progress.started(cell.id, cell.label, cell.config["budget"])
        outcome = run_cell(cell, directory, info, threads, progress.update)
        summary.outcomes.append(outcome)
        progress.finished(outcome)


# --- process pool -------------------------------------------------------------------------

_queue = None


def _init_worker(threads: int, queue, extra_plugins: list[str]) -> None:
    global _queue
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    threading.Thread(target=_exit_with_parent, args=(os.getppid(),), daemon=True).start()
    _queue = queue
    _set_threads(threads)
    plugins.register_modules(extra_plugins)


def _exit_with_parent(parent: int) -> None:
    """A worker whose runner was killed (SIGKILL cannot be caught) stops too, rather than
    finishing its cell for nobody."""
    while os.getppid() == parent:
        time.sleep(0.5)
    os._exit(1)


def _worker_run(cell: Cell, directory: Path, info: RunInfo, threads: int) -> CellOutcome:
    _queue.put(("started", cell.id, cell.label, cell.config["budget"], os.getpid()))
    return run_cell(cell, directory, info, threads,
                    lambda *args: _queue.put(("update", *args)))


MAX_REQUEUES = 3
"""How often a cell whose worker was stopped because another worker died is run again."""


def _run_processes(todo: list[Cell], directory: Path, info: RunInfo, workers: int,
                   progress: GridProgress, summary: RunSummary) -> None:
    context = mp.get_context("spawn")
    queue = context.Queue()
    threads = threads_per_worker(workers)
    requeued: Counter[str] = Counter()
    remaining = list(todo)
    while remaining:
        running: dict[str, int] = {}  # cell id -> pid of the worker running it
        processes: dict[int, Any] = {}
        executor = ProcessPoolExecutor(
            workers, mp_context=context, initializer=_init_worker,
            initargs=(threads, queue, plugins.registered_module_names()),
        )
        futures: dict[Future, Cell] = {
            executor.submit(_worker_run, c, directory, info, threads): c for c in remaining
        }
        remaining = []
        processes.update(getattr(executor, "_processes", None) or {})
        try:
            while futures:
                done, _ = wait(futures, timeout=0.2, return_when=FIRST_COMPLETED)
                processes.update(getattr(executor, "_processes", None) or {})
                _drain(queue, progress, running)
                for future in done:
                    cell = futures.pop(future)
                    try:
                        outcome = future.result()
                    except BrokenProcessPool:
                        reason = _death(running.get(cell.id), processes)
                        retry = reason == "stopped" and requeued[cell.id] < MAX_REQUEUES
                        if reason is None or retry:
                            requeued[cell.id] += retry
                            remaining.append(cell)
                            continue
                        outcome = record_lost_cell(cell, directory, info, threads, reason)
                    running.pop(cell.id, None)
                    summary.outcomes.append(outcome)
                    progress.finished(outcome)
        except BaseException:
            _kill(executor)
            raise
        executor.shutdown(wait=True)


def _death(pid: int | None, processes: dict[int, Any]) -> str | None:
    """Why the worker running a cell is gone after the pool broke: None if the cell never
    started, "stopped" if the pool terminated it because another worker died, else how it
    died."""
    if pid is None:
        return None
    process = processes.get(pid)
    if process is None:
        return "died"
    # The pool's own thread reaps its workers too; whichever waits first gets the status.
    deadline = time.monotonic() + 10
    while (code := process.exitcode) is None and time.monotonic() < deadline:
        time.sleep(0.05)
    if code == -signal.SIGTERM:
        return "stopped"
    if code is not None and code < 0:
        return f"was killed by signal {-code} ({signal.Signals(-code).name}; out of memory?)"
    return f"exited with code {code}"


def _drain(queue, progress: GridProgress, running: dict[str, int]) -> None:
    while True:
        try:
            event, *args = queue.get_nowait()
        except Empty:
            return
        if event == "started":
            cell_id, label, budget, pid = args
            running[cell_id] = pid
            progress.started(cell_id, label, budget)
        else:
            progress.update(*args)


def _kill(executor: ProcessPoolExecutor) -> None:
    processes = list(getattr(executor, "_processes", {}).values())
    for process in processes:
        process.kill()
    executor.shutdown(wait=False, cancel_futures=True)
    for process in processes:
        process.join(timeout=5)


def _set_threads(threads: int) -> None:
    os.environ["OMP_NUM_THREADS"] = str(threads)
    os.environ["MKL_NUM_THREADS"] = str(threads)
    try:
        import torch
    except ImportError:
        return
    torch.set_num_threads(threads)
