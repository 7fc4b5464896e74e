"""Reading a suite file: YAML with a SafeLoader, plus where each key sits in the file.

Errors must point at a line. PyYAML's composer (no constructors run, so it is as safe as
``safe_load``) keeps the line of every node; we map key paths to lines, and refuse duplicate
keys, which ``safe_load`` would silently resolve to the last one.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import yaml

from senbench.errors import SuiteError

Loc = tuple[Any, ...]


class SuiteLoader(yaml.SafeLoader):
    """``yaml.SafeLoader`` (no Python objects, ever) that also reads ``1e-3`` as a number.
    PyYAML follows YAML 1.1, where a float needs a dot: ``learning_rate: 1e-3`` would be
    the string "1e-3", and a typed hyperparameter would be refused."""


SuiteLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"),
    list("-+0123456789"),
)


class SuiteSource:
    """A suite file's data and the line of each key path in it."""

    def __init__(self, path: Path, data: Any, lines: dict[Loc, int]):
        self.path = path
        self.data = data
        self.lines = lines

    def where(self, loc: Loc) -> str:
        """``file:line`` for the deepest prefix of ``loc`` found in the file."""
        for end in range(len(loc), -1, -1):
            line = self.lines.get(tuple(loc[:end]))
            if line is not None:
                return f"{self.path}:{line}"
        return str(self.path)


def read_suite_file(path: str | Path) -> SuiteSource:
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise SuiteError(f"{path}: no such suite file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise SuiteError(f"{path}: cannot read the suite file: {exc}") from None
    try:
        root = yaml.compose(text, Loader=SuiteLoader)
        data = yaml.load(text, Loader=SuiteLoader)  # noqa: S506 - a SafeLoader subclass
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line = f":{mark.line + 1}" if mark is not None else ""
        raise SuiteError(f"{path}{line}: not valid YAML: {exc.problem or exc}") from None
    except yaml.YAMLError as exc:
        raise SuiteError(f"{path}: not valid YAML: {exc}") from None
    lines: dict[Loc, int] = {}
    if root is not None:
        _index(root, (), lines, path, set())
    return SuiteSource(path, data, lines)


def _index(node: yaml.Node, loc: Loc, lines: dict[Loc, int], path: Path,
           seen: set[int]) -> None:
    """Each node once: a YAML alias points back to a node already indexed, so neither a
    self-referencing alias nor nested ones ("billion laughs") make this loop or explode."""
    if id(node) in seen:
        return
    seen.add(id(node))
    lines.setdefault(loc, node.start_mark.line + 1)
    if isinstance(node, yaml.MappingNode):
        first_line: dict[Any, int] = {}
        for key_node, value_node in node.value:
            key = key_node.value
            line = key_node.start_mark.line + 1
            if key in first_line:
                dotted = ".".join(str(p) for p in (*loc, key))
                raise SuiteError(
                    f"{path}:{line}: key '{dotted}' appears twice (first on line "
                    f"{first_line[key]}); keep one"
                )
            first_line[key] = line
            lines[(*loc, key)] = line
            _index(value_node, (*loc, key), lines, path, seen)
    elif isinstance(node, yaml.SequenceNode):
        for i, item in enumerate(node.value):
            _index(item, (*loc, i), lines, path, seen)
