"""State encoders trained once, cached under their request's id, loaded safely.

``<cache>/<id>/`` holds
``model.pt`` (tensors only: it loads with ``torch.load(weights_only=True)``), ``spec.json``,
``metrics.parquet`` (loss per epoch, held-out error per dimension) and ``traces.parquet``
(predicted vs true along a successful trajectory). A second cell, or a second run, with the
same spec loads it; a file lock keeps two processes from training the same one at once.
"""

from __future__ import annotations

import dataclasses
import fcntl
from collections.abc import Callable
from pathlib import Path

from senbench.encoders.model import StateEncoder, build_model, observation_bounds
from senbench.encoders.request import EncoderRequest
from senbench.encoders.training import train
from senbench.plugin.registry import Registries


def complete(request: EncoderRequest, regs: Registries) -> EncoderRequest:
    """The request with its architecture's and sampler's configs filled in with their
    defaults, so that ``{}`` and the same values written out name the same encoder."""
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
