"""What names a state encoder: its request, the one home of its defaults (suites, the CLI
and the cache all take them from here).

An encoder is named by everything that decides its weights — env and its options, pixel
spec, sampler and its config, pool size, the fraction of the pool it trains on (the
paper's d%), architecture and its config, training settings, seed — hashed into an id.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass, field
from typing import Any

from senbench.observe.pixels import PixelSpec

TRAINING_THREADS = 2
"""torch threads encoder training runs on unless told otherwise (``Training.threads``)."""


@dataclass(frozen=True)
class Training:
    epochs: int = 30
    """Most passes over the training set; early stopping usually ends sooner."""
    batch_size: int = 128
    learning_rate: float = 1e-3
    validation: float = 0.1
    """Share of the training set held out to pick the best epoch and stop early."""
    patience: int = 4
    """Epochs without a better validation loss before stopping."""
    lr_decay: float = 0.3
    """The learning rate is multiplied by this after an epoch without improvement."""
    test_samples: int = 5000
    """Size of the independent held-out set the reported errors come from."""
    threads: int = TRAINING_THREADS
    """torch threads training runs on. The weights depend on it (float sums split across
    threads add up in another order), so it is fixed rather than the machine's core count:
    the same spec trains the same encoder on a laptop and on a 64-core node."""


@dataclass(frozen=True)
class EncoderRequest:
    env: str
    pixels: PixelSpec
    arch: str = "sen-resnet"
    sampler: str = "uniform"
    samples: int = 50_000
    """Labelled pairs in the pool."""
    fraction: float = 0.2
    """Share of the pool trained on: the paper's d% as a fraction."""
    seed: int = 0
    """The encoder's own seed: cells of every RL seed share one encoder."""
    arch_config: dict[str, Any] = field(default_factory=dict)
    sampler_config: dict[str, Any] = field(default_factory=dict)
    training: Training = Training()
    env_options: dict[str, Any] = field(default_factory=dict)
    """The env's keyword options (a suite's ``envs: <env>: options:``): the sampler draws
    its frames from the env made with them, as the cells that read them are."""

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)

    @property
    def id(self) -> str:
        named = self.as_dict()
        if named["training"]["threads"] == TRAINING_THREADS:  # ids from before the field
            del named["training"]["threads"]
        if not named["env_options"]:  # ids from before the field
            del named["env_options"]
        canonical = json.dumps(named, sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(canonical.encode()).hexdigest()[:16]

    @property
    def train_size(self) -> int:
        return max(2, round(self.samples * self.fraction))
