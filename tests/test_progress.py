"""Progress into a log file: running cells print a plain line now and then."""

import io

from rich.console import Console

from senbench.cli.progress import GridProgress
from senbench.run.execute import CellOutcome


def progress_into(log, terminal, clock):
    """Progress printing into ``log``, as a terminal or a file, on a settable clock."""
    return GridProgress(Console(file=log, force_terminal=terminal, width=200),
                        log_every_s=60, clock=lambda: clock[0])


def test_without_a_terminal_a_running_cell_prints_a_line_every_interval():
    log = io.StringIO()
    clock = [0.0]
    progress = progress_into(log, False, clock)
    with progress.grid(total=2, skipped=0):
        progress.started("c1", "mountaincar/dqn-pixels[x=1] seed 0", 1_000_000)
        for second, steps in ((30, 7_500), (61, 15_000), (90, 22_500), (125, 30_000)):
            clock[0] = second
            progress.update("c1", steps, 250.0, -1000.0 if steps > 10_000 else None)
        progress.finished(CellOutcome("c1", "mountaincar/dqn-pixels[x=1] seed 0", "ok", None,
                                      -1000.0, 125.0))
    lines = [line for line in log.getvalue().splitlines() if "frames/s" in line]
    assert lines == [
        "  mountaincar/dqn-pixels[x=1] seed 0: 15,000 of 1,000,000 frames, 250 frames/s, "
        "eval -1000.0",
        "  mountaincar/dqn-pixels[x=1] seed 0: 30,000 of 1,000,000 frames, 250 frames/s, "
        "eval -1000.0"]


def test_on_a_terminal_the_live_line_is_enough():
    log = io.StringIO()
    clock = [0.0]
    progress = progress_into(log, True, clock)
    with progress.grid(total=1, skipped=0):
        progress.started("c1", "cell", 1000)
        clock[0] = 500
        progress.update("c1", 500, 10.0, None)
    assert "500 of 1,000 frames" not in log.getvalue()
