"""What the runner tells whoever watches a run: the progress protocol.

The runner never imports a display. It calls these methods; the CLI's rich display
(:class:`senbench.cli.progress.GridProgress`) implements them, a tuning study implements
them to prune trials, and :class:`NullProgress` ignores them (library use, tests).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Protocol

from senbench.run.execute import CellOutcome


class Progress(Protocol):
    def grid(self, total: int, skipped: int):
        """A context manager around the whole run: ``total`` cells, ``skipped`` of them
        already finished."""

    def log(self, message: str) -> None: ...

    def warn(self, message: str) -> None: ...

    def started(self, cell_id: str, label: str, budget: int) -> None:
        """A cell began; ``budget`` in frames."""

    def update(self, cell_id: str, steps: int, rate: float, last_eval: float | None,
               eval_step: int | None = None, train_return: float | None = None) -> None:
        """A running cell's frames so far, frames/s, its latest evaluation return with
        the frame it was taken at, and the mean return of its training episodes so far."""

    def finished(self, outcome: CellOutcome) -> None: ...

    def copied(self, label: str, source: Path, final_eval: float | None) -> None:
        """A cell taken from another suite's results (``run --reuse``), not run."""

    def passed_over(self, label: str) -> None:
        """A cell left to another run of the suite, which holds it or has written it."""


class NullProgress:
    """Shows nothing."""

    @contextmanager
    def grid(self, total: int, skipped: int) -> Iterator[None]:
        yield

    def log(self, message: str) -> None:
        pass

    def warn(self, message: str) -> None:
        pass

    def started(self, cell_id: str, label: str, budget: int) -> None:
        pass

    def update(self, cell_id: str, steps: int, rate: float, last_eval: float | None,
               eval_step: int | None = None, train_return: float | None = None) -> None:
        pass

    def finished(self, outcome: CellOutcome) -> None:
        pass

    def copied(self, label: str, source: Path, final_eval: float | None) -> None:
        pass

    def passed_over(self, label: str) -> None:
        pass
