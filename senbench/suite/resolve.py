"""Checking a suite's values against the config classes of the plugins they name: each
value strictly against its field's type and declared range, each problem at its own key.
"""

from __future__ import annotations

import dataclasses
import math
import reprlib
import typing
from typing import Any

import pydantic

from senbench.errors import UnknownNameError, unknown_name_message
from senbench.plugin.registry import Registries
from senbench.plugin.specs import narrow
from senbench.suite.source import Loc

_REPR = reprlib.Repr()  # keyword arguments only from Python 3.12
_REPR.maxlevel, _REPR.maxstring, _REPR.maxother, _REPR.maxlist, _REPR.maxdict = 2, 60, 60, 4, 4


def show(value: Any) -> str:
    """A short repr: a value built from YAML aliases can be recursive, or huge."""
    return _REPR.repr(value)


def resolve_config(agent, params: dict[str, Any], where, problem) -> dict[str, Any] | None:
    return _resolve_dataclass(agent.config, f"{agent.name} hyperparameter", params, where,
                              problem)


def resolve_encoder(encoder: dict[str, Any], regs: Registries, where,
                     problem) -> dict[str, Any] | None:
    """The encoder entry with its architecture's and sampler's configs checked and
    completed with their defaults. ``where(key, field="")`` is where the encoder's ``key``
    (a field of it, for ``config`` and ``sampler_config``) is set. Every problem of the
    entry is reported, an unknown arch beside an unknown sampler or sampler setting."""
    resolved, ok = dict(encoder), True
    for key, registry, name_key in (("config", regs.encoders, "arch"),
                                    ("sampler_config", regs.samplers, "sampler")):
        name = encoder[name_key]
        if name not in registry:
            problem(where(name_key), registry.unknown_message(name))
            ok = False
            continue

        def at(field: str, key: str = key) -> Loc:
            return where(key, field)

        values = _resolve_dataclass(registry.get(name).config, f"{name} setting", encoder[key],
                                    at, problem)
        if values is None:
            ok = False
        else:
            resolved[key] = values
    return resolved if ok else None


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
            problem(where(key), unknown_name_message(what, key, fields) if fields else
                    f"unknown {what} '{key}': {what.rsplit(' ', 1)[0]} has none")
            ok = False
            continue
        if isinstance(value, float) and not math.isfinite(value):
            problem(where(key), f"expected a finite number, got {value}")  # no field wants one
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
    return without_late_defaults(config_cls, dataclasses.asdict(config))


def without_late_defaults(config_cls, values: dict[str, Any]) -> dict[str, Any]:
    """``values`` less the fields the config names in ``LATE_FIELDS`` (settings added after
    results were committed) where they hold their default: a cell that never sets one keeps
    the id it had before the field existed. The agent's config fills them in again."""
    late = getattr(config_cls, "LATE_FIELDS", ())
    defaults = {f.name: f.default for f in dataclasses.fields(config_cls) if f.name in late}
    return {k: v for k, v in values.items() if not (k in defaults and v == defaults[k])}


def _type_name(annotation: Any) -> str:
    origin = typing.get_origin(annotation)
    if origin is typing.Annotated:  # a type with a declared range: the type is the part named
        return _type_name(typing.get_args(annotation)[0])
    if origin is typing.Literal:
        return " or ".join(repr(arg) for arg in typing.get_args(annotation))
    return getattr(annotation, "__name__", None) or str(annotation)


def fits(value: Any, expected: type) -> bool:
    if expected is float:
        return (isinstance(value, int | float) and not isinstance(value, bool)
                and math.isfinite(value))
    return isinstance(value, expected)


# Capabilities: what a plugin needs (agent, encoder architecture, sampler) against what the
# env offers and the frames are, so that a cell that cannot run fails validation, not a run.

_UNBOUNDED: dict[int, tuple[Any, tuple[str, ...] | str]] = {}
"""id(env spec) → (the spec, kept so the id stays its own; its unbounded dimensions, or why
they could not be read). Reading them builds an env: once per env per process."""


def _unbounded(env_spec: Any) -> tuple[str, ...] | str:
    cached = _UNBOUNDED.get(id(env_spec))
    if cached is None or cached[0] is not env_spec:
        try:
            found: tuple[str, ...] | str = env_spec.unbounded_dimensions()
        except Exception as exc:  # noqa: BLE001 - a plugin's make() failing is a problem
            found = f"{type(exc).__name__}: {exc}"
        cached = _UNBOUNDED[id(env_spec)] = (env_spec, found)
    return cached[1]


def check_capabilities(agent: Any, env_name: str, env_spec: Any, observation: str,
                       pixels: Any, hyperparams: dict[str, Any] | None,
                       encoder: dict[str, Any] | None, regs: Registries, at, problem) -> None:
    """Report each thing the agent (with ``hyperparams``, resolved; None where they failed
    their own checks), the encoder's architecture or its sampler needs that
    the env or the frames do not give. ``at(what)`` is where ``what`` is set: "agent",
    "observation", "pixels", "pixels.renderer", "encoder.arch", "encoder.sampler"."""
    offers = env_spec.capabilities()
    if observation == "encoded" and "observe" not in offers:
        problem(at("observation"), f"env '{env_name}' has no observe(): an encoded "
                "observation needs one (its encoder learns to predict it); use observation: "
                "pixels or state, restrict the method with 'envs: [...]', or add observe to "
                "the env plugin")
    if observation in ("state", "encoded") and agent.needs_bounded_observations:
        unbounded = _unbounded(env_spec)
        if isinstance(unbounded, str):
            problem(at("agent"), f"agent '{agent.name}' needs finite observation bounds, but "
                    f"env '{env_name}' could not be built to read them: {unbounded}")
        elif unbounded:
            problem(at("agent"), f"agent '{agent.name}' needs finite observation bounds (its "
                    f"spec declares needs_bounded_observations), but env '{env_name}' has "
                    f"infinite ones "
                    f"on {', '.join(unbounded)}; restrict the method with 'envs: [...]', use "
                    "another agent, or give the env plugin an observation space with finite "
                    "bounds")
    configured = callable(agent.min_frame_size)
    if observation == "pixels" and agent.min_frame_size and (hyperparams is not None
                                                             or not configured):
        try:
            smallest = (agent.min_frame_size_for(agent.config(**hyperparams)) if configured
                        else agent.min_frame_size)
        except Exception as exc:  # noqa: BLE001 - a plugin's function failing is a problem
            problem(at("agent"), f"agent '{agent.name}': min_frame_size failed: {exc!r}")
            smallest = None
        if smallest:
            _check_frames(f"agent '{agent.name}'" + (" with these hyperparams" if configured
                                                      else ""), smallest, pixels,
                          ", or change its hyperparams" if configured else "", at("pixels"),
                          problem)
    pixels_only = [f for f in getattr(agent.config, "PIXEL_FIELDS", ()) if f in (hyperparams or {})]
    if observation != "pixels" and pixels_only:  # resolved: only a late field set off its default
        named = " and ".join(pixels_only) + (" only act" if len(pixels_only) > 1 else " only acts")
        problem(at("hyperparams"), f"agent '{agent.name}': {named} on pixels (the CNN), and "
                f"this method learns on {observation}; remove it, or use observation: pixels")
    if encoder is None:
        return
    arch = regs.encoders.get(encoder["arch"])
    try:
        smallest = arch.min_frame_size_for(arch.config(**encoder["config"]))
    except Exception as exc:  # noqa: BLE001 - a plugin's function failing is a problem
        problem(at("encoder.arch"), f"encoder '{arch.name}': min_frame_size failed: {exc!r}")
        smallest = None
    if smallest:
        who = f"encoder '{arch.name}'" + (" with this config" if callable(arch.min_frame_size)
                                          else "")
        _check_frames(who, smallest, pixels, ", or use another arch", at("pixels"), problem)
    _check_sampler(regs, encoder["sampler"], env_name, offers, pixels, at, problem)


def _check_frames(who: str, smallest: int, pixels: Any, other_fix: str, loc: Loc,
                  problem) -> None:
    height, width = pixels.size
    if min(height, width) < smallest:
        problem(loc, f"{who} needs frames of at least {smallest}x{smallest}, got "
                f"{height}x{width}; set pixels: {{height: {max(height, smallest)}, width: "
                f"{max(width, smallest)}}} or more{other_fix}")


def _check_sampler(regs: Registries, name: str, env_name: str, offers: frozenset[str],
                   pixels: Any, at, problem) -> None:
    def usable(sampler: Any) -> bool:  # observe is the encoded observation's to report
        needs = set(sampler.needs) - {"observe"}
        return needs <= offers and not ("render" in needs and pixels.renderer == "gymnasium")

    others = [n for n in regs.samplers.names() if n != name and usable(regs.samplers.get(n))]
    instead = f"sampler: {' or '.join(others)}" if others else "another sampler"
    sampler = regs.samplers.get(name)
    missing = sorted(set(sampler.needs) - {"observe"} - offers)
    if missing:
        functions = " and no ".join(f"{m}()" for m in missing)
        problem(at("encoder.sampler"), f"env '{env_name}' has no {functions}: the {name} "
                f"sampler needs {'them' if len(missing) > 1 else 'it'}; use {instead}, or add "
                f"{' and '.join(missing)} to the env plugin")
    elif "render" in sampler.needs and pixels.renderer == "gymnasium":
        problem(at("pixels.renderer"), f"the {name} sampler draws frames with the env "
                "plugin's render(), but these observations come from gymnasium's render() "
                f"(renderer: gymnasium); use renderer: auto, or {instead}")


def check_batchable(method_name: str, method: Any, model: Any, agent: Any, regs: Registries,
                    problem) -> bool:
    """A seed batch shares an encoder's passes: it needs an encoded observation and an agent
    that can run beside other seeds in one process (fewer seeds than B run padded)."""
    where = (("methods", method_name, "seed_batch") if method.seed_batch is not None
             else ("seed_batch",))
    fix = (f"set seed_batch: 1 for method '{method_name}'"
           if method.seed_batch is None or model.seed_batch > 1 else "remove its seed_batch")
    if method.observation != "encoded":
        problem(where, f"seed_batch batches an encoder's passes, and method '{method_name}' "
                f"observes {method.observation}, not encoded: {fix}")
        return False
    if not agent.seed_batching:
        able = sorted(n for n in regs.agents.names() if regs.agents.get(n).seed_batching)
        problem(where, f"agent '{agent.name}' cannot run beside other seeds in one process "
                "(its spec does not declare seed_batching: an agent that draws from "
                "process-global random generators must not); agents that can: "
                f"{', '.join(able) or 'none'}. {fix[0].upper()}{fix[1:]}")
        return False
    return True


def check_tune(model: Any, regs: Registries, problem) -> None:
    """The suite's ``tune:`` block: each method a method of the suite, each name one it
    searches, each range within (and of the kind of) what its agent or encoder declares."""
    for method_name, ranges in model.tune.items():
        if method_name not in model.methods:
            known = list(model.methods)
            problem(("tune", method_name), unknown_name_message("method", method_name, known))
            continue
        entry = model.methods[method_name]
        searched = {}
        if entry.agent in regs.agents:
            searched |= regs.agents.get(entry.agent).search_space
        if entry.encoder is not None and entry.encoder.arch in regs.encoders:
            searched |= {f"encoder.{name}": param for name, param
                         in regs.encoders.get(entry.encoder.arch).search_space.items()}
        for name, narrower in ranges.items():
            if name not in searched:
                problem(("tune", method_name, name), f"'{method_name}' searches "
                        f"{', '.join(sorted(searched)) or 'nothing'}; not {name!r}")
                continue
            if name in entry.hyperparams:
                problem(("tune", method_name, name), f"not searched: the method fixes it in "
                        f"hyperparams ({name}: {entry.hyperparams[name]!r})")
                continue
            field = name.removeprefix("encoder.")
            if field != name and field in entry.encoder.config:
                problem(("tune", method_name, name), "not searched: the method fixes it in "
                        f"its encoder's config ({field}: {entry.encoder.config[field]!r})")
                continue
            try:
                narrow(searched[name], narrower.low, narrower.high, narrower.values)
            except ValueError as exc:
                problem(("tune", method_name, name), str(exc))


def memory_format_of(model: Any, method_name: str, method: Any, agent: Any,
                   regs: Registries, problem) -> str | None:
    """The method's layout: contiguous on the state, whose networks have no convolutions
    (so the key moves no state cell's id); else the method's or the suite's, if its agent
    and its encoder offer it (None, with the problem, if not)."""
    asked = method.memory_format or model.memory_format
    if method.observation == "state" or asked == "contiguous":
        return "contiguous"
    at: Loc = (("methods", method_name, "memory_format") if method.memory_format else
               ("memory_format",))
    offers = [(f"agent '{agent.name}'", agent.memory_formats)]
    if method.observation == "encoded" and method.encoder is not None:
        try:
            arch = regs.encoders.get(method.encoder.arch)
            offers.append((f"encoder '{arch.name}'", arch.memory_formats))
        except UnknownNameError:
            pass  # reported where the encoder is checked
    for who, formats in offers:
        if asked not in formats:
            problem(at, f"{who} offers memory_format {' or '.join(sorted(formats))}, not "
                    f"{asked} (its spec's memory_formats); set memory_format: contiguous "
                    f"for method '{method_name}'")
            return None
    return asked


def action_repeat_of(model: Any, method_name: str, method: Any, env_name: str, env_entry: Any,
                     problem) -> int | None:
    """Frames each of the method's actions is held for on the env: its own, else the env's;
    None, with the problem, for an encoded method (its encoder learns from consecutive
    frames) or a budget or ``eval.every`` that is not a whole number of decisions."""
    repeat = method.action_repeat or env_entry.action_repeat
    at: Loc = (("methods", method_name, "action_repeat") if method.action_repeat
               else ("envs", env_name, "action_repeat"))
    if method.observation == "encoded" and repeat > 1:
        problem(at, f"method '{method_name}' observes through a state encoder, which learns "
                "from stacks of consecutive frames, so it takes no action repeat; set "
                f"action_repeat: 1 for it on {env_name}")
        return None
    for what, frames in (("budget", env_entry.budget or model.budget),
                         ("eval.every", model.eval.every)):
        if frames % repeat:
            problem(at, f"method '{method_name}' holds each action {repeat} frames on "
                    f"{env_name}, so its {what} ({frames} frames) must be a multiple of "
                    f"{repeat}; change one of the two")
            return None
    return repeat
