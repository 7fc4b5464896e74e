"""The one way senbench writes a file or a folder that readers may see at any moment: into a
temporary name beside it, then renamed into place. A reader finds the old version or the
new one, never half of one, and a killed writer leaves only a temporary name, which
:func:`senbench.results.store.remove_stray_temp_files` recognises by its pattern
``.<stem>.<pid>[-<host>].tmp``."""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


@contextmanager
def atomic_file(path: Path, stem: str | None = None, tag: str | None = None,
                durable: bool = False) -> Iterator[Path]:
    """A temporary path beside ``path`` to write to, renamed onto ``path`` (replacing it)
    when the block ends without an error; it never stays behind. ``stem`` and ``tag`` name
    the temporary file (default: the file's name and this process's id). ``durable``: the
    file and the rename are flushed to disk (fsync), so that they survive a power loss."""
    tmp = path.with_name(f".{stem or path.name}.{tag or os.getpid()}.tmp")
    try:
        yield tmp
        if durable:
            _fsync(tmp, os.O_RDONLY)
        os.replace(tmp, path)
        if durable:
            _fsync(path.parent, os.O_RDONLY)
    finally:
        tmp.unlink(missing_ok=True)


@contextmanager
def atomic_folder(target: Path) -> Iterator[Path | None]:
    """A temporary folder beside ``target`` to fill, renamed to ``target`` when the block
    ends; None (nothing to do) if ``target`` is there already. If another process puts
    ``target`` there meanwhile, its folder is kept and this one is dropped."""
    if target.exists():
        yield None
        return
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.", dir=target.parent))
    try:
        yield tmp
        try:
            os.rename(tmp, target)
        except OSError:  # another process got there first
            pass
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _fsync(path: Path, flags: int) -> None:
    try:
        fd = os.open(path, flags)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)
