"""Which cells a run is computing, so that several runs of one suite on one machine (two
terminals, two batch jobs) share its grid and compute each cell once.

A run takes a cell's lock, ``.<cell_id>.lock`` beside the cell files, before it starts
the cell, and lets go once the cell's file is written. It passes over a cell that another
run holds, and one whose file another run wrote after this run started (finished, failed,
or redone under ``--force``), so no cell is computed twice by runs that overlap. The
kernel drops a dead process's locks, so a killed run holds nothing. The lock file names its
holder (``pid@host``) for ``senbench status``; the holder removes it on release, and a
stale one, left by a killed run, stops nobody.
"""

from __future__ import annotations

import errno
import fcntl
import os
import socket
import time
from pathlib import Path

import psutil

from senbench.errors import SenbenchError
from senbench.results.store import cell_path, finished_status

_NO_FLOCK = {errno.ENOLCK, errno.ENOSYS, errno.EOPNOTSUPP, errno.EINVAL}


def lock_path(directory: Path, cell_id: str) -> Path:
    return directory / f".{cell_id}.lock"


class CellClaims:
    """The cell locks one run holds in a cells folder."""

    def __init__(self, directory: Path, force: bool = False):
        self.directory = directory
        self.force = force
        self.since = time.time()
        """When this run started: a cell file written later is another run's."""
        self._held: dict[str, int] = {}
        """Cell id → the descriptor of its locked file."""

    def take(self, cell_id: str) -> bool:
        """Lock the cell for this run: False if another run holds it, or wrote its file
        since this run started, or (without ``force``) it is finished."""
        path = lock_path(self.directory, cell_id)
        fd = self._lock(path)
        if fd is None:
            return False
        try:
            if not self.free_to_run(cell_id):
                self._let_go(path, fd)
                return False
            os.ftruncate(fd, 0)
            os.write(fd, f"{os.getpid()}@{socket.gethostname()}\n".encode())
        except BaseException:
            self._let_go(path, fd)
            raise
        self._held[cell_id] = fd
        return True

    def free_to_run(self, cell_id: str) -> bool:
        """No other run wrote the cell's file since this one started, and (without
        ``force``) it is not finished."""
        try:
            written = cell_path(self.directory, cell_id).stat().st_mtime
        except FileNotFoundError:
            return True
        if written >= self.since:
            return False
        return self.force or finished_status(cell_path(self.directory, cell_id)) != "ok"

    def finished_elsewhere(self, cell_id: str) -> bool:
        """The cell's file records ``ok`` (written since this run started, under
        ``force``): a cell this run passed over needs no other run."""
        path = cell_path(self.directory, cell_id)
        try:
            fresh = path.stat().st_mtime >= self.since
        except FileNotFoundError:
            return False
        return (fresh or not self.force) and finished_status(path) == "ok"

    def release(self, cell_id: str) -> None:
        # Forgotten first: an interrupt between the two leaks a descriptor (the kernel drops
        # its lock when the run exits), never closes one twice (by then maybe another file's)
        fd = self._held.pop(cell_id, None)
        if fd is not None:
            self._let_go(lock_path(self.directory, cell_id), fd)

    def release_all(self) -> None:
        for cell_id in list(self._held):
            self.release(cell_id)

    @staticmethod
    def _lock(path: Path) -> int | None:
        """A descriptor of ``path`` locked by this process, or None if another holds it."""
        while True:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                os.close(fd)
                return None
            except OSError as exc:
                os.close(fd)
                if exc.errno in _NO_FLOCK:
                    raise SenbenchError(
                        f"{path.parent}: this file system does not support flock, which lets "
                        "runs share a suite; put the results on a local disk (--results)"
                    ) from None
                raise
            except BaseException:
                os.close(fd)
                raise
            try:
                same = os.stat(path).st_ino == os.fstat(fd).st_ino
            except FileNotFoundError:
                same = False
            except BaseException:
                os.close(fd)
                raise
            if same:
                return fd
            os.close(fd)  # its holder let go and removed it meanwhile: lock the new file

    @staticmethod
    def _let_go(path: Path, fd: int) -> None:
        try:
            path.unlink(missing_ok=True)  # while still locked: see _lock's inode check
        finally:
            os.close(fd)


def running_cells(directory: Path) -> set[str]:
    """Cells whose lock file names a holder that is running: a live process on this host
    (started before it wrote the file: not a reused pid), or any process on another host,
    whose liveness this host cannot see (a killed run there leaves its lock files)."""
    here = socket.gethostname()
    running = set()
    for path in directory.glob(".*.lock"):
        try:
            pid, _, host = path.read_text(errors="replace").strip().partition("@")
            written = path.stat().st_mtime
        except OSError:
            continue
        if not pid.isdigit():
            continue  # being written
        if host != here or _started_before(int(pid), written):
            running.add(path.name[1:-len(".lock")])
    return running


def _started_before(pid: int, when: float) -> bool:
    try:
        process = psutil.Process(pid)
        return process.status() != psutil.STATUS_ZOMBIE and process.create_time() <= when + 1
    except psutil.Error:
        return False
