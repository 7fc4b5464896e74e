"""senbench: does learning a state encoder first beat end-to-end pixel RL, and by how much?

A plugin writes ``import senbench`` and decorates its hooks with ``@senbench.hookimpl``.
"""

from importlib.metadata import PackageNotFoundError, version

from senbench.hookspecs import hookimpl
from senbench.specs import (
    Agent,
    AgentContext,
    AgentDefaults,
    AgentSpec,
    Choice,
    EncoderSpec,
    EnvSpec,
    Float,
    Int,
    Recorder,
    SamplerSpec,
)

try:
    __version__ = version("senbench")
except PackageNotFoundError:  # running from a source tree that was never installed
    __version__ = "0+unknown"

__all__ = [
    "Agent",
    "AgentContext",
    "AgentDefaults",
    "Choice",
    "Float",
    "Int",
    "AgentSpec",
    "EncoderSpec",
    "EnvSpec",
    "Recorder",
    "SamplerSpec",
    "__version__",
    "hookimpl",
]
