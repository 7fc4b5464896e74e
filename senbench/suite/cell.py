"""The cell: one (env, method, variant, seed) of a suite, typed, built once at expansion.

Every layer below the suite reads a cell's attributes; nothing reads it by string key. A
cell has two kinds of field:

- **labels** (suite, method, variant, hyperparams source, threshold, labelled frames,
  published reference) name it in reports and never change what it computes;
- **the computation** (env and its options, agent and its resolved hyperparameters,
  observation, encoder spec, pixel spec, seed, budget, evaluation protocol, threads).

Its id is a hash of the computation and :data:`CURVE_VERSION` only, so two cells that
compute the same curve — in one suite under two names, or in two suites — have one id and
one result file name, and ``run --reuse`` is a lookup by id.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from dataclasses import dataclass, field
from typing import Any

from senbench.encoders import EncoderRequest, Training
from senbench.observe.pixels import PixelSpec

CURVE_VERSION = 1
"""The version of the code that computes curves. Raise it when a change to senbench alters
what an existing cell computes (an agent's update, the evaluation, the observation
pipeline): every cell then gets a new id, so a finished result of the old code is never
taken for one of the new. Version 1: the ids of senbench's layered layout (before it, ids
hashed the labels too; ``scripts/migrate_cell_ids.py`` renamed the files of that time)."""


@dataclass(frozen=True)
class Cell:
    # labels: they name the cell and never change its curve
    suite: str
    method: str
    variant: str
    """``path=value`` pairs joined by ``,``; empty for a method's base variant."""
    # the computation
    env: str
    agent: str
    observation: str
    """``state``, ``pixels`` or ``encoded``."""
    seed: int
    budget: int
    """Frames (environment steps) the agent learns for."""
    eval_every: int
    """Frames between evaluations."""
    eval_episodes: int
    max_episode_steps: int
    """Frames per episode at most."""
    threads: int
    """torch threads: float sums, and so curves, can differ with the count."""
    hyperparams: dict[str, Any] = field(default_factory=dict)
    """The agent's config after defaults: every field of its config class."""
    eval_epsilon: float = 0.0
    """Probability of a random action at each evaluation step."""
    precision: str = "fp32"
    """The arithmetic of the agent's network updates: fp32 or bf16."""
    memory_format: str = "contiguous"
    """The convolutions' tensor layout, the agent's and the encoder's: contiguous (NCHW)
    or channels_last (NHWC). Float sums are added in another order in each."""
    seed_batch: int = 1
    """Frames per encoder pass: the seeds that run together in one process (and padding
    where fewer do). Float sums of a batched pass differ from a single frame's."""
    env_options: dict[str, Any] = field(default_factory=dict)
    action_repeat: int = 1
    """Frames each of the agent's actions is held for (the ALE's frame skip): the agent
    decides, and sees frames, every ``action_repeat`` frames; budget and curve count frames."""
    encoder: dict[str, Any] | None = None
    """The resolved encoder entry (architecture and sampler configs completed with their
    defaults), for an ``encoded`` observation."""
    pixels: PixelSpec | None = None
    """Frame size and stack, where frames are drawn (``pixels`` and ``encoded``)."""
    # more labels
    threshold: float = 0.0
    """The evaluation return that counts as solved: read by the analysis only."""
    variant_values: dict[str, Any] = field(default_factory=dict)
    """The variant's ``path → value`` overrides."""
    hyperparams_source: str = ""
    """Where the agent's defaults for this env came from (a table, a paper)."""
    labelled_frames: int = 0
    """Labelled frames (frame stack, true state) the cell's encoder was trained on before
    any online frame: what an encoded method is charged beside its online frames. 0 for the
    state and pixel learners."""
    labelled_by: str = ""
    """How those labels were obtained: the sampler's ``labels`` (e.g. states set by hand)."""
    reference: dict[str, Any] | None = None
    """A published final return this cell's method must reproduce on its env (a positive
    control): ``{"value", "spread", "source"}``."""

    def curve(self) -> dict[str, Any]:
        """What determines the cell's curve: the id hashes exactly this."""
        return {
            "curve_version": CURVE_VERSION,
            "env": {"name": self.env, "max_episode_steps": self.max_episode_steps,
                    "options": self.env_options,
                    **({} if self.action_repeat == 1 else {"action_repeat": self.action_repeat})},
            "agent": self.agent, "observation": self.observation,
            "hyperparams": self.hyperparams, "encoder": self.encoder,
            "pixels": None if self.pixels is None else dataclasses.asdict(self.pixels),
            "seed": self.seed, "budget": self.budget,
            "eval": self._eval(), "threads": self.threads,
            **self._precision(),
        }

    def _precision(self) -> dict[str, Any]:
        """fp32, a seed batch of 1 and the contiguous layout, the neutral values, are left
        out: adding the options moved no id."""
        return {**({} if self.precision == "fp32" else {"precision": self.precision}),
                **({} if self.seed_batch == 1 else {"seed_batch": self.seed_batch}),
                **({} if self.memory_format == "contiguous"
                   else {"memory_format": self.memory_format})}

    @property
    def batch_key(self) -> str:
        """What the seeds that may run in one batch share: the computation but the seed."""
        curve = {k: v for k, v in self.curve().items() if k != "seed"}
        canonical = json.dumps(curve, sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(canonical.encode()).hexdigest()[:16]

    def _eval(self) -> dict[str, Any]:
        """The evaluation protocol. An option at its neutral value (ε = 0) is left out, so
        that adding an option never changes the ids of the cells that do not use it."""
        protocol: dict[str, Any] = {"every": self.eval_every, "episodes": self.eval_episodes}
        if self.eval_epsilon:
            protocol["epsilon"] = self.eval_epsilon
        return protocol

    @property
    def id(self) -> str:
        canonical = json.dumps(self.curve(), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(canonical.encode()).hexdigest()[:16]

    @property
    def label(self) -> str:
        variant = f"[{self.variant}]" if self.variant else ""
        return f"{self.env}/{self.method}{variant} seed {self.seed}"

    def config(self) -> dict[str, Any]:
        """The resolved config as a result file's ``config`` column records it (JSON):
        the computation and the labels, in the layout of every result written so far."""
        curve = self.curve()
        return {
            "env": {**curve["env"], "threshold": self.threshold},
            "method": self.method, "agent": self.agent, "observation": self.observation,
            "hyperparams": self.hyperparams, "encoder": self.encoder, "pixels": curve["pixels"],
            "variant": self.variant_values, "seed": self.seed, "budget": self.budget,
            "eval": curve["eval"], "threads": self.threads, **self._precision(),
            **({"labelled": {"frames": self.labelled_frames, "by": self.labelled_by}}
               if self.encoder is not None else {}),
            **({"reference": self.reference} if self.reference is not None else {}),
        }

    @classmethod
    def from_config(cls, config: dict[str, Any], suite: str, variant: str = "",
                    hyperparams_source: str = "") -> Cell:
        """The cell a result file's ``config`` column describes."""
        return cls(
            suite=suite, method=config["method"], variant=variant, env=config["env"]["name"],
            agent=config["agent"], observation=config["observation"], seed=config["seed"],
            budget=config["budget"], eval_every=config["eval"]["every"],
            eval_episodes=config["eval"]["episodes"],
            eval_epsilon=config["eval"].get("epsilon", 0.0),
            precision=config.get("precision", "fp32"), seed_batch=config.get("seed_batch", 1),
            memory_format=config.get("memory_format", "contiguous"),
            max_episode_steps=config["env"]["max_episode_steps"], threads=config["threads"],
            hyperparams=config["hyperparams"], env_options=config["env"]["options"],
            action_repeat=config["env"].get("action_repeat", 1), encoder=config.get("encoder"),
            pixels=PixelSpec(**config["pixels"]) if config.get("pixels") else None,
            threshold=float(config["env"]["threshold"]),
            variant_values=config.get("variant") or {}, hyperparams_source=hyperparams_source,
            labelled_frames=config.get("labelled", {}).get("frames", 0),
            labelled_by=config.get("labelled", {}).get("by", ""),
            reference=config.get("reference"))

    def replace(self, **changes: Any) -> Cell:
        return dataclasses.replace(self, **changes)

    def encoder_request(self) -> EncoderRequest | None:
        """The state encoder this cell observes through, if any."""
        if self.encoder is None:
            return None
        entry = self.encoder
        assert self.pixels is not None, "an encoded observation draws frames"
        return EncoderRequest(
            env=self.env, pixels=self.pixels, arch=entry["arch"], sampler=entry["sampler"],
            samples=entry["samples"], fraction=entry["fraction"], seed=entry["seed"],
            arch_config=entry["config"], sampler_config=entry["sampler_config"],
            training=Training(epochs=entry["epochs"], batch_size=entry["batch_size"],
                              learning_rate=entry["learning_rate"], patience=entry["patience"],
                              lr_decay=entry["lr_decay"], test_samples=entry["test_samples"]),
            env_options=dict(self.env_options))
