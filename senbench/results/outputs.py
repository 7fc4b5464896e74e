"""Files a command writes on request (``--out``, ``--export``): checked before any work is
done, so a mistake costs nothing, and written whole or not at all."""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from senbench.errors import OutputError
from senbench.results.atomic import atomic_file

FIGURES = (".png", ".pdf", ".svg")
"""What ``plot`` and ``show`` write: matplotlib's format follows the suffix."""
TABLES = (".csv", ".parquet")
"""What ``report --out`` and ``compare --out`` write."""


def check_out_file(path: Path, suffixes: tuple[str, ...], option: str = "--out") -> None:
    """Refuse ``path`` unless a file with one of ``suffixes`` can be written there (its
    missing folders are created when it is written)."""
    if path.is_dir():
        raise OutputError(f"{option} {path}: is a folder; name a file in it, e.g. "
                          f"{path / ('out' + suffixes[0])}")
    if path.suffix.lower() not in suffixes:
        kinds = ", ".join(suffixes[:-1]) + f" or {suffixes[-1]}" if len(suffixes) > 1 \
            else suffixes[0]
        raise OutputError(f"{option} {path}: name a {kinds} file")
    folder = path.parent
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    if not folder.is_dir():
        raise OutputError(f"{option} {path}: {folder} is a file, not a folder")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise OutputError(f"{option} {path}: cannot write in {folder}")


@contextmanager
def written_whole(path: Path, option: str = "--out") -> Iterator[Path]:
    """A temporary path beside ``path`` to write to; renamed onto ``path`` (replacing it)
    when the block ends. An OS error is a user's error naming the option; the temporary
    file never stays behind."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with atomic_file(path) as tmp:
            yield tmp
    except OSError as exc:
        raise OutputError(f"{option} {path}: {exc.strerror or exc}") from None


def check_table_path(path: Path) -> None:
    """``check_out_file`` for a table; never inside a cells/ folder, where every Parquet
    file is read as a cell."""
    check_out_file(path, TABLES)
    if path.parent.name == "cells":
        raise OutputError(f"--out {path}: a cells/ folder holds only cell results; write "
                          "the table beside it")


def write_export(table, path: Path) -> None:
    """A pandas DataFrame as .csv or .parquet (by the suffix), written whole."""
    check_table_path(path)
    with written_whole(path) as tmp:
        if path.suffix.lower() == ".csv":
            table.to_csv(tmp, index=False)
        else:
            table.to_parquet(tmp, index=False)


def save_figure(fig, out: Path, dpi: int) -> None:
    """A matplotlib figure to ``out`` (its format from the suffix), written whole; the
    figure is closed either way."""
    import matplotlib.pyplot as plt

    try:
        with written_whole(out) as tmp:
            fig.savefig(tmp, format=out.suffix[1:].lower(), dpi=dpi)
    finally:
        plt.close(fig)
