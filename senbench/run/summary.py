"""What a run did: the record the runner fills and the CLI prints."""

from __future__ import annotations

from dataclasses import dataclass, field

from senbench.run.execute import CellOutcome

EXIT_NOT_DONE = 75
"""sysexits' EX_TEMPFAIL: not done, run again later (a batch job's requeue)."""


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
    since this run started (see :mod:`senbench.run.claims`)."""
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
