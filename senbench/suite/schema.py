"""The schema of a suite file, as pydantic models: every key, its type, its default.

Unknown keys are errors (``extra="forbid"``), counts and numbers are strict (no "2000", no
"0.2", no true) and finite, so a typo or a wrong type never silently becomes a default.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator

from senbench.encoders import EncoderRequest, Training

Precision = Literal["fp32", "bf16"]
"""fp32 or bf16: how an agent's network updates compute (AgentContext.precision)."""
MemoryFormat = Literal["contiguous", "channels_last"]
"""How the networks' convolutions lay out their tensors (AgentContext.memory_format)."""
SeedBatch = Annotated[int, Field(strict=True, ge=1, le=64)]
"""Seeds per process and frames per encoder pass (senbench.run.batch)."""


class StrictModel(BaseModel):
    model_config = ConfigDict(extra="forbid")


Count = Annotated[int, Field(strict=True, gt=0)]
"""A positive whole number, written as one: not "2000", not true, not 2000.0."""
Seed = Annotated[int, Field(strict=True, ge=0, lt=2**32)]


class EnvEntry(StrictModel):
    max_episode_steps: Count | None = None
    """Episode cap in frames; the env's own default when absent."""
    threshold: Annotated[float, Field(strict=True, allow_inf_nan=False)] | None = None
    """Evaluation return that counts as solved; the env's default when absent."""
    budget: Count | None = None
    """Frames (environment steps) per cell on this env; the suite's budget when absent."""
    options: dict[str, Any] = {}
    """Keyword options of the env plugin, e.g. ``goal_velocity`` for mountaincar."""
    action_repeat: Annotated[int, Field(strict=True, ge=1, le=16)] = 1
    """Frames each action is held for, by every method on this env that sets none of its own
    (the Arcade Learning Environment's frame skip, 4 in the DQN papers): the agent decides
    and sees a frame every ``action_repeat`` frames, rewards summed between. Budget,
    ``eval.every`` and the curves count frames, so they must be multiples of it. Not for
    encoded observations (their encoders learn from stacks of consecutive frames)."""


class EncoderEntry(StrictModel):
    """A method's state encoder. Every default is the encoder request's own
    (:mod:`senbench.encoders.request`), so a suite, ``senbench encoder train`` and the cache
    agree on what an unset key means."""

    arch: str = EncoderRequest.arch
    config: dict[str, Any] = {}
    """The architecture's hyperparameters."""
    sampler: str = EncoderRequest.sampler
    sampler_config: dict[str, Any] = {}
    samples: Count = EncoderRequest.samples
    """Labelled (frames, state) pairs in the pool."""
    fraction: Annotated[float, Field(strict=True, gt=0, le=1)] = EncoderRequest.fraction
    """Share of the pool used for training: the paper's d% as a fraction."""
    seed: Seed = EncoderRequest.seed
    """The encoder's own seed: cells of every RL seed share one encoder."""
    epochs: Count = Training.epochs
    batch_size: Annotated[int, Field(strict=True, ge=2)] = Training.batch_size
    learning_rate: Annotated[float, Field(strict=True, gt=0, allow_inf_nan=False)] = (
        Training.learning_rate)
    patience: Count = Training.patience
    lr_decay: Annotated[float, Field(strict=True, gt=0, le=1)] = Training.lr_decay
    test_samples: Count = Training.test_samples


class PixelsEntry(StrictModel):
    height: Annotated[int, Field(strict=True, ge=8, le=512)] = 64
    width: Annotated[int, Field(strict=True, ge=8, le=512)] = 64
    stack: Annotated[int, Field(strict=True, ge=1, le=16)] = 2
    """Frames per observation, oldest first: one frame shows no velocity."""
    renderer: Literal["auto", "gymnasium"] = "auto"
    """auto: the env plugin's renderer if it has one; gymnasium: gymnasium's render()."""


class MethodEntry(StrictModel):
    agent: str
    observation: str = "state"
    hyperparams: dict[str, Any] = {}
    encoder: EncoderEntry | None = None
    pixels: PixelsEntry | None = None
    """Frame size and stack for pixels / encoded observations (default: the suite's)."""
    envs: Annotated[list[str], Field(min_length=1)] | None = None
    """Run only on these envs (default: every env of the suite)."""
    precision: Precision | None = None
    """The arithmetic of the agent's network updates (default: the suite's)."""
    memory_format: MemoryFormat | None = None
    """The layout of the convolutions' tensors (default: the suite's)."""
    seed_batch: SeedBatch | None = None
    """Seeds run together in one process (default: the suite's)."""
    action_repeat: Annotated[int, Field(strict=True, ge=1, le=16)] | None = None
    """Frames each of this method's actions is held for (default: its env's
    ``action_repeat``)."""


class EvalEntry(StrictModel):
    every: Count
    """Frames between evaluations."""
    episodes: Count = 10
    """Deterministic episodes per evaluation."""
    epsilon: Annotated[float, Field(strict=True, ge=0, le=1, allow_inf_nan=False)] = 0.0
    """Probability of a uniformly random action at each evaluation step (ε-greedy
    evaluation; the DQN literature uses 0.05). The same for every method of the suite, and
    recorded in each cell's config."""


class TuneRange(StrictModel):
    """A narrower search range than the agent declares: ``low``/``high`` for a number,
    ``values`` (a subset) for a choice."""

    low: Annotated[float, Field(strict=True, allow_inf_nan=False)] | None = None
    high: Annotated[float, Field(strict=True, allow_inf_nan=False)] | None = None
    values: Annotated[list[Any], Field(min_length=1)] | None = None


class ReferenceEntry(StrictModel):
    """A published final return that a method must reproduce on an env: a positive
    control. ``report`` puts it beside the method's own and says whether it passes."""

    value: Annotated[float, Field(strict=True, allow_inf_nan=False)]
    """The published mean return."""
    spread: Annotated[float, Field(strict=True, ge=0, allow_inf_nan=False)] = 0.0
    """Its published ± (e.g. the standard deviation over evaluation episodes)."""
    source: Annotated[str, Field(min_length=1)]
    """Where the number is published: table, row, version."""


class SuiteModel(StrictModel):
    name: Annotated[str, Field(pattern=r"^[A-Za-z0-9][A-Za-z0-9._-]*$")]
    description: str = ""
    envs: Annotated[dict[str, EnvEntry], Field(min_length=1)]
    methods: Annotated[dict[str, MethodEntry], Field(min_length=1)]
    seeds: Annotated[list[Seed], Field(min_length=1)]
    budget: Count
    """Frames (environment steps) per cell."""
    eval: EvalEntry
    threads: Annotated[int, Field(strict=True, ge=1, le=256)] = 1
    """torch threads per cell. Part of a cell's config: float sums, and so curves, can
    differ with the thread count, so it is fixed by the suite, not by --workers."""
    precision: Precision = "fp32"
    """The arithmetic of every method's network updates: fp32, or bf16 (torch autocast on
    the CPU: about 1.4x faster on a CNN update where the CPU has bf16 instructions).
    Part of a cell's computation; an agent that offers no choice refuses bf16 at
    validation. bf16 changes the curves: measure its effect before relying on it."""
    memory_format: MemoryFormat = "contiguous"
    """How the convolutions of every network a cell runs — its agent's and its state
    encoder's — lay out their tensors: ``contiguous`` (NCHW, PyTorch's default) or
    ``channels_last`` (NHWC, the layout oneDNN's CPU kernels prefer: faster on the CPUs
    measured in docs/benchmarks.md). Part of a cell's computation: float sums are added in
    another order, so curves can differ as with another thread count; the learning is the
    same. An agent that offers no choice refuses channels_last at validation."""
    seed_batch: SeedBatch = 1
    """How many seeds of an encoded method run together in one process, their frames
    encoded in one batch (senbench.run.batch): faster only where the encoder's batched
    pass is much cheaper per frame than its pass of one, which it was not for sen-resnet on
    the project's 2-core machine (SEN-SARSA ran 0.7x as fast batched: docs/benchmarks.md).
    Every encoder pass takes this many frames (padded where fewer seeds run),
    so a seed's curve does not depend on the seeds beside it; it is part of each cell's
    computation, as threads are. 1: each seed alone."""
    pixels: PixelsEntry = PixelsEntry()
    """Frame size and stack of pixel observations, unless a method sets its own."""
    variants: dict[str, dict[str, Annotated[list[Any], Field(min_length=1)]]] = {}
    """method → {parameter path → values}: one variant per combination of values."""
    references: dict[str, dict[str, ReferenceEntry]] = {}
    """method → {env → the published final return it must reproduce} (controls)."""
    tune: dict[str, dict[str, TuneRange]] = {}
    """method → {hyperparameter → narrower range} for ``senbench tune``; no effect on runs."""

    @field_validator("envs", mode="before")
    @classmethod
    def _empty_env_entries(cls, value: Any) -> Any:
        if isinstance(value, dict):
            return {k: ({} if v is None else v) for k, v in value.items()}
        return value

    @field_validator("seeds", mode="before")
    @classmethod
    def _seed_count(cls, value: Any) -> Any:
        if isinstance(value, int) and not isinstance(value, bool):
            if not 1 <= value <= 10_000:
                raise ValueError("a seed count must be between 1 and 10000")
            return list(range(value))
        return value
