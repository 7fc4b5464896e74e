"""The plugin manager: loads the entry-point group ``senbench`` and builds the registries.

Built-in plugins come through the same entry-point group as any third-party one, so the
core never names them. Set ``SENBENCH_NO_THIRD_PARTY_PLUGINS=1`` to load only the
plugins shipped in the ``senbench`` distribution (the test suite does), and
``SENBENCH_DISABLE_PLUGINS=name,name`` to leave out plugins by entry-point or distribution
name (as pytest's ``-p no:NAME``).

A broken plugin disables itself, not the tool: one whose module fails to import, or whose
``register_*`` hook raises, is left out whole; a name a plugin registers after another
plugin did is left out of the later one. Each such problem is kept in
``registries().problems``, handed once per process to whatever :func:`report_problems` was
given (the CLI prints a warning), and named in the error of a suite that asks for
something a disabled plugin provides.
"""

from __future__ import annotations

import difflib
import importlib
import importlib.util
import os
import sys
import traceback
from collections.abc import Callable
from importlib.metadata import EntryPoint, entry_points
from pathlib import Path
from types import ModuleType

import pluggy

from senbench.plugin import hookspecs
from senbench.plugin.registry import Origin, PluginProblem, Register, Registries

GROUP = "senbench"
BUILTIN_DISTRIBUTION = "senbench"
NO_THIRD_PARTY = "SENBENCH_NO_THIRD_PARTY_PLUGINS"
DISABLE = "SENBENCH_DISABLE_PLUGINS"

pm = pluggy.PluginManager("senbench")
pm.add_hookspecs(hookspecs)

_origins: dict[str, Origin] = {}
_labels: dict[str, str] = {}
"""pluggy name (``dist:entry point``) → the plugin's short name in messages."""
_order: list[str] = []
"""pluggy names in the order their hooks are asked: built-ins first."""
_skipped: list[PluginProblem] = []
"""Entry points not registered: disabled on purpose, or failed to import."""
_from_entry_points: set[str] = set()
_modules: dict[str, str] = {}
"""pluggy name → the module an entry point names."""
_registered_modules: list[tuple[str, str, str]] = []
"""Modules registered with register_plugin, so worker processes can register them too."""
_loaded = False
_registries: Registries | None = None
_reporter: Callable[[str], None] | None = None
_reported: set[str] = set()


def third_party_enabled() -> bool:
    return os.environ.get(NO_THIRD_PARTY, "").strip() in ("", "0", "false", "no")


def disabled_by_user() -> set[str]:
    """The entry-point and distribution names SENBENCH_DISABLE_PLUGINS lists."""
    return {n.strip() for n in os.environ.get(DISABLE, "").split(",") if n.strip()}


def load_plugins() -> None:
    global _loaded
    if _loaded:
        return
    _loaded = True
    allow_third_party = third_party_enabled()
    off = disabled_by_user()
    found = list(entry_points(group=GROUP))
    # built-ins first, then by name: which of two plugins is "later" does not depend on
    # the order of files in a folder
    found.sort(key=lambda ep: (_dist_name(ep) != BUILTIN_DISTRIBUTION, _dist_name(ep), ep.name))
    for ep in found:
        dist_name = _dist_name(ep)
        name = f"{dist_name}:{ep.name}"
        if name in _from_entry_points:  # the same distribution seen twice on sys.path
            continue
        _from_entry_points.add(name)
        origin = Origin(dist_name, ep.dist.version if ep.dist is not None else "")
        if dist_name != BUILTIN_DISTRIBUTION and not allow_third_party:
            _skipped.append(PluginProblem(ep.name, origin, f"{NO_THIRD_PARTY} switches "
                                          "third-party plugins off", quiet=True))
            continue
        if ep.name in off or dist_name in off:
            _skipped.append(PluginProblem(ep.name, origin, f"{DISABLE} names it", quiet=True))
            continue
        try:
            plugin = ep.load()
        except Exception as exc:
            _skipped.append(PluginProblem(
                ep.name, origin, f"it failed to import: {describe(exc, _ep_roots(ep))}"))
            continue
        try:
            _register(plugin, name)
        except Exception as exc:  # pluggy's validation of its hooks, or a name unknown
            _skipped.append(PluginProblem(
                ep.name, origin, f"its hooks are invalid: {describe(exc, [])}"))
            continue
        _add(name, ep.name, origin)
        _modules[name] = ep.value.split(":")[0].strip()


def _register(plugin: object, name: str) -> None:
    """Register ``plugin`` with pluggy, refusing a ``@hookimpl`` whose name is no senbench
    hook (pluggy would keep it, never called: a misspelled hook registers nothing) unless
    it is marked ``optionalhook=True`` (one for a later senbench's hook, say)."""
    pm.register(plugin, name=name)
    unknown = sorted(caller.name for caller in pm.get_hookcallers(plugin) or []
                     if not caller.has_spec()
                     and any(impl.plugin is plugin and not impl.optionalhook
                             for impl in caller.get_hookimpls()))
    if unknown:
        pm.unregister(plugin)
        hooks = sorted(n for n in dir(hookspecs) if n.startswith("register_"))
        close = {n: difflib.get_close_matches(n, hooks, n=1) for n in unknown}
        said = ", ".join(f"'{n}'" + (f" (did you mean '{close[n][0]}'?)" if close[n] else "")
                         for n in unknown)
        raise ValueError(f"@hookimpl {said} is no senbench hook; the hooks are "
                         f"{', '.join(hooks)}")


def entry_point_modules() -> list[str]:
    """The modules of the entry-point plugins that loaded, for a process server to import
    beforehand: not those disabled, nor those that failed to import."""
    load_plugins()
    return sorted({_modules[name] for name in _order if name in _modules})


def _dist_name(ep: EntryPoint) -> str:
    return ep.dist.name if ep.dist is not None else "unknown"


def _add(name: str, label: str, origin: Origin) -> None:
    _origins[name] = origin
    _labels[name] = label
    if name not in _order:
        _order.append(name)


def register_plugin(plugin: object, distribution: str = "local", version: str = "") -> None:
    """Register a plugin object (a module or class with ``@hookimpl`` functions) directly,
    e.g. from a test or a notebook."""
    load_plugins()
    name = f"{distribution}:{getattr(plugin, '__name__', id(plugin))}"
    _register(plugin, name)
    _add(name, getattr(plugin, "__name__", type(plugin).__name__), Origin(distribution, version))
    if isinstance(plugin, ModuleType):
        _registered_modules.append((plugin.__name__, distribution, version))
    _invalidate()


def registered_module_names() -> list[tuple[str, str, str]]:
    return list(_registered_modules)


def register_modules(modules: list[tuple[str, str, str]]) -> None:
    """Register plugin modules by name (in a worker process, what the parent registered)."""
    for module_name, distribution, version in modules:
        module = importlib.import_module(module_name)
        if not pm.is_registered(module):
            register_plugin(module, distribution, version)


def unregister_plugin(plugin: object) -> None:
    name = pm.get_name(plugin)
    pm.unregister(plugin)
    _origins.pop(name, None)
    _labels.pop(name, None)
    if name in _order:
        _order.remove(name)
    module_name = getattr(plugin, "__name__", None)
    _registered_modules[:] = [m for m in _registered_modules if m[0] != module_name]
    _invalidate()


def _invalidate() -> None:
    global _registries
    _registries = None


def registries() -> Registries:
    """Every env, agent, encoder and sampler the installed plugins provide; the plugins
    left out, and why, in its ``problems``."""
    global _registries
    if _registries is None:
        load_plugins()
        regs = Registries.empty()
        for problem in _skipped:
            regs.disable(problem)
        for name in _order:
            _ask(name, regs)
        _registries = regs
    _report(_registries.problems)
    return _registries


def _ask(name: str, regs: Registries) -> None:
    """Call one plugin's hooks; add what they register, or leave the plugin out if one
    raises."""
    plugin = pm.get_plugin(name)
    origin, label = _origins[name], _labels[name]
    staged = Registries.empty()
    for hook_name, registry in staged.by_hook().items():
        for impl in getattr(pm.hook, hook_name).get_hookimpls():
            if impl.plugin_name != name:
                continue
            try:
                impl.function(register=Register(registry, origin))
            except Exception as exc:
                reason = f"its {hook_name} hook raised {describe(exc, _roots(plugin))}"
                regs.disable(PluginProblem(label, origin, reason), staged)
                return
    regs.merge(staged, label)


def report_problems(warn: Callable[[str], None]) -> None:
    """Hand each problem with the plugins to ``warn``, once per process: those found so far
    and those found later (the CLI prints them as warnings)."""
    global _reporter
    _reporter = warn
    if _registries is not None:
        _report(_registries.problems)


def warning(problem: PluginProblem) -> str:
    """What to tell the user about ``problem``, with what to do."""
    text = str(problem).rstrip(".") + "."
    if not problem.thing and f"{problem.origin.distribution}:{problem.plugin}" in \
            _from_entry_points:
        text += (f" Everything else works without it. Fix or uninstall "
                 f"{problem.origin.distribution}, or set {DISABLE}={problem.plugin} to "
                 "leave it out without this warning.")
    return text


def _report(problems: list[PluginProblem]) -> None:
    if _reporter is None:
        return
    for problem in problems:
        text = warning(problem)
        if not problem.quiet and text not in _reported:
            _reported.add(text)
            _reporter(text)


def describe(exc: BaseException, roots: list[Path]) -> str:
    """``Type: message (file:line)``, at the traceback's last frame inside ``roots`` (the
    plugin's files), or else the last one outside Python's import machinery."""
    message = " ".join(str(exc).split())
    text = f"{type(exc).__name__}: {message}" if message else type(exc).__name__
    where = _where(exc, roots)
    return f"{text} ({where})" if where else text


def _where(exc: BaseException, roots: list[Path]) -> str:
    if isinstance(exc, SyntaxError) and exc.filename:
        return f"{exc.filename}:{exc.lineno}"
    frames = [f for f in traceback.extract_tb(exc.__traceback__)
              if not f.filename.startswith("<")]
    inside = [f for f in frames if any(_under(f.filename, root) for root in roots)]
    if not inside:
        machinery = [Path(importlib.__file__).parent, Path(pluggy.__file__).parent,
                     Path(__file__).parent]
        inside = [f for f in frames if not any(_under(f.filename, m) for m in machinery)]
    return f"{inside[-1].filename}:{inside[-1].lineno}" if inside else ""


def _under(filename: str, root: Path) -> bool:
    path = Path(filename)
    return path == root or root in path.parents


def _ep_roots(ep: EntryPoint) -> list[Path]:
    """Where an entry point's top-level package or module lives."""
    top = ep.value.split(":")[0].strip().split(".")[0]
    try:
        spec = importlib.util.find_spec(top)
    except (ImportError, ValueError):
        return []
    if spec is None:
        return []
    if spec.submodule_search_locations:
        return [Path(p) for p in spec.submodule_search_locations]
    return [Path(spec.origin)] if spec.origin else []


def _roots(plugin: object) -> list[Path]:
    """Where a registered plugin object's top-level package or module lives."""
    module = plugin if isinstance(plugin, ModuleType) else sys.modules.get(
        getattr(type(plugin), "__module__", ""))
    top = sys.modules.get(getattr(module, "__name__", "").split(".")[0])
    file = getattr(top, "__file__", None)
    if not file:
        return []
    path = Path(file)
    return [path.parent] if path.name == "__init__.py" else [path]
