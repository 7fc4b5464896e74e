"""Checking a suite's values against the config classes of the plugins they name: each
value strictly against its field's type and declared range, each problem at its own key.
"""

from __future__ import annotations

import dataclasses
import reprlib
import typing
from typing import Any

import pydantic

from senbench.errors import unknown_name_message
from senbench.plugin.registry import Registries
from senbench.suite.source import Loc

_REPR = reprlib.Repr()  # keyword arguments only from Python 3.12
_REPR.maxlevel, _REPR.maxstring, _REPR.maxother, _REPR.maxlist, _REPR.maxdict = 2, 60, 60, 4, 4


def show(value: Any) -> str:
    """A short repr: a value built from YAML aliases can be recursive, or huge."""
    return _REPR.repr(value)


def resolve_config(agent, params: dict[str, Any], where, problem) -> dict[str, Any] | None:
    return _resolve_dataclass(agent.config, f"{agent.name} hyperparameter", params, where,
                              problem)


def resolve_encoder(encoder: dict[str, Any], regs: Registries, method_name: str,
                     problem) -> dict[str, Any] | None:
    """The encoder entry with its architecture's and sampler's configs checked and
    completed with their defaults."""
    resolved = dict(encoder)
    for key, registry, name in (("config", regs.encoders, encoder["arch"]),
                                ("sampler_config", regs.samplers, encoder["sampler"])):
        spec = registry.get(name)

        def where(field: str, key: str = key) -> Loc:
            return ("methods", method_name, "encoder", key, field)

        values = _resolve_dataclass(spec.config, f"{name} setting", encoder[key], where, problem)
        if values is None:
            return None
        resolved[key] = values
    return resolved


def _resolve_dataclass(config_cls, what: str, params: dict[str, Any], where,
                       problem) -> dict[str, Any] | None:
    """A config dataclass from its defaults and ``params``, each value checked strictly
    against the field's type (no "2000" for an int, no true for a number) and the range it
    declares (``Annotated[int, Field(ge=1)]``), every problem at its own key; then the
    config's checks across fields (``__post_init__``, or a pydantic dataclass's validators).
    A plain dataclass range-checking in ``__post_init__`` works too, reported less exactly."""
    hints = typing.get_type_hints(config_cls, include_extras=True)
    fields = [f.name for f in dataclasses.fields(config_cls)]
    values, ok = {}, True
    for key, value in params.items():
        if key not in fields:
            problem(where(key), unknown_name_message(what, key, fields))
            ok = False
            continue
        try:
            values[key] = pydantic.TypeAdapter(hints[key]).validate_python(value, strict=True)
        except pydantic.ValidationError as exc:
            ok = False
            errors = exc.errors()
            wrong_type = next((e for e in errors if e["type"].endswith("_type")), None)
            if wrong_type is not None:
                problem(where(key), f"expected {_type_name(hints[key])}: {wrong_type['msg']} "
                        f"(got {show(value)})")
                continue
            for err in errors:  # out of range: pydantic's message, for each value that is
                item = f"item {'.'.join(map(str, err['loc']))}: " if err["loc"] else ""
                problem(where(key), f"{item}{err['msg']} (got {show(err.get('input'))})")
    if not ok:
        return None
    try:
        config = config_cls(**values)
    except (ValueError, TypeError) as exc:
        if isinstance(exc, pydantic.ValidationError):  # a pydantic dataclass's own checks
            messages = [str(e["ctx"]["error"]) if "error" in e.get("ctx", {}) else
                        f"{'.'.join(map(str, e['loc'])) + ': ' if e['loc'] else ''}{e['msg']}"
                        for e in exc.errors()]
        else:
            messages = [str(exc)]
        for message in messages:
            # the first field set here that the message names, word for word
            words = "".join(c if c.isalnum() or c == "_" else " " for c in message).split()
            culprit = next((w for w in words if w in values), None)
            problem(where(culprit) if culprit else where("")[:-1], message)
        return None
    return dataclasses.asdict(config)


def _type_name(annotation: Any) -> str:
    origin = typing.get_origin(annotation)
    if origin is typing.Annotated:  # a type with a declared range: the type is the part named
        return _type_name(typing.get_args(annotation)[0])
    if origin is typing.Literal:
        return " or ".join(repr(arg) for arg in typing.get_args(annotation))
    return getattr(annotation, "__name__", None) or str(annotation)


def fits(value: Any, expected: type) -> bool:
    if expected is float:
        return isinstance(value, int | float) and not isinstance(value, bool)
    return isinstance(value, expected)
