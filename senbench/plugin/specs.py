"""What a plugin registers, and the protocol an agent follows.

Every spec carries a ``config`` dataclass: its fields are the hyperparameters a suite may
set, with a docstring-style comment giving the unit. A key that is not a field is an error
at validation time, so a typo in a suite never silently falls back to a default.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Literal, Protocol, get_args

import numpy as np

ActionKind = Literal["discrete", "continuous"]

OBSERVATION_KINDS = ("state", "pixels", "encoded")
"""The observations senbench builds (senbench.observe.observations), which
``AgentSpec.observations`` chooses from."""
MEMORY_FORMATS = frozenset({"contiguous", "channels_last"})
"""The tensor layouts a suite's ``memory_format`` chooses from: what an agent or encoder
that runs in both declares as its ``memory_formats``."""
ENV_CAPABILITIES = ("observe", "set_state", "render")
"""The optional :class:`EnvSpec` functions a sampler may need (``SamplerSpec.needs``): an
env can do what it has the function for."""


@dataclass(frozen=True)
class EnvSpec:
    """An environment: gymnasium dynamics, the physical state, and what counts as solved."""

    name: str
    make: Callable[..., Any]
    """``make(max_episode_steps=..., render_mode=None, **options) -> gymnasium.Env``
    observing the state vector."""
    physical_state: Callable[[Any], np.ndarray]
    """Reads the physical state (``state_labels`` order) from the env, which senbench
    passes unwrapped (gymnasium wrappers do not forward attributes such as ``state``)."""
    state_labels: tuple[str, ...]
    """Names of the physical state's dimensions (d of them), as tables and plots label
    them."""
    state_low: tuple[float, ...]
    """Lower bound of each physical state dimension: the range the ``uniform`` sampler
    draws states from and encoder errors are a % of. Not a hard limit: a state outside
    it is still rendered and observed."""
    state_high: tuple[float, ...]
    """Upper bound of each physical state dimension (see ``state_low``)."""
    actions: ActionKind
    threshold: float
    """Evaluation return from which a policy counts as solving the task."""
    threshold_source: str
    """Where the threshold comes from (shown beside it)."""
    max_episode_steps: int
    """The default episode cap, passed to ``make`` (which must enforce it); a suite's
    ``max_episode_steps`` overrides it."""
    options: Mapping[str, type] = field(default_factory=dict)
    """Extra keyword options a suite may pass to ``make``, with their types."""
    description: str = ""
    render: Callable[[np.ndarray, tuple[int, int]], np.ndarray] | None = None
    """``render(states (B, d), (H, W)) -> (B, H, W) uint8``: grayscale frames of physical
    states, batched. Without it, pixel observations come from gymnasium's ``render()``."""
    set_state: Callable[[Any, np.ndarray], None] | None = None
    """``set_state(unwrapped_env, state)`` puts the env in a physical state (to sample
    labelled frames, and to compare renderers)."""
    observe: Callable[[np.ndarray], np.ndarray] | None = None
    """``observe(states (B, d)) -> (B, k)`` float32: the observation an agent on the true
    state gets for each physical state — what a state encoder learns to predict. It must
    equal what ``make()``'s env returns in that state: the same k values, inside its
    ``observation_space`` (an encoded observation is clipped to those bounds). Needed by
    the ``encoded`` observation and by every sampler."""
    observation_labels: tuple[str, ...] = ()
    """Names of the k observation dimensions, for tables of encoder errors and for
    validation messages; empty: their indices."""
    demo_policy: Callable[[np.ndarray], Any] | None = None
    """``demo_policy(observation (k,)) -> action``: a policy on the state observation that
    solves the task, for encoder traces along a successful trajectory (the paper's Figs. 6
    and 10). None: ``senbench plot traces`` follows random actions instead."""

    def capabilities(self) -> frozenset[str]:
        """What the env can do beyond its dynamics: those of ``"observe"``, ``"set_state"``
        and ``"render"`` whose function it sets. Suites are checked against them before
        anything runs: an ``encoded`` observation needs ``observe``, a sampler what its
        ``needs`` names."""
        return frozenset(name for name in ENV_CAPABILITIES if getattr(self, name) is not None)

    def unbounded_dimensions(self) -> tuple[str, ...]:
        """The dimensions of the state observation (``make(...).observation_space``, also
        the bounds an encoded observation is clipped to) with an infinite bound, by their
        ``observation_labels`` (or index); all of them when the space has no bounds. Builds
        an env to read them: senbench asks once per env, and only for an agent that
        declares ``needs_bounded_observations``."""
        space = self.make(max_episode_steps=1).observation_space
        low, high = getattr(space, "low", None), getattr(space, "high", None)
        if low is None or high is None:
            return ("all (the observation space has no bounds)",)
        finite = np.isfinite(np.asarray(low, np.float64)) & np.isfinite(
            np.asarray(high, np.float64))
        names = (self.observation_labels if len(self.observation_labels) == finite.size
                 else tuple(str(i) for i in range(finite.size)))
        return tuple(name for name, ok in zip(names, finite.ravel(), strict=True) if not ok)


@dataclass(frozen=True)
class Float:
    """A real hyperparameter in [low, high]; ``log``: sampled on a log scale."""

    low: float
    high: float
    log: bool = False


@dataclass(frozen=True)
class Int:
    """A whole-number hyperparameter in [low, high]; ``log``: sampled on a log scale."""

    low: int
    high: int
    log: bool = False


@dataclass(frozen=True)
class Choice:
    """One of ``values`` (numbers, strings, booleans or lists of them)."""

    values: tuple[Any, ...]


Param = Float | Int | Choice


def narrow(param: Param, low: float | None, high: float | None,
           values: list[Any] | None) -> Param:
    """A declared range cut to a suite's narrower one (``senbench tune``): ``values``, a
    subset, for a choice; ``low``/``high`` within the range for a number. ValueError, saying
    what would do, for anything else."""
    if isinstance(param, Choice):
        if low is not None or high is not None or values is None:
            raise ValueError(f"a choice is narrowed with 'values', a subset of "
                             f"{list(param.values)}")
        extra = [v for v in values if v not in param.values]
        if extra:
            raise ValueError(f"{extra} not among {list(param.values)}")
        return Choice(tuple(values))
    if values is not None:
        raise ValueError("a number is narrowed with 'low' and 'high'")
    low = param.low if low is None else low
    high = param.high if high is None else high
    if not param.low <= low <= high <= param.high:
        raise ValueError(f"[{low}, {high}] must lie within [{param.low}, {param.high}] "
                         "with low <= high")
    if isinstance(param, Int):
        if low != int(low) or high != int(high):
            raise ValueError(f"whole numbers, got [{low}, {high}]")
        return Int(int(low), int(high), param.log)
    return Float(float(low), float(high), param.log)


def _check_min_frame_size(kind: str, name: str, size: Any, function_allowed: bool) -> None:
    if size is None or (function_allowed and callable(size)):
        return
    if not isinstance(size, int) or isinstance(size, bool) or size < 1:
        also = ", a function of the config" if function_allowed else ""
        raise ValueError(f"{kind} '{name}': min_frame_size must be a positive int{also} or "
                         f"None, got {size!r}")


def _check_search_space(kind: str, name: str, config: type,
                        space: Mapping[str, Param]) -> None:
    fields = getattr(config, "__dataclass_fields__", {})
    unknown = [field for field in space if field not in fields]
    if unknown:
        raise ValueError(f"{kind} '{name}': search_space names {unknown}, which are not "
                         "fields of its config")


@dataclass(frozen=True)
class AgentDefaults:
    """Hyperparameters for one env, and where they come from (paper, zoo, our tuning)."""

    values: Mapping[str, Any]
    source: str


@dataclass(frozen=True)
class AgentSpec:
    """A learner: how to build it, its hyperparameters, what it can act on."""

    name: str
    make: Callable[[AgentContext], Agent]
    config: type
    """A dataclass; its fields are the hyperparameters and their defaults. Suites are
    checked against it before anything runs: unknown keys, wrong types, ranges a field
    declares (``Annotated[int, pydantic.Field(ge=1)]`` on a pydantic dataclass, as the
    built-in agents do) and whatever its ``__post_init__`` raises (checks across fields)
    are validation errors, each at its own key."""
    actions: frozenset[str]
    observations: frozenset[str]
    defaults: Mapping[str, AgentDefaults] = field(default_factory=dict)
    """Per-env overrides of the config defaults, keyed by env name, or by
    ``"env:observation"`` for one observation only (that key wins over the env's)."""
    description: str = ""
    search_space: Mapping[str, Param] = field(default_factory=dict)
    """What ``senbench tune`` searches: config field → its range. A suite fixes a
    parameter by setting it in the method's ``hyperparams``."""
    min_frame_size: int | Callable[[Any], int] | None = None
    """The smallest frame height and width the agent learns on with the ``pixels``
    observation (what its network takes: 36 for Stable-Baselines3's NatureCNN): a number,
    or a function of the resolved config (an instance of ``config``) when a hyperparameter
    decides it (an augmentation's pad, say). A suite with smaller frames is a validation
    error at its ``pixels``. None: any size a suite allows."""
    precisions: frozenset[str] = frozenset({"fp32"})
    """The ``precision`` values the agent honours (``AgentContext.precision``): a suite
    asking for another is a validation error at its ``precision``."""
    seed_batching: bool = False
    """The agent may run beside other seeds in one process (a suite's ``seed_batch``; see
    :mod:`senbench.run.batch`): each seed in a thread of its own, their frames encoded in
    one batch. True only for an agent that draws from no process-global random generator
    (Python's ``random``, NumPy's ``np.random.*``, torch's default generator), since the
    seeds of one process share those, and that keeps no other process-wide state."""
    needs_bounded_observations: bool = False
    """The agent reads the observation space's bounds (tile coding scales each dimension
    by them), so on ``state`` and ``encoded`` it needs every bound finite: an env whose
    state observation has an infinite one is a validation error. False: any bounds."""
    memory_formats: frozenset[str] = frozenset({"contiguous"})
    """The ``memory_format`` values the agent honours (``AgentContext.memory_format``) on
    frames: a suite asking for another on a ``pixels`` or ``encoded`` observation is a
    validation error at its ``memory_format`` (a ``state`` cell has no convolutions, and
    the key leaves it as it is)."""

    def __post_init__(self) -> None:
        _check_search_space("agent", self.name, self.config, self.search_space)
        _check_min_frame_size("agent", self.name, self.min_frame_size, True)
        for field_name, known in (("actions", get_args(ActionKind)),
                                  ("observations", OBSERVATION_KINDS),
                                  ("precisions", ("fp32", "bf16")),
                                  ("memory_formats", sorted(MEMORY_FORMATS))):
            unknown = sorted(set(getattr(self, field_name)) - set(known))
            if unknown:
                raise ValueError(f"agent '{self.name}': {field_name} names {unknown}; it "
                                 f"chooses from {', '.join(known)}")
        fields = getattr(self.config, "__dataclass_fields__", {})
        for key, defaults in self.defaults.items():
            unknown = sorted(set(defaults.values) - set(fields))
            if fields and unknown:
                raise ValueError(f"agent '{self.name}': defaults['{key}'] sets {unknown}, "
                                 f"which its config {self.config.__name__} has no field for")
        for key in self.defaults:
            env, _, observation = key.partition(":")
            if not env or (observation and observation not in self.observations):
                raise ValueError(f"agent '{self.name}': defaults key '{key}' must be 'env' or "
                                 f"'env:observation' with an observation in "
                                 f"{sorted(self.observations)}")

    def defaults_for(self, env: str, observation: str) -> AgentDefaults | None:
        return self.defaults.get(f"{env}:{observation}", self.defaults.get(env))

    def min_frame_size_for(self, config: Any) -> int | None:
        """``min_frame_size`` for a config (an instance of ``config``)."""
        if callable(self.min_frame_size):
            return self.min_frame_size(config)
        return self.min_frame_size


@dataclass(frozen=True)
class EncoderSpec:
    """A state encoder architecture: ``build((stack, H, W), outputs, config)`` returns a
    torch module mapping float frames in [0, 1], (B, stack, H, W), to (B, outputs).

    senbench trains it on the CPU against targets standardised per dimension (mean 0,
    std 1 over the training set), so its last layer should be linear, not squashed. The
    cache stores the trained weights only: ``build`` must return the same architecture for
    the same (shape, outputs, config)."""

    name: str
    build: Callable[..., Any]
    config: type
    description: str = ""
    traceable: bool = False
    """The network's forward has no control flow that depends on its input, so senbench
    may freeze it into TorchScript for inference (1.6x faster at batch 1 for sen-resnet).
    Leave False unless that holds: a trace would silently fix one branch."""
    batch_independent: bool = False
    """In inference (eval mode) each frame's output depends on that frame alone, not on the
    other frames of its batch, so a seed batch (``seed_batch``) may encode several seeds'
    frames in one pass and a seed's curve stays bitwise the same whatever its companions.
    Convolutions, linear layers, spatial softmax and batch norm in eval mode hold it;
    anything that mixes the frames of a batch does not. Leave False unless that holds."""
    search_space: Mapping[str, Param] = field(default_factory=dict)
    """What ``senbench tune`` searches of the architecture's config, as ``encoder.<field>``
    (each distinct value trains its own encoder)."""
    min_frame_size: int | Callable[[Any], int] | None = None
    """The smallest frame height and width ``build`` takes: a number, or a function of the
    resolved config (an instance of ``config``) returning one, when it depends on the
    config (a stride, say). A suite with smaller frames is a validation error at its
    ``pixels``. None: any size a suite allows (``build`` may still refuse one)."""
    memory_formats: frozenset[str] = frozenset({"contiguous"})
    """The ``memory_format`` values the module runs in: ``channels_last`` only if its
    forward takes NHWC tensors (``reshape``/``flatten``, not ``view``, after a
    convolution). An encoded cell asking for another is a validation error."""

    def __post_init__(self) -> None:
        _check_search_space("encoder", self.name, self.config, self.search_space)
        _check_min_frame_size("encoder", self.name, self.min_frame_size, True)

    def min_frame_size_for(self, config: Any) -> int | None:
        """``min_frame_size`` for a config (an instance of ``config``)."""
        if callable(self.min_frame_size):
            return self.min_frame_size(config)
        return self.min_frame_size


@dataclass(frozen=True)
class SamplerSpec:
    """A way to draw labelled data from an env: ``sample(env_spec, count, pixels, seed,
    config)`` returns (frames (N, stack, H, W) uint8, observations (N, k) float32), the
    frames exactly as the pixel pipeline draws them for that observation.

    Each stack is oldest frame first, as the pipeline stacks them, and its label is
    ``env_spec.observe`` of the physical state of its newest frame. ``config`` is always an
    instance of ``config``, resolved from the suite; the same seed must give the same
    pairs (the encoder cache relies on it). With ``pixels.renderer: gymnasium`` the
    pipeline draws with gymnasium's ``render()``: a sampler that needs ``render`` is refused
    there, and one that steps ``make_env(env_spec, "pixels", ...)`` draws as the pipeline
    does whatever the renderer."""

    name: str
    sample: Callable[..., Any]
    config: type
    description: str = ""
    labels: str = "not stated by the sampler"
    """How the labelled frames are obtained, as reports charge them beside the online
    frames: e.g. "states set by hand" (the env is put in chosen states: access an
    end-to-end learner never has) or "random-policy rollouts"."""
    needs: frozenset[str] = frozenset()
    """What the sampler needs of an env beyond its dynamics, of ``"set_state"`` (to put it
    in chosen states), ``"render"`` (to draw them with the env plugin's renderer, so also
    ``pixels.renderer: auto``) and ``"observe"`` (every sampler labels its frames with
    ``observe``, which an encoded observation needs anyway). Suites are checked against it
    before anything runs. Empty: only the env's resets and steps."""

    def __post_init__(self) -> None:
        unknown = sorted(set(self.needs) - set(ENV_CAPABILITIES))
        if unknown:
            raise ValueError(f"sampler '{self.name}': needs names {unknown}; an env can offer "
                             f"{', '.join(ENV_CAPABILITIES)}")


@dataclass
class AgentContext:
    """Everything an agent is given for one cell. It never sees the true state unless its
    observation is ``state``."""

    config: Any
    """The agent's config dataclass, resolved: defaults ← per-env defaults ← suite."""
    env: EnvSpec
    make_env: Callable[[], Any]
    """Builds a training env with the cell's observation pipeline; the agent seeds its
    first ``reset`` with ``seed`` (vectorised agents: ``seed + i`` for env ``i``). Its
    observation space says which observation the cell uses: a (stack, H, W) uint8 Box for
    ``pixels``, a float Box of the k observation values for ``state`` and ``encoded``."""
    seed: int
    threads: int
    """torch threads this cell runs with (the suite's ``threads``), already set."""
    precision: str = "fp32"
    """The arithmetic of the agent's network updates: ``fp32``, or ``bf16`` (for an agent
    whose ``precisions`` include it: e.g. its updates under ``torch.autocast("cpu",
    dtype=torch.bfloat16)``)."""
    memory_format: str = "contiguous"
    """The layout of the agent's convolutions' tensors: ``contiguous`` (NCHW), or
    ``channels_last`` (NHWC: for an agent whose ``memory_formats`` include it, its networks
    converted with ``module.to(memory_format=torch.channels_last)``). An encoded cell's
    state encoder is laid out so by the runner."""


class Recorder(Protocol):
    """The one protocol every agent reports through."""

    def step(self, steps: int) -> bool:
        """Report the steps of ``ctx.make_env()``'s envs taken so far, over all of them (a
        vectorised step of n envs adds n): frames, or decisions of k frames under an action
        repeat of k. Evaluations run here: at 0, at the first report at or after each
        multiple of ``eval.every`` frames and at the budget; call it after every (vectorised)
        step so they land on time. Returns False once the budget is spent: the agent stops.

        The first report is ``step(0)``, before the first env step; the count never goes
        back; nothing is reported after False. A cell whose agent breaks one of these
        fails, naming the rule."""

    def episode(self, steps: int, episode_return: float, length: int) -> None:
        """Report a finished training episode at ``steps`` total frames."""


class Agent(Protocol):
    def learn(self, budget: int, recorder: Recorder) -> None:
        """Learn for ``budget`` steps of ``ctx.make_env()``'s env, reporting to ``recorder``."""

    def act(self, observation: np.ndarray) -> Any:
        """The greedy / deterministic action for one observation (not a batch), used by
        evaluation, which may call it from inside ``recorder.step`` during ``learn``."""
