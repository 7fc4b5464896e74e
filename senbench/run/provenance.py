"""Which code computed a run: the git commit, and whether the working tree had changes to
code that it does not hold.

``git describe --dirty`` calls a tree dirty for any change, results included: a run that
writes its own tracked result files (``--force``), or a docs edit beside a long run, made
every later run "dirty" though the code was committed. Here only a change that can alter
what a cell computes counts: a Python file, ``pyproject.toml`` or a constraints file,
outside the results root (tracked and changed, or new and not ignored).
"""

from __future__ import annotations

import subprocess
from pathlib import Path

CODE_FILES = (".py",)
CODE_NAMES = ("pyproject.toml",)
CODE_FOLDERS = ("constraints",)


def git_commit(results_root: Path) -> str | None:
    """The commit checked out where the command runs, with ``-dirty`` appended when code
    differs from it (see the module's text); None outside a git checkout."""
    commit = _git("describe", "--always", "--abbrev=40")
    if commit is None:
        return None
    top = _git("rev-parse", "--show-toplevel")
    status = _git("status", "--porcelain=v1", "-z", "--untracked-files=all")
    if top is None or status is None:
        return commit
    results = Path(results_root).resolve()
    changed = [Path(top) / path for path in _paths(status)]
    if any(is_code(path) and not path.resolve().is_relative_to(results) for path in changed):
        return f"{commit}-dirty"
    return commit


def is_code(path: Path) -> bool:
    return (path.suffix in CODE_FILES or path.name in CODE_NAMES
            or any(part in CODE_FOLDERS for part in path.parts[-2:-1]))


def _paths(status: str) -> list[str]:
    """The paths of ``git status --porcelain -z``: each entry 'XY path', a rename followed
    by its old path as an entry of its own (both count)."""
    paths, entries = [], status.split("\0")
    index = 0
    while index < len(entries):
        entry = entries[index]
        index += 1
        if len(entry) < 4:
            continue
        paths.append(entry[3:])
        if entry[0] in "RC" and index < len(entries):
            paths.append(entries[index])
            index += 1
    return paths


def _git(*args: str) -> str | None:
    try:
        out = subprocess.run(["git", *args], capture_output=True, text=True, timeout=10,
                             check=False)
    except (OSError, subprocess.SubprocessError):
        return None
    if out.returncode != 0:
        return None
    return out.stdout.strip("\n") if args[0] != "status" else out.stdout
