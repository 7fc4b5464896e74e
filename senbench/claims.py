"""Which cells a run is computing, so that several runs of one suite can share its grid:
two terminals, or batch jobs on one machine or on a disk they share that supports
``flock`` (local disks, NFSv4).

A run takes a cell's lock, ``.<cell_id>.lock`` beside the cell files, before it starts
the cell, and lets go once the cell's file is written. A cell another run holds is passed
over, and so is one that another run finished since this run looked (unless ``force``).
The kernel drops a dead process's locks, so a killed run holds nothing. The lock file names
its holder (``pid@host``) for ``senbench status``; it is removed on release, and a stale
one, left by a killed run, stops nobody.
"""

from __future__ import annotations

import fcntl
import os
import socket
from pathlib import Path

from senbench.results import cell_path, finished_status, process_alive


def lock_path(directory: Path, cell_id: str) -> Path:
    return directory / f".{cell_id}.lock"


class CellClaims:
    """The cell locks one run holds in a cells folder."""

    def __init__(self, directory: Path, force: bool = False):
        self.directory = directory
        self.force = force
        self._held: dict[str, int] = {}
        """Cell id → the descriptor of its locked file."""

    def take(self, cell_id: str) -> bool:
        """Lock the cell for this run: False if another run holds it, or (without ``force``)
        finished it since this run made its list."""
        path = lock_path(self.directory, cell_id)
        while True:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                os.close(fd)
                return False
            try:
                same = os.stat(path).st_ino == os.fstat(fd).st_ino
            except FileNotFoundError:
                same = False
            if same:
                break
            os.close(fd)  # its holder released and removed it meanwhile: lock the new file
        if not self.force and finished_status(cell_path(self.directory, cell_id)) == "ok":
            self._let_go(path, fd)
            return False
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}@{socket.gethostname()}\n".encode())
        self._held[cell_id] = fd
        return True

    def release(self, cell_id: str) -> None:
        fd = self._held.pop(cell_id, None)
        if fd is not None:
            self._let_go(lock_path(self.directory, cell_id), fd)

    def release_all(self) -> None:
        for cell_id in list(self._held):
            self.release(cell_id)

    @staticmethod
    def _let_go(path: Path, fd: int) -> None:
        path.unlink(missing_ok=True)  # while still locked: see take's inode check
        os.close(fd)


def running_cells(directory: Path) -> set[str]:
    """Cells whose lock file names a holder that may still be running: a live process on
    this host, or any process on another (whose liveness this host cannot see)."""
    here = socket.gethostname()
    running = set()
    for path in directory.glob(".*.lock"):
        try:
            pid, _, host = path.read_text().strip().partition("@")
        except OSError:
            continue
        if not pid.isdigit():
            continue  # being written, or not ours
        if host != here or process_alive(int(pid)):
            running.add(path.name[1:-len(".lock")])
    return running

