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
    (``code``: default :func:`code_paths`) differs from it; None outside a git checkout.
    git itself is asked about the code files only, so any entry it lists is a change."""
    commit = _git("describe", "--always", "--abbrev=40")
    if commit is None:
        return None
    top = _git("rev-parse", "--show-toplevel")
    if top is None:
        return commit
    root = Path(top).resolve()
    code = code_paths() if code is None else [Path(p).resolve() for p in code]
    specs = [f":(glob){p}/**/*.py" if p.is_dir() else str(p)
             for p in code if p.is_relative_to(root)]
    results = Path(results_root).resolve()
    if results.is_relative_to(root):
        specs.append(f":(exclude){results}")
    status = _git("status", "--porcelain", "--untracked-files=all", "--", *specs,
                  ":(top,glob)**/pyproject.toml", ":(top,glob)**/constraints/*")
    if status is None:
        return commit
    return f"{commit}-dirty" if status else commit


def _git(*args: str) -> str | None:
    try:
        out = subprocess.run(["git", *args], capture_output=True, text=True, timeout=10,
                             check=False)
    except (OSError, subprocess.SubprocessError):
        return None
    if out.returncode != 0:
        return None
    return out.stdout.strip()


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
