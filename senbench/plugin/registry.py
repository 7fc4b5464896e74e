"""Typed registries of what the installed plugins provide, with "did you mean" lookups.

A registry is built by asking every plugin's hooks, one plugin at a time, so that each
registered name is tied to the distribution (and version) that provided it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Generic, TypeVar

from senbench.errors import PluginError, UnknownNameError
from senbench.plugin.specs import AgentSpec, EncoderSpec, EnvSpec, SamplerSpec

T = TypeVar("T")


@dataclass(frozen=True)
class Origin:
    """The distribution that provided a registered thing."""

    distribution: str
    version: str

    def __str__(self) -> str:
        return f"{self.distribution} {self.version}".strip()


class Registry(Generic[T]):
    def __init__(self, kind: str, spec_type: type[T]):
        self.kind = kind
        self.spec_type = spec_type
        self._entries: dict[str, tuple[T, Origin]] = {}

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
            raise UnknownNameError(self.kind, name, list(self._entries)) from None

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

    @classmethod
    def empty(cls) -> Registries:
        return cls(
            envs=Registry("env", EnvSpec),
            agents=Registry("agent", AgentSpec),
            encoders=Registry("encoder", EncoderSpec),
            samplers=Registry("sampler", SamplerSpec),
        )

    def by_hook(self) -> dict[str, Registry]:
        return {
            "register_envs": self.envs,
            "register_agents": self.agents,
            "register_encoders": self.encoders,
            "register_samplers": self.samplers,
        }
