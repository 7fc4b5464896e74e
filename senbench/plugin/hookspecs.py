"""The four hooks a senbench plugin may implement.

Each hook is handed a typed ``register`` callable: a plugin calls it once per thing it
provides. ``register`` checks the type at once, so a mistake leaves the plugin out at
start-up, with a warning naming its distribution, rather than failing deep inside a run.
"""

from __future__ import annotations

from collections.abc import Callable

import pluggy

from senbench.plugin.specs import AgentSpec, EncoderSpec, EnvSpec, SamplerSpec

hookspec = pluggy.HookspecMarker("senbench")
hookimpl = pluggy.HookimplMarker("senbench")


@hookspec
def register_envs(register: Callable[[EnvSpec], None]) -> None:
    """Register environments: ``register(EnvSpec(...))``."""


@hookspec
def register_agents(register: Callable[[AgentSpec], None]) -> None:
    """Register agents: ``register(AgentSpec(...))``."""


@hookspec
def register_encoders(register: Callable[[EncoderSpec], None]) -> None:
    """Register state encoder architectures: ``register(EncoderSpec(...))``."""


@hookspec
def register_samplers(register: Callable[[SamplerSpec], None]) -> None:
    """Register samplers of labelled (frames, state) data: ``register(SamplerSpec(...))``."""
