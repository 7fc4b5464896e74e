"""State encoders: identified by their full spec, trained once, cached, loaded safely.

An encoder is named by everything that decides its weights — env, pixel spec, sampler and
its config, pool size, the fraction of the pool it trains on (the paper's d%), architecture
and its config, training settings, seed — hashed into an id. ``<cache>/<id>/`` holds
``model.pt`` (tensors only: it loads with ``torch.load(weights_only=True)``), ``spec.json``,
``metrics.parquet`` (loss per epoch, held-out error per dimension) and ``traces.parquet``
(predicted vs true along a successful trajectory). A second cell, or a second run, with the
same spec loads it; a file lock keeps two processes from training the same one at once.
"""

from __future__ import annotations

import fcntl
import hashlib
import json
import warnings
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from senbench.pixels import PixelSpec
from senbench.registry import Registries

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
    arch: str
    sampler: str
    samples: int
    """Labelled pairs in the pool."""
    fraction: float
    """Share of the pool trained on: the paper's d% as a fraction."""
    seed: int = 0
    arch_config: dict[str, Any] = field(default_factory=dict)
    sampler_config: dict[str, Any] = field(default_factory=dict)
    training: Training = Training()

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)

    @property
    def id(self) -> str:
        named = self.as_dict()
        if named["training"]["threads"] == TRAINING_THREADS:  # ids from before the field
            del named["training"]["threads"]
        canonical = json.dumps(named, sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(canonical.encode()).hexdigest()[:16]

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> EncoderRequest:
        data = dict(data)
        data["pixels"] = PixelSpec(**data["pixels"])
        data["training"] = Training(**data.get("training", {}))
        return cls(**data)

    @property
    def train_size(self) -> int:
        return max(2, round(self.samples * self.fraction))


def encoder_request(cell_config: dict[str, Any]) -> EncoderRequest:
    """The encoder a cell's resolved config asks for."""
    entry = cell_config["encoder"]
    return EncoderRequest(
        env=cell_config["env"]["name"],
        pixels=PixelSpec(**cell_config["pixels"]),
        arch=entry["arch"],
        sampler=entry["sampler"],
        samples=entry["samples"],
        fraction=entry["fraction"],
        seed=entry["seed"],
        arch_config=entry["config"],
        sampler_config=entry["sampler_config"],
        training=Training(epochs=entry["epochs"], batch_size=entry["batch_size"],
                          learning_rate=entry["learning_rate"], patience=entry["patience"],
                          lr_decay=entry["lr_decay"], test_samples=entry["test_samples"]),
    )


class StateEncoder:
    """Frames → estimated observation: the trained network, its target normalisation, and
    the observation bounds its output is clipped to."""

    def __init__(self, model: Any, mean: np.ndarray, std: np.ndarray, low: np.ndarray,
                 high: np.ndarray, traceable: bool = False):
        import torch

        self.model = model.eval()
        self.mean = torch.as_tensor(mean, dtype=torch.float32)
        self.std = torch.as_tensor(std, dtype=torch.float32)
        self.low, self.high = np.asarray(low, np.float32), np.asarray(high, np.float32)
        self.traceable = traceable
        self._frozen: dict[tuple[int, ...], Any] = {}

    def __call__(self, frames: np.ndarray) -> np.ndarray:
        """(B, stack, H, W) uint8 → (B, k) float32."""
        import torch

        with torch.inference_mode():
            x = torch.as_tensor(np.asarray(frames), dtype=torch.float32) / 255.0
            y = self._network(x)(x) * self.std + self.mean
        return np.clip(y.numpy(), self.low, self.high)

    def _network(self, x: Any) -> Any:
        """For an architecture that declares itself traceable, the model frozen into
        TorchScript for this input shape (1.4-1.6x faster at batch 1, where a SEN-SARSA step
        spends most of its time), kept only if it gives the eager model's outputs."""
        import torch

        if not self.traceable:
            return self.model
        shape = tuple(x.shape)
        if shape not in self._frozen:
            self._frozen[shape] = self.model
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    frozen = torch.jit.freeze(torch.jit.trace(self.model, x,
                                                              check_trace=False))
                    same = torch.allclose(frozen(x), self.model(x), rtol=1e-4, atol=1e-5)
            except Exception:  # noqa: BLE001 - a network TorchScript cannot take stays eager
                same = False
            if same:
                self._frozen[shape] = frozen
        return self._frozen[shape]


def observation_bounds(env_spec: Any) -> tuple[np.ndarray, np.ndarray]:
    space = env_spec.make(max_episode_steps=1).observation_space
    return np.asarray(space.low, np.float32), np.asarray(space.high, np.float32)


def build_model(request: EncoderRequest, regs: Registries, outputs: int) -> Any:
    arch = regs.encoders.get(request.arch)
    config = arch.config(**request.arch_config)
    shape = (request.pixels.stack, request.pixels.height, request.pixels.width)
    return arch.build(shape, outputs, config)


def complete(request: EncoderRequest, regs: Registries) -> EncoderRequest:
    """The request with its architecture's and sampler's configs filled in with their
    defaults, so that ``{}`` and the same values written out name the same encoder."""
    import dataclasses

    arch = regs.encoders.get(request.arch).config(**request.arch_config)
    sampler = regs.samplers.get(request.sampler).config(**request.sampler_config)
    return dataclasses.replace(request, arch_config=dataclasses.asdict(arch),
                               sampler_config=dataclasses.asdict(sampler))


def cache_dir(root: Path, request: EncoderRequest) -> Path:
    return Path(root) / request.id


def load(root: Path, request: EncoderRequest, regs: Registries) -> StateEncoder | None:
    """The cached encoder for ``request``, or None if it was never trained."""
    import torch

    request = complete(request, regs)
    path = cache_dir(root, request) / "model.pt"
    if not path.exists():
        return None
    saved = torch.load(path, weights_only=True, map_location="cpu")
    env_spec = regs.envs.get(request.env)
    model = build_model(request, regs, len(saved["mean"]))
    model.load_state_dict(saved["model"])
    low, high = observation_bounds(env_spec)
    return StateEncoder(model, saved["mean"].numpy(), saved["std"].numpy(), low, high,
                        traceable=regs.encoders.get(request.arch).traceable)


def load_or_train(root: Path, request: EncoderRequest, regs: Registries,
                  log: Callable[[str], None] = lambda message: None) -> StateEncoder:
    """Load the encoder for ``request``, training it first if no process has yet."""
    from senbench.encoder_training import train

    root = Path(root)
    root.mkdir(parents=True, exist_ok=True)
    request = complete(request, regs)
    with open(root / f".{request.id}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # a second process waits here, then loads
        encoder = load(root, request, regs)
        if encoder is not None:
            log(f"encoder {request.id} ({request.arch}, {request.env}, "
                f"d = {request.fraction:.0%}): cached, loaded")
            return encoder
        log(f"encoder {request.id} ({request.arch}, {request.env}, d = {request.fraction:.0%} "
            f"of {request.samples} {request.sampler} samples): training")
        train(request, regs, cache_dir(root, request), log)
    encoder = load(root, request, regs)
    assert encoder is not None
    return encoder
