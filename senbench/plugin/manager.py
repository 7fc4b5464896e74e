"""The plugin manager: loads the entry-point group ``senbench`` and builds the registries.

Built-in plugins come through the same entry-point group as any third-party one, so the
core never names them. Set ``SENBENCH_NO_THIRD_PARTY_PLUGINS=1`` to load only the
plugins shipped in the ``senbench`` distribution (the test suite does).
"""

from __future__ import annotations

import importlib
import os
from importlib.metadata import entry_points
from types import ModuleType

import pluggy

from senbench.errors import PluginError
from senbench.plugin import hookspecs
from senbench.plugin.registry import Origin, Register, Registries

GROUP = "senbench"
BUILTIN_DISTRIBUTION = "senbench"
NO_THIRD_PARTY = "SENBENCH_NO_THIRD_PARTY_PLUGINS"

pm = pluggy.PluginManager("senbench")
pm.add_hookspecs(hookspecs)

_origins: dict[str, Origin] = {}
_registered_modules: list[tuple[str, str, str]] = []
"""Modules registered with register_plugin, so worker processes can register them too."""
_loaded = False
_registries: Registries | None = None


def third_party_enabled() -> bool:
    return os.environ.get(NO_THIRD_PARTY, "").strip() in ("", "0", "false", "no")


def load_plugins() -> None:
    global _loaded
    if _loaded:
        return
    _loaded = True
    allow_third_party = third_party_enabled()
    for ep in entry_points(group=GROUP):
        dist = ep.dist
        dist_name = dist.name if dist is not None else "unknown"
        if dist_name != BUILTIN_DISTRIBUTION and not allow_third_party:
            continue
        name = f"{dist_name}:{ep.name}"
        if pm.has_plugin(name):  # the same distribution seen twice on sys.path
            continue
        try:
            plugin = ep.load()
        except Exception as exc:
            raise PluginError(
                f"plugin '{ep.name}' from {dist_name} failed to import: {exc!r}. "
                f"Fix or uninstall {dist_name}, or set {NO_THIRD_PARTY}=1."
            ) from exc
        pm.register(plugin, name=name)
        _origins[name] = Origin(dist_name, dist.version if dist is not None else "")


def register_plugin(plugin: object, distribution: str = "local", version: str = "") -> None:
    """Register a plugin object (a module or class with ``@hookimpl`` functions) directly,
    e.g. from a test or a notebook."""
    load_plugins()
    name = f"{distribution}:{getattr(plugin, '__name__', id(plugin))}"
    pm.register(plugin, name=name)
    _origins[name] = Origin(distribution, version)
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
    module_name = getattr(plugin, "__name__", None)
    _registered_modules[:] = [m for m in _registered_modules if m[0] != module_name]
    _invalidate()


def _invalidate() -> None:
    global _registries
    _registries = None


def registries() -> Registries:
    """Every env, agent, encoder and sampler the installed plugins provide."""
    global _registries
    if _registries is None:
        load_plugins()
        regs = Registries.empty()
        for hook_name, registry in regs.by_hook().items():
            for impl in getattr(pm.hook, hook_name).get_hookimpls():
                origin = _origins.get(impl.plugin_name, Origin(impl.plugin_name, ""))
                impl.function(register=Register(registry, origin))
        _registries = regs
    return _registries
