"""Suites: a YAML grid of comparisons, validated, expanded into cells (:mod:`senbench.suite.cell`).

Every problem of a suite is found in one pass and reported together, each with its file,
line and key path; nothing runs until there are none.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pydantic
from pydantic import BaseModel

from senbench.encoders import EncoderRequest
from senbench.errors import SuiteError, unknown_name_message
from senbench.observe.observations import OBSERVATIONS
from senbench.observe.pixels import PixelSpec
from senbench.plugin.registry import Registries
from senbench.suite.cell import Cell
from senbench.suite.resolve import (
    action_repeat_of,
    check_batchable,
    check_capabilities,
    check_tune,
    fits,
    memory_format_of,
    resolve_config,
    resolve_encoder,
    show,
)
from senbench.suite.schema import EncoderEntry, MethodEntry, SuiteModel
from senbench.suite.source import Loc, SuiteSource, read_suite_file


@dataclass
class Suite:
    model: SuiteModel
    source: SuiteSource
    cells: list[Cell]

    @property
    def name(self) -> str:
        return self.model.name

    def select(self, methods: list[str] = (), envs: list[str] = (), seeds: list[int] = (),
               variants: list[str] = ()) -> list[Cell]:
        """The cells of the given methods, envs, seeds and variants (each empty: all; a
        variant as ``path=value`` pairs, e.g. ``encoder.fraction=0.5``). A name the suite
        does not have is an error that lists those it has."""
        for what, asked, have in (("method", methods, {c.method for c in self.cells}),
                                  ("env", envs, {c.env for c in self.cells}),
                                  ("seed", seeds, {c.seed for c in self.cells}),
                                  ("variant", variants,
                                   {c.variant for c in self.cells if c.variant})):
            unknown = [a for a in asked if a not in have]
            if unknown and not have:
                raise SuiteError(f"suite '{self.name}' has no {what}s")
            if unknown:
                raise SuiteError(
                    f"suite '{self.name}' has no {what} "
                    f"{', '.join(repr(u) for u in unknown)}; it has: "
                    f"{', '.join(str(h) for h in sorted(have))}")
        picked = [c for c in self.cells
                  if (not methods or c.method in methods) and (not envs or c.env in envs)
                  and (not seeds or c.seed in seeds)
                  and (not variants or c.variant in variants)]
        if not picked:
            raise SuiteError(f"suite '{self.name}' has no cell that is of the picked methods, "
                             "envs, seeds and variants at once (is the variant another "
                             "method's?)")
        return picked


def load_suite(path: str | Path, registries: Registries) -> Suite:
    """Read, validate and expand a suite; raise SuiteError listing every problem found."""
    source = read_suite_file(path)
    if not isinstance(source.data, dict):
        raise SuiteError(f"{source.path}: a suite is a YAML mapping (name, envs, methods, ...)")
    try:
        model = SuiteModel.model_validate(source.data)
    except pydantic.ValidationError as exc:
        raise SuiteError(_format_pydantic(exc, source)) from None
    problems: list[str] = []
    cells = _expand(model, source, registries, problems)
    if problems:
        raise SuiteError(_join(source, list(dict.fromkeys(problems))))
    return Suite(model, source, cells)


def _join(source: SuiteSource, problems: list[str]) -> str:
    head = f"{source.path}: {len(problems)} problem{'s' if len(problems) > 1 else ''}"
    return head + "\n" + "\n".join(f"  {p}" for p in problems)




def _dotted(loc: Loc) -> str:
    return ".".join(str(p) for p in loc if p != "")


def _format_pydantic(exc: pydantic.ValidationError, source: SuiteSource) -> str:
    problems = []
    for err in exc.errors():
        loc = tuple(err["loc"])
        if err["type"] == "extra_forbidden":
            known = _fields_at(loc[:-1])
            msg = unknown_name_message("key", str(loc[-1]), known)
        elif err["type"] == "missing":
            msg = "required key is missing"
        else:
            msg = f"{err['msg']} (got {show(err.get('input'))})"
        problems.append(f"{source.where(loc)}: {_dotted(loc) or '(top level)'}: {msg}")
    return _join(source, problems)


def _fields_at(loc: Loc) -> list[str]:
    """The keys allowed at ``loc`` in the suite schema, for "did you mean" on typos."""
    model: Any = SuiteModel
    rest = list(loc)
    while rest:
        part = rest.pop(0)
        annotation = model.model_fields[part].annotation
        while True:
            args = [a for a in getattr(annotation, "__args__", ()) if a is not type(None)]
            if isinstance(annotation, type) and issubclass(annotation, BaseModel):
                model = annotation
                break
            if getattr(annotation, "__origin__", None) is dict and rest:
                rest.pop(0)  # a user-chosen key (an env or method name)
                annotation = args[1]
            elif args:
                annotation = args[0]
            else:
                return []
    return list(model.model_fields)


def _expand(model: SuiteModel, source: SuiteSource, regs: Registries, problems: list[str]):
    def problem(loc: Loc, msg: str) -> None:
        problems.append(f"{source.where(loc)}: {_dotted(loc)}: {msg}")

    envs = _check_envs(model, regs, problem)
    for method_name in model.variants:
        if method_name not in model.methods:
            known = list(model.methods)
            problem(("variants", method_name), unknown_name_message("method", method_name, known))
    for method_name, by_env in model.references.items():
        if method_name not in model.methods:
            problem(("references", method_name),
                    unknown_name_message("method", method_name, list(model.methods)))
            continue
        runs_on = model.methods[method_name].envs or list(model.envs)
        for env_name in by_env:
            if env_name not in model.envs:
                problem(("references", method_name, env_name),
                        unknown_name_message("suite env", env_name, list(model.envs)))
            elif env_name not in runs_on:  # it could never be read beside a result
                problem(("references", method_name, env_name),
                        f"{method_name} does not run on {env_name} (its envs: "
                        f"{', '.join(runs_on)}); key the reference by one of them, or add "
                        f"{env_name} to the method's envs")
    check_tune(model, regs, problem)
    cells: list[Cell] = []
    for method_name, method in model.methods.items():
        agent = _check_method(method_name, method, regs, problem)
        if agent is None:
            continue
        loc = ("methods", method_name)
        env_names = method.envs if method.envs is not None else list(model.envs)
        for i, env_name in enumerate(env_names):
            if env_name not in model.envs:
                known = list(model.envs)
                problem((*loc, "envs", i), unknown_name_message("suite env", env_name, known))
            elif env_name in envs:  # else already reported as an unknown env
                cells += _method_cells(model, method_name, method, agent, env_name,
                                       *envs[env_name], regs, problem)
    seen: dict[str, Cell] = {}
    for cell in cells:
        if cell.id in seen:
            problems.append(f"{source.where(('seeds',))}: {seen[cell.id].label} and "
                            f"{cell.label} resolve to the same config; remove the duplicate "
                            "seed, variant value or method")
        seen.setdefault(cell.id, cell)
    return cells


def bf16_native() -> bool:
    """Whether this machine's CPU computes bf16 natively (oneDNN's own check)."""
    import torch

    return bool(torch.ops.mkldnn._is_mkldnn_bf16_supported())


def _method_cells(model: SuiteModel, method_name: str, method: MethodEntry, agent: Any,
                  env_name: str, env_spec: Any, env_entry: Any, regs: Registries,
                  problem) -> list[Cell]:
    """The cells of one method on one env: a cell per variant and seed."""
    if env_spec.actions not in agent.actions:
        problem(("methods", method_name), f"agent '{agent.name}' needs "
                f"{'/'.join(sorted(agent.actions))} actions but env '{env_name}' has "
                f"{env_spec.actions} actions; restrict the method with 'envs: [...]'")
        return []
    repeat = action_repeat_of(model, method_name, method, env_name, env_entry, problem)
    if repeat is None:
        return []
    pixels = None  # only where frames are drawn
    if method.observation != "state":
        pixels = PixelSpec(**(method.pixels or model.pixels).model_dump())
    pixels_at: Loc = (("methods", method_name, "pixels") if method.pixels is not None
                      else ("pixels",) if "pixels" in model.model_fields_set
                      else ("methods", method_name, "observation"))
    precision = method.precision or model.precision
    precision_at: Loc = (("methods", method_name, "precision") if method.precision is not None
                         else ("precision",))
    if precision not in agent.precisions:
        problem(precision_at, f"agent '{agent.name}' computes in "
                f"{' or '.join(sorted(agent.precisions))}, not {precision}; set precision: "
                f"fp32 for method '{method_name}'")
        return []
    memory_format = memory_format_of(model, method_name, method, agent, regs, problem)
    if memory_format is None:
        return []
    if precision == "bf16" and not bf16_native():
        problem(precision_at, "this machine's CPU has no bf16 instructions (torch "
                "reports no native bf16 support), so bf16 would run emulated and slower "
                "than fp32; set precision: fp32, or run the suite on a CPU with AVX512-BF16 "
                "or AMX")
        return []
    seed_batch = method.seed_batch or model.seed_batch
    if seed_batch > 1 and not check_batchable(method_name, method, model, agent, regs,
                                              problem):
        return []
    defaults = agent.defaults_for(env_name, method.observation)
    common = dict(
        suite=model.name, method=method_name, env=env_name, agent=agent.name,
        observation=method.observation, budget=env_entry.budget or model.budget,
        eval_every=model.eval.every, eval_episodes=model.eval.episodes,
        eval_epsilon=model.eval.epsilon, precision=precision, seed_batch=seed_batch,
        memory_format=memory_format,
        max_episode_steps=env_entry.max_episode_steps or env_spec.max_episode_steps,
        threads=model.threads, env_options=dict(env_entry.options), pixels=pixels,
        action_repeat=repeat,
        threshold=float(env_spec.threshold if env_entry.threshold is None
                        else env_entry.threshold),
        hyperparams_source=defaults.source if defaults else "agent defaults",
        reference=(reference.model_dump() if (reference := model.references.get(
            method_name, {}).get(env_name)) else None))
    cells = []
    for variant, overrides in _variants(model.variants.get(method_name, {})):
        hyperparams, encoder, where, where_encoder = _apply_variant(method_name, method,
                                                                    overrides, problem)
        merged = {**(defaults.values if defaults else {}), **hyperparams}
        resolved = resolve_config(agent, merged, where, problem)
        if encoder is not None:
            encoder = resolve_encoder(encoder, regs, where_encoder, problem)
        mixes = (encoder is not None and seed_batch > 1
                 and not regs.encoders.get(encoder["arch"]).batch_independent)
        if mixes:
            problem(where_encoder("arch"), f"seed_batch encodes several seeds' frames in "
                    f"one pass, and encoder '{encoder['arch']}' does not declare that a "
                    "frame's output is independent of its batch (EncoderSpec."
                    f"batch_independent); set seed_batch: 1 for method '{method_name}'")

        def at(what: str, where_encoder=where_encoder) -> Loc:
            head, _, key = what.partition(".")
            if head == "encoder":
                return where_encoder(key)
            if head == "pixels":
                return (*pixels_at, key) if key and pixels_at[-1] == "pixels" else pixels_at
            return ("methods", method_name, what)

        check_capabilities(agent, env_name, env_spec, method.observation, pixels, resolved,
                           encoder, regs, at, problem)
        if mixes or resolved is None or (method.encoder is not None and encoder is None):
            continue
        labelled = {}
        if encoder is not None:
            labelled = {"labelled_frames": EncoderRequest(
                env_name, pixels, samples=encoder["samples"],
                fraction=encoder["fraction"]).train_size,
                "labelled_by": regs.samplers.get(encoder["sampler"]).labels}
        cells += [Cell(**common, **labelled, variant=variant, variant_values=overrides,
                       seed=seed, hyperparams=resolved, encoder=encoder) for seed in model.seeds]
    return cells


def _check_envs(model: SuiteModel, regs: Registries, problem) -> dict[str, tuple]:
    envs = {}
    for env_name, entry in model.envs.items():
        if env_name not in regs.envs:
            problem(("envs", env_name), regs.envs.unknown_message(env_name))
            continue
        spec = regs.envs.get(env_name)
        envs[env_name] = (spec, entry)
        for key, value in entry.options.items():
            loc = ("envs", env_name, "options", key)
            if key not in spec.options:
                problem(loc, unknown_name_message(f"{env_name} option", key, list(spec.options)))
            elif not fits(value, spec.options[key]):
                finite = "a finite " if spec.options[key] is float else ""
                problem(loc, f"expected {finite}{spec.options[key].__name__}, got {value!r}")
        budget = entry.budget or model.budget
        if model.eval.every > budget:
            problem(("eval", "every"), f"evaluates every {model.eval.every} frames but the "
                    f"budget on {env_name} is {budget}; lower eval.every")
    return envs


def _check_method(name: str, method: MethodEntry, regs: Registries, problem):
    """The method's agent spec, or None after reporting why the method cannot run."""
    loc = ("methods", name)
    if method.agent not in regs.agents:
        problem((*loc, "agent"), regs.agents.unknown_message(method.agent))
        return None
    agent = regs.agents.get(method.agent)
    if method.observation not in OBSERVATIONS:
        message = unknown_name_message("observation", method.observation, list(OBSERVATIONS))
        problem((*loc, "observation"), message)
        return None
    if method.observation not in agent.observations:
        problem((*loc, "observation"), f"agent '{agent.name}' does not learn on "
                f"'{method.observation}'; it learns on {', '.join(sorted(agent.observations))}")
        return None
    if (method.observation == "encoded") != (method.encoder is not None):
        problem((*loc, "encoder"), "an encoder is needed exactly when observation is 'encoded'")
        return None
    if method.encoder is not None:  # reported here too for a method that gets no cells
        for key, registry in (("arch", regs.encoders), ("sampler", regs.samplers)):
            value = getattr(method.encoder, key)
            if value not in registry:  # the method's other keys are still checked
                problem((*loc, "encoder", key), registry.unknown_message(value))
    return agent


def _apply_variant(method_name: str, method: MethodEntry, overrides: dict[str, Any], problem):
    """The method's hyperparams and encoder with a variant's values in, and functions
    giving where in the file each hyperparameter, and each encoder key, was set."""
    hyperparams = dict(method.hyperparams)
    encoder = method.encoder.model_dump() if method.encoder else None
    from_variant: dict[str, Loc] = {}
    for path, value in overrides.items():
        head, _, field = path.partition(".")
        if head == "hyperparams" and field:
            hyperparams[field] = value
            from_variant[field] = ("variants", method_name, path)
        elif head == "encoder" and encoder is not None and field in encoder:
            encoder[field] = value
        else:
            problem(("variants", method_name, path), "a variant sweeps 'hyperparams.<name>', or "
                    "'encoder.<field>' of a method that has an encoder")

    if encoder is not None and overrides:
        try:  # a swept value gets the same strict checks as one written in the method
            encoder = EncoderEntry.model_validate(encoder).model_dump()
        except pydantic.ValidationError as exc:
            for err in exc.errors():
                path = f"encoder.{err['loc'][0]}" if err["loc"] else "encoder"
                problem(("variants", method_name, path),
                        f"{err['msg']} (got {show(err.get('input'))})")
            encoder = None

    def where(key: str) -> Loc:
        return from_variant.get(key, ("methods", method_name, "hyperparams", key))

    def where_encoder(key: str, field: str = "") -> Loc:
        """Where the encoder's ``key`` (its ``field``) is set: a variant's sweep, or the
        method's encoder block."""
        if f"encoder.{key}" in overrides:
            return ("variants", method_name, f"encoder.{key}")
        return ("methods", method_name, "encoder", key, *((field,) if field else ()))

    return hyperparams, encoder, where, where_encoder


def _variants(axes: dict[str, list[Any]]):
    if not axes:
        yield "", {}
        return
    paths = list(axes)
    for values in itertools.product(*(axes[p] for p in paths)):
        overrides = dict(zip(paths, values, strict=True))
        yield ",".join(f"{p}={v}" for p, v in overrides.items()), overrides


