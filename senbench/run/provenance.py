"""Which code computed a run: the git commit, and whether the working tree had changes to
code that it does not hold.

``git describe --dirty`` calls a tree dirty for any change, results included: a run that
writes its own tracked result files (``--force``), or a docs edit beside a long run, made
every later run "dirty" though the code was committed. Here only a change that can alter
what a cell computes counts (tracked and changed, or new and not ignored): a Python file of
senbench or of a plugin the run loads (their package folders), ``pyproject.toml`` or a
constraints file. A test, a benchmark or a result file written beside a run does not.
"""

from __future__ import annotations

import functools
import hashlib
import importlib
import subprocess
import sys
from pathlib import Path

CODE_NAMES = ("pyproject.toml",)
CODE_FOLDERS = ("constraints",)


def code_paths() -> list[Path]:
    """Where the code a run executes lives: senbench's package folder and each loaded
    plugin's (its package folder, or its file for a one-file module)."""
    import senbench
    from senbench.plugin import manager

    paths = [Path(senbench.__file__).parent]
    names = [name for name, _, _ in manager.registered_module_names()]
    for name in manager.entry_point_modules() + names:
        module = sys.modules.get(name)
        if module is None:
            try:
                module = importlib.import_module(name)
            except ImportError:  # registered in a notebook: no file, no checkout to read
                continue
        file = getattr(module, "__file__", None)
        if file:
            path = Path(file)
            paths.append(path.parent if path.name == "__init__.py" else path)
    return [p.resolve() for p in paths]


def git_commit(results_root: Path, code: list[Path] | None = None) -> str | None:
    """The commit checked out where the command runs, with ``-dirty`` appended when code
    (``code``: default :func:`code_paths`) differs from it; None outside a git checkout."""
    commit = _git("describe", "--always", "--abbrev=40")
    if commit is None:
        return None
    top = _git("rev-parse", "--show-toplevel")
    if top is None:
        return commit
    code = code_paths() if code is None else [Path(p).resolve() for p in code]
    inside = [str(p) for p in code if p.is_relative_to(Path(top).resolve())]
    status = _git("status", "--porcelain=v1", "-z", "--untracked-files=all", "--",
                  *inside, ":(top,glob)**/pyproject.toml", ":(top,glob)**/constraints/*")
    if status is None:
        return commit
    results = Path(results_root).resolve()
    changed = [(Path(top) / path).resolve() for path in _paths(status)]
    if any(is_code(path, code) and not path.is_relative_to(results) for path in changed):
        return f"{commit}-dirty"
    return commit


def is_code(path: Path, code: list[Path]) -> bool:
    if path.name in CODE_NAMES or path.parent.name in CODE_FOLDERS:
        return True
    return path.suffix == ".py" and any(path == p or path.is_relative_to(p) for p in code)


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


@functools.cache
def cpu_description() -> str | None:
    """The processor a run computed on: its model, family/model/stepping, the instruction
    set torch dispatches to, and a digest of its feature flags. The math libraries pick
    their kernels by these, and kernels differ in their last bits, which a learner's
    feedback loop grows into another curve: a cell reproduces bit for bit on a machine with
    the same description, not necessarily on another. None where /proc/cpuinfo is not."""
    try:
        text = Path("/proc/cpuinfo").read_text()
    except OSError:
        return None
    fields: dict[str, str] = {}
    for line in text.splitlines():
        if not line.strip():
            break  # the first processor's block; the others are the same chip
        key, _, value = line.partition(":")
        fields[key.strip()] = value.strip()
    try:
        import torch

        capability = torch.backends.cpu.get_cpu_capability()
    except (ImportError, AttributeError):
        capability = "?"
    flags = " ".join(sorted(fields.get("flags", "").split()))
    digest = hashlib.sha256(flags.encode()).hexdigest()[:8]
    return (f"{fields.get('model name', '?')} (family {fields.get('cpu family', '?')} "
            f"model {fields.get('model', '?')} stepping {fields.get('stepping', '?')}), "
            f"torch {capability}, flags {digest}")
