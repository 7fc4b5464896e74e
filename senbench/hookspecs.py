"""The four hooks a senbench plugin may implement.

Each hook is handed a typed ``register`` callable: a plugin calls it once per thing it
provides. ``register`` checks the type at once, so a mistake fails at start-up, naming the
plugin's distribution, rather than deep inside a run.
"""

from __future__ import annotations

import pluggy

hookspec = pluggy.HookspecMarker("senbench")
hookimpl = pluggy.HookimplMarker("senbench")


@hookspec
def register_envs(register):
    """Register environments: ``register(EnvSpec(...))``."""


@hookspec
def register_agents(register):
    """Register agents: ``register(AgentSpec(...))``."""


@hookspec
def register_encoders(register):
    """Register state encoder architectures: ``register(EncoderSpec(...))``."""


@hookspec
def register_samplers(register):
    """Register samplers of labelled (frames, state) data: ``register(SamplerSpec(...))``."""
