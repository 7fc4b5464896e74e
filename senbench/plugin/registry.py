"""Typed registries of what the installed plugins provide, with "did you mean" lookups.

A registry is built by asking every plugin's hooks, one plugin at a time, so that each
registered name is tied to the distribution (and version) that provided it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Generic, TypeVar

from senbench.errors import PluginError, UnknownNameError, unknown_name_message
from senbench.plugin.specs import AgentSpec, EncoderSpec, EnvSpec, SamplerSpec

T = TypeVar("T")


@dataclass(frozen=True)
class Origin:
    """The distribution that provided a registered thing."""

    distribution: str
    version: str

    def __str__(self) -> str:
        return f"{self.distribution} {self.version}".strip()


@dataclass(frozen=True)
class PluginProblem:
    """A plugin left out (``thing`` empty), or one thing it registered, and why."""

    plugin: str
    """The plugin's entry-point name (or, registered directly, its module's)."""
    origin: Origin
    reason: str
    thing: str = ""
    """For one thing left out: what, e.g. ``env 'mountaincar'``."""
    quiet: bool = False
    """Left out on purpose (SENBENCH_DISABLE_PLUGINS): no warning."""

    def __str__(self) -> str:
        who = f"plugin '{self.plugin}' ({self.origin})"
        if self.thing:
            return f"{self.thing} of {who} is left out: {self.reason}"
        return f"{who} is disabled: {self.reason}"


class Registry(Generic[T]):
    def __init__(self, kind: str, spec_type: type[T],
                 problems: list[PluginProblem] | None = None):
        self.kind = kind
        self.spec_type = spec_type
        self._entries: dict[str, tuple[T, Origin]] = {}
        self._problems = [] if problems is None else problems
        """Shared by the four registries: the plugins left out."""
        self._left_out: dict[str, PluginProblem] = {}
        """Names only a disabled plugin registered, with why it is disabled."""

    def add(self, spec: T, origin: Origin) -> None:
        if not isinstance(spec, self.spec_type):
            raise PluginError(
                f"{origin.distribution}: register_{self.kind}s got {type(spec).__name__}, "
                f"expected senbench.{self.spec_type.__name__}"
            )
        name = spec.name
        if name in self._entries:
            first = self._entries[name][1]
            both = " and ".join(sorted({first.distribution, origin.distribution}))
            raise PluginError(
                f"{self.kind} '{name}' is registered twice, by {both}. Uninstall one of "
                "them, or rename what one of them registers."
            )
        self._entries[name] = (spec, origin)

    def get(self, name: str) -> T:
        try:
            return self._entries[name][0]
        except KeyError:
            raise UnknownNameError(self.kind, name, list(self._entries),
                                   self._disabled_note(name)) from None

    def unknown_message(self, name: str) -> str:
        """Why ``name`` is not here: the names that are, and any disabled plugin that
        provides it (or may)."""
        return unknown_name_message(self.kind, name, self.names()) + self._disabled_note(name)

    def _disabled_note(self, name: str) -> str:
        if name in self._left_out:
            problem = self._left_out[name]
            return (f" {self.kind.capitalize()} '{name}' is provided by plugin "
                    f"'{problem.plugin}' ({problem.origin}), which is disabled: "
                    f"{problem.reason}")
        disabled = [str(p) for p in self._problems if not p.thing]
        if not disabled:
            return ""
        return " It may be provided by a disabled plugin: " + "; ".join(disabled)

    def merge(self, staged: Registry[T], plugin: str) -> list[PluginProblem]:
        """Add what one plugin registered (``staged``); a name another plugin registered
        first is left out, and returned as a problem naming both."""
        problems = []
        for name, (spec, origin) in staged._entries.items():
            if name in self._entries:
                first = self._entries[name][1]
                problems.append(PluginProblem(
                    plugin, origin, f"{first} registered {self.kind} '{name}' first. "
                    "Uninstall one of them, or rename what one of them registers.",
                    thing=f"{self.kind} '{name}'"))
            else:
                self._entries[name] = (spec, origin)
        return problems

    def leave_out(self, staged: Registry[T], problem: PluginProblem) -> None:
        """Remember what a disabled plugin registered before it failed, and why."""
        for name in staged._entries:
            self._left_out.setdefault(name, problem)

    def origin(self, name: str) -> Origin:
        self.get(name)
        return self._entries[name][1]

    def names(self) -> list[str]:
        return sorted(self._entries)

    def __contains__(self, name: object) -> bool:
        return name in self._entries

    def __len__(self) -> int:
        return len(self._entries)


class Register(Generic[T]):
    """The callable handed to a ``register_*`` hook: one call per thing provided."""

    def __init__(self, registry: Registry[T], origin: Origin):
        self._registry = registry
        self._origin = origin

    def __call__(self, spec: T) -> None:
        self._registry.add(spec, self._origin)


@dataclass
class Registries:
    envs: Registry[EnvSpec]
    agents: Registry[AgentSpec]
    encoders: Registry[EncoderSpec]
    samplers: Registry[SamplerSpec]
    problems: list[PluginProblem] = field(default_factory=list)
    """Plugins, or things they registered, left out, and why."""

    @classmethod
    def empty(cls) -> Registries:
        problems: list[PluginProblem] = []
        return cls(
            envs=Registry("env", EnvSpec, problems),
            agents=Registry("agent", AgentSpec, problems),
            encoders=Registry("encoder", EncoderSpec, problems),
            samplers=Registry("sampler", SamplerSpec, problems),
            problems=problems,
        )

    def merge(self, staged: Registries, plugin: str) -> None:
        """Add what one plugin registered; names registered before are left out."""
        for mine, theirs in zip(self.by_hook().values(), staged.by_hook().values(),
                                strict=True):
            self.problems += mine.merge(theirs, plugin)

    def disable(self, problem: PluginProblem, staged: Registries | None = None) -> None:
        """Leave a plugin out; ``staged``: what it registered before it failed."""
        self.problems.append(problem)
        if staged is not None:
            for mine, theirs in zip(self.by_hook().values(), staged.by_hook().values(),
                                    strict=True):
                mine.leave_out(theirs, problem)

    def by_hook(self) -> dict[str, Registry]:
        return {
            "register_envs": self.envs,
            "register_agents": self.agents,
            "register_encoders": self.encoders,
            "register_samplers": self.samplers,
        }
