"""Seed-batched cells: the seeds of one encoded method run together in one process, their
frames encoded in one batch (a suite's ``seed_batch: B``).

Each seed runs as it would alone — its own agent, envs, random generators, evaluation and
result file — in a thread of its own. What the seeds share is the state encoder, behind a
barrier: a pass waits until every seed still running has handed in its frame, then encodes
them together. Every pass takes B frames: the seeds' and, in place of seeds that are not
there (finished, failed, run elsewhere, or a single seed resumed alone), frames of zeros.
A convolutional net in eval mode computes each frame of a batch from that frame alone, with
arithmetic that depends on the batch size only, so a seed's encoded observations — and its
curve — are bitwise the same whichever seeds it runs beside and in whichever slot
(``tests/test_seed_batch.py`` checks it). Between batch sizes the outputs differ by float
rounding (≤ 1.2e-7 of the normalised output, batch 2-8 against 1, measured on sen-resnet),
which a tile boundary can turn into another action and so another curve: B is part of a
cell's computation (its id, config and ``seed_batch`` column), as the torch thread count is.

Only agents whose spec sets ``seed_batching`` run this way: they draw from no process-global
random generator, which threads would share. The seeds' Python code takes turns on the GIL;
what a batch buys is the encoder's throughput at batch B against B passes of one frame,
which on the project's machine did not pay for the batch's hand-offs
(``benchmarks/seed_batch.py``, docs/benchmarks.md).

Failure stays per seed: a seed whose agent raises is recorded failed by its own cell (as
alone) and leaves the barrier, so the others go on; a pass that raises fails the seeds that
waited on it.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from senbench.encoders import load_or_train
from senbench.plugin.manager import registries
from senbench.results.store import write_cell
from senbench.run.execute import (
    CellOutcome,
    ProgressCallback,
    RunInfo,
    execute_cell,
    failure_text,
    lost_cell,
    record_lost_cell,
    reset_peak_rss,
)
from senbench.suite import Cell


class SharedEncoder:
    """A state encoder that the seeds of a batch call from their threads: each call hands
    in one frame stack and returns its estimate once the pass of that round has run. Each of
    the ``seeds`` threads calls it inside its ``seat(slot)``; the seats are counted from the
    start, so the first seed to call waits for the others rather than run a pass alone."""

    def __init__(self, encoder: Any, size: int, seeds: int):
        if not 1 <= seeds <= size:
            raise ValueError(f"{seeds} seeds do not fit a batch of {size}")
        self.encoder = encoder
        self.size = size
        self.low, self.high = encoder.low, encoder.high
        self._lock = threading.Condition()
        self._seated = seeds
        self._frames: dict[int, np.ndarray] = {}
        self._results: dict[int, np.ndarray | BaseException] = {}
        self._round = 0
        self._local = threading.local()
        self.passes = 0

    def seat(self, slot: int) -> _Seat:
        if not 0 <= slot < self.size:
            raise ValueError(f"slot {slot} outside a batch of {self.size}")
        return _Seat(self, slot)

    def __call__(self, frames: np.ndarray) -> np.ndarray:
        """(1, stack, H, W) uint8 → (1, k), encoded in this round's batch."""
        slot = getattr(self._local, "slot", None)
        if slot is None:
            raise RuntimeError("a shared encoder is called from a seed's thread, in its seat")
        if len(frames) != 1:
            raise ValueError(f"a seed hands in one frame stack per call, not {len(frames)}")
        with self._lock:
            self._frames[slot] = np.asarray(frames[0])
            round_ = self._round
            self._run_if_all_in()
            while self._round == round_:
                self._lock.wait()
            result = self._results.pop(slot)
        if isinstance(result, BaseException):
            raise RuntimeError(f"the batched encoder pass failed: {result!r}") from result
        return result[None]

    def _run_if_all_in(self) -> None:
        """With the lock held: run the pass once every seated seed has handed in a frame."""
        if not self._frames or len(self._frames) < self._seated:
            return
        first = next(iter(self._frames.values()))
        batch = np.zeros((self.size, *first.shape), dtype=first.dtype)
        for slot, frame in self._frames.items():
            batch[slot] = frame
        try:
            encoded = self.encoder(batch)
            results: dict[int, Any] = {slot: encoded[slot] for slot in self._frames}
        except Exception as exc:  # noqa: BLE001 - handed to every seed that waited on it
            results = dict.fromkeys(self._frames, exc)
        self._results.update(results)
        self._frames.clear()
        self._round += 1
        self.passes += 1
        self._lock.notify_all()


class _Seat:
    """A seed's place at the barrier while its cell runs: the others wait for its frame
    until it leaves."""

    def __init__(self, shared: SharedEncoder, slot: int):
        self.shared, self.slot = shared, slot

    def __enter__(self) -> _Seat:
        self.shared._local.slot = self.slot
        return self

    def __exit__(self, *exc: Any) -> None:
        self.shared._local.slot = None
        with self.shared._lock:
            self.shared._seated -= 1
            self.shared._run_if_all_in()  # the others may be waiting for this seed only


Result = tuple[list[dict[str, Any]], CellOutcome]


def execute_cells(cells: list[Cell], info: RunInfo, progress: ProgressCallback | None = None,
                  done: Callable[[Cell, Result], None] = lambda cell, result: None,
                  stop_at: int | None = None) -> list[Result]:
    """Run cells that share a batch key (seeds of one method) and return each one's rows and
    outcome, in order; ``done`` is called, in the seed's thread, as each one finishes. Cells
    with ``seed_batch`` 1 run one after another, as alone. ``stop_at``: see
    :func:`execute_cell`."""
    if not cells:
        return []
    size = cells[0].seed_batch
    if size == 1:
        results = []
        for cell in cells:
            results.append(execute_cell(cell, info, progress, stop_at=stop_at))
            done(cell, results[-1])
        return results
    if len(cells) > size or len({c.batch_key for c in cells}) != 1:
        raise ValueError(f"a seed batch of {size} takes up to {size} seeds of one method, "
                         f"not {[c.label for c in cells]}")
    try:
        encoder = load_or_train(info.encoder_cache, cells[0].encoder_request(),
                                registries()).laid_out(cells[0].memory_format)
    except Exception as exc:  # each cell records why, as alone
        results = [lost_cell(c, info, f"could not load its encoder: {failure_text(exc)}")
                   for c in cells]
        for cell, result in zip(cells, results, strict=True):
            done(cell, result)
        return results
    reset_peak_rss()  # the batch's peak, not the process's (it may have trained encoders)
    shared = SharedEncoder(encoder, size, len(cells))
    results: list[Result | None] = [None] * len(cells)
    one_at_a_time = threading.Lock()  # the seeds report down one pipe, to one display
    if progress is not None:
        report = progress

        def progress(*args: Any) -> None:
            with one_at_a_time:
                report(*args)

    raised: list[BaseException] = []  # by ``done``: the caller's, raised again below

    def run(slot: int, cell: Cell) -> None:
        try:
            with shared.seat(slot):
                results[slot] = execute_cell(cell, info, progress, encoder=shared,
                                             stop_at=stop_at)
        except BaseException as exc:  # noqa: BLE001 - outside the agent: this seed only
            results[slot] = lost_cell(cell, info, f"crashed in its seed batch: {exc!r}")
        with one_at_a_time:
            try:
                done(cell, results[slot])
            except BaseException as exc:  # noqa: BLE001 - handed to the calling thread
                raised.append(exc)

    threads = [threading.Thread(target=run, args=(slot, cell), daemon=True,
                                name=f"senbench-seed-{cell.seed}")
               for slot, cell in enumerate(cells)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    if raised:
        raise raised[0]
    return [r for r in results if r is not None]


def run_cells(cells: list[Cell], directory: Path, info: RunInfo,
              progress: ProgressCallback | None = None,
              written: Callable[[CellOutcome], None] = lambda outcome: None
              ) -> list[CellOutcome]:
    """Run cells (one, or the seeds of one batch) and write each one's result file as soon
    as it finishes; ``written`` is called with its outcome once it is."""
    outcomes: list[CellOutcome] = []
    interrupted, writing = threading.Event(), threading.Lock()

    def write(cell: Cell, result: Result) -> None:
        with writing:
            if interrupted.is_set():  # the run stopped: an interrupted cell writes nothing
                return
            rows, outcome = result
            try:
                write_cell(directory, cell.id, rows)
            except Exception as exc:  # as a cell that cannot write its result
                outcome = record_lost_cell(cell, directory, info, f"crashed: {exc!r}")
            outcomes.append(outcome)
            written(outcome)

    try:
        execute_cells(cells, info, progress, write)
    except KeyboardInterrupt:
        # The seeds' threads (daemons) go on until the process ends; what they finish
        # from now on is dropped, as the cells of an interrupted run are.
        with writing:
            interrupted.set()
        raise
    return outcomes
