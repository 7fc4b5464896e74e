"""Running a suite's cells as Ray tasks: ``senbench run SUITE --executor ray``.

Each cell is one task that declares the CPUs it uses (its torch threads), so Ray places it
on a node with that many free. A cell of a seed batch runs as a task of its own too (its
encoder passes padded to the batch, so its curve is the one it has in a batch; the speed-up
of batching is the local executor's). The task runs the cell where it lands and returns its rows;
the driver writes them with the same atomic per-cell files as a local run, so workers need
no shared disk, and resume is the local runner's (finished files are skipped before any
task is submitted). Encoders are trained once by the driver and put in Ray's object store;
a node writes the files into a cache of its own the first time a cell there needs them.
A task whose worker dies (killed, out of memory, a node lost) is retried ``retries`` times by
Ray, then the cell is recorded as failed with why. Ctrl-C stops the tasks in flight: it
cancels them on a cluster, and stops a local instance started for the run with them.

Ray is an optional extra (``pip install 'senbench[ray]'``); it is imported only here.
"""

from __future__ import annotations

import dataclasses
import os
import platform
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from senbench.encoders import complete
from senbench.errors import SenbenchError
from senbench.plugin import manager as plugins
from senbench.results.atomic import atomic_folder
from senbench.results.store import remove_stray_temp_files, write_cell
from senbench.run.batch import execute_cells
from senbench.run.execute import CellOutcome, RunInfo, lost_cell, record_lost_cell
from senbench.run.processes import set_threads, signals_held, usable_cores
from senbench.run.progress import Progress
from senbench.suite import Cell

ENCODER_FILES = ("model.pt", "spec.json")
"""What a node needs of a trained encoder to load it (not its traces or training curve)."""

LOCAL_OBJECT_STORE_BYTES = 256 * 1024**2
"""A local instance's object store: encoders and cell results are small; Ray's default
(30% of memory) would take gigabytes of /dev/shm for nothing."""


def import_ray() -> Any:
    try:
        import ray
    except ImportError:
        raise SenbenchError("--executor ray needs Ray: pip install 'senbench[ray]' (or "
                            "pip install ray), or run without --executor ray") from None
    return ray


def run_cells(todo: list[Cell], directory: Path, info: RunInfo, progress: Progress,
              summary: Any, address: str | None = None, workers: int | None = None,
              retries: int = 2, written: Callable[[str], None] = lambda cell_id: None) -> None:
    """Run ``todo`` on Ray and record each cell's outcome in ``summary``; ``written`` is
    called with a cell's id once its file is written.

    ``address``: an existing cluster (``auto``, ``ray://host:port``); None starts a local
    instance for this run, with ``workers`` CPUs (default: this machine's), and stops it."""
    ray = import_ray()
    needs = max((c.threads for c in todo), default=1)
    started_here = False
    if not ray.is_initialized():
        # Held: a Ctrl-C while Ray starts is handled once it has; and on leaving, our
        # handlers replace those ray.init installs, which would exit the driver outright.
        with signals_held():
            if address is None:
                # "local": always a new instance, never a cluster `ray start` left running
                ray.init(address="local", num_cpus=max(workers or usable_cores(), needs),
                         include_dashboard=False, object_store_memory=LOCAL_OBJECT_STORE_BYTES,
                         log_to_driver=False, configure_logging=False)
            else:
                try:
                    ray.init(address=address, log_to_driver=False, configure_logging=False)
                except ConnectionError as exc:
                    raise SenbenchError(f"cannot reach the Ray cluster at {address!r}: {exc}; "
                                        "check --address (auto, or ray://host:10001)") from None
            started_here = True
    try:
        largest = max((node["Resources"].get("CPU", 0) for node in ray.nodes()
                       if node.get("Alive")), default=0)
        if needs > largest:  # Ray would leave such a task pending for ever
            raise SenbenchError(f"cells of this suite need {needs} CPUs (their threads) but the "
                                f"largest Ray node has {largest:g}: lower the suite's threads, "
                                "or add a larger node")
        # Ray can abort the driver when a task is cancelled just as its result arrives
        # (a check in its task manager fails, seen in 2.60), so Ctrl-C cancels tasks one by
        # one only on a cluster; an instance of this run's own is stopped whole instead
        _run(ray, todo, directory, info, progress, summary, retries, written,
             cancel=not (started_here and address is None))
    finally:
        if started_here:
            ray.shutdown()


def _run(ray: Any, todo: list[Cell], directory: Path, info: RunInfo, progress: Progress,
         summary: Any, retries: int, written: Callable[[str], None], cancel: bool) -> None:
    sink = ray.remote(num_cpus=0, max_restarts=-1)(_ProgressSink).remote()
    task = ray.remote(_ray_cell)
    shipped: dict[str, Any] = {}
    extra = plugins.registered_module_names()
    pending: dict[Any, Cell] = {}
    cells = {c.id: c for c in todo}
    running: set[str] = set()
    ended: set[str] = set()  # a cell's last reports may reach the sink after its result
    try:
        for cell in todo:
            key = _encoder_key(cell) if cell.encoder is not None else None
            if key is not None and key not in shipped:
                shipped[key] = ray.put(_encoder_files(info.encoder_cache, key))
            ref = task.options(num_cpus=cell.threads, max_retries=retries,
                               retry_exceptions=False, name=f"senbench-cell-{cell.id}",
                               ).remote(cell, info, key, shipped.get(key), extra, sink)
            pending[ref] = cell
        while pending:
            done, _ = ray.wait(list(pending), num_returns=1, timeout=0.5)
            _show(_drain(ray, sink), cells, running, ended, progress)
            for ref in done:
                cell = pending.pop(ref)
                outcome = _collect(ray, ref, cell, directory, info, retries)
                written(cell.id)
                if cell.id not in running:
                    progress.started(cell.id, cell.label, cell.budget)
                running.discard(cell.id)
                ended.add(cell.id)
                summary.outcomes.append(outcome)
                progress.finished(outcome)
    except BaseException:
        for ref in pending if cancel else ():
            ray.cancel(ref, force=True)
        remove_stray_temp_files(directory)
        raise


def _drain(ray: Any, sink: Any) -> list[tuple]:
    """The progress reports so far; none while the sink's actor restarts (progress only)."""
    try:
        return ray.get(sink.drain.remote())
    except ray.exceptions.RayActorError:
        return []


def _collect(ray: Any, ref: Any, cell: Cell, directory: Path, info: RunInfo,
             retries: int) -> CellOutcome:
    """Write a finished task's cell, or record why it has none."""
    try:
        rows, outcome = ray.get(ref)
    except ray.exceptions.RayTaskError as exc:  # raised before the cell ran
        cause = exc.cause if exc.cause is not None else exc
        return record_lost_cell(cell, directory, info, f"raised on Ray: {cause!r}")
    except ray.exceptions.RayError as exc:  # its worker or node lost, each try; or cancelled
        return record_lost_cell(cell, directory, info,
                                f"was lost on Ray ({type(exc).__name__}; retried up to "
                                f"{retries} times): {_first_line(exc)}")
    try:
        write_cell(directory, cell.id, rows)
    except Exception as exc:  # as a local cell that cannot write its result
        return record_lost_cell(cell, directory, info, f"crashed: {exc!r}")
    return outcome


def _show(events: list[tuple], cells: dict[str, Cell], running: set[str], ended: set[str],
          progress: Progress) -> None:
    for event, cell_id, *args in events:
        if cell_id in ended:
            continue
        if cell_id not in running:  # a retried cell starts again: show it once
            cell = cells[cell_id]
            progress.started(cell_id, cell.label, cell.budget)
            running.add(cell_id)
        if event == "update":
            progress.update(cell_id, *args)


def _first_line(exc: BaseException) -> str:
    lines = [line for line in str(exc).splitlines() if line.strip()]
    return lines[0][:200] if lines else repr(exc)


# --- encoders ------------------------------------------------------------------------------


def _encoder_key(cell: Cell) -> str:
    """The encoder's cache folder name (its completed request's id)."""
    return complete(cell.encoder_request(), plugins.registries()).id


def _encoder_files(cache: Path, key: str) -> dict[str, bytes]:
    folder = Path(cache) / key
    try:
        return {name: (folder / name).read_bytes() for name in ENCODER_FILES}
    except OSError as exc:
        raise SenbenchError(f"encoder {key} is not in {cache}: {exc}") from None


def node_cache() -> Path:
    """Where a node keeps the encoders it was sent, shared by its workers:
    ``$SENBENCH_RAY_NODE_CACHE``, or a folder under the node's temp dir."""
    chosen = os.environ.get("SENBENCH_RAY_NODE_CACHE")
    if chosen:
        return Path(chosen)
    return Path(tempfile.gettempdir()) / f"senbench-ray-{os.getuid()}" / "encoders"


def _materialize(key: str, files: dict[str, bytes]) -> Path:
    """Write a shipped encoder into this node's cache once: into a temp folder, renamed into
    place, so a worker never loads half an encoder."""
    root = node_cache()
    if not (root / key / "model.pt").exists():
        with atomic_folder(root / key) as tmp:
            for name, data in (files.items() if tmp is not None else ()):
                (tmp / name).write_bytes(data)
    return root


# --- in a Ray worker -----------------------------------------------------------------------


class _ProgressSink:
    """An actor that cells report to; the driver drains it twice a second."""

    def __init__(self) -> None:
        self.events: list[tuple] = []

    def tell(self, event: tuple) -> None:
        self.events.append(event)

    def drain(self) -> list[tuple]:
        events, self.events = self.events, []
        return events


def _ray_cell(cell: Cell, info: RunInfo, key: str | None, files: dict[str, bytes] | None,
              extra: list[tuple[str, str, str]], sink: Any
              ) -> tuple[list[dict[str, Any]], CellOutcome]:
    set_threads(cell.threads)
    plugins.register_modules(extra)
    here = dataclasses.replace(info, host=platform.node(),
                               encoder_cache=_materialize(key, files) if key else
                               info.encoder_cache)
    sink.tell.remote(("started", cell.id))
    last, last_step = 0.0, None

    def report(cell_id: str, steps: int, rate: float, last_eval: float | None,
               eval_step: int | None, train_return: float | None) -> None:
        nonlocal last, last_step
        now = time.monotonic()
        if eval_step != last_step or now - last >= 1.0:  # a new evaluation always; else 1/s
            last, last_step = now, eval_step
            sink.tell.remote(("update", cell_id, steps, rate, last_eval, eval_step,
                              train_return))

    try:  # a seed of a batch runs alone here, its passes padded to its batch: same curve
        return execute_cells([cell], here, report)[0]
    except Exception as exc:  # outside the agent (e.g. its encoder would not load): no retry
        return lost_cell(cell, here, f"crashed: {exc!r}")
