"""senbench: does learning a state encoder first beat end-to-end pixel RL, and by how much?

A plugin writes ``import senbench`` and decorates its hooks with ``@senbench.hookimpl``.
Everything a plugin needs is exported here, and nothing else: the built-in plugins under
``plugins/`` import only these names, as a third-party plugin would.
"""

from importlib.metadata import PackageNotFoundError, version

from senbench.observe.observations import PhysicalStateInfo, make_env
from senbench.observe.pixels import FrameStack, PixelSpec, rendered_frames
from senbench.plugin.hookspecs import hookimpl
from senbench.plugin.specs import (
    MEMORY_FORMATS,
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
    "MEMORY_FORMATS",
    "AgentSpec",
    "EncoderSpec",
    "EnvSpec",
    "FrameStack",
    "PhysicalStateInfo",
    "PixelSpec",
    "Recorder",
    "SamplerSpec",
    "__version__",
    "hookimpl",
    "make_env",
    "rendered_frames",
]
