"""State encoders trained once, cached under their request's id, loaded safely.

``<cache>/<id>/`` holds
``model.pt`` (tensors only: it loads with ``torch.load(weights_only=True)``), ``model.sha256``
(its checksum, checked before each load: a damaged file is refused, naming it), ``spec.json``,
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
from senbench.encoders.training import CHECKSUM, env_of, sha256_of, train
from senbench.errors import EncoderCacheError
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
    check_checksum(path)
    env_spec = env_of(request, regs)  # the bounds of the env the cells make
    try:
        saved = torch.load(path, weights_only=True, map_location="cpu")
        mean, std, weights = saved["mean"], saved["std"], saved["model"]
    except Exception as exc:
        raise EncoderCacheError(_refusal(
            path, f"it does not load, so it is truncated or damaged ({_say(exc)})")) from None
    model = build_model(request, regs, len(mean))
    try:
        model.load_state_dict(weights)
    except Exception as exc:
        raise EncoderCacheError(_refusal(path, f"its weights do not fit the {request.arch} "
                                         f"architecture ({_say(exc)})")) from None
    low, high = observation_bounds(env_spec)
    return StateEncoder(model, mean.numpy(), std.numpy(), low, high,
                        traceable=regs.encoders.get(request.arch).traceable)


def check_checksum(path: Path) -> None:
    """Refuse a model.pt whose SHA-256 is not the one recorded beside it when it was
    written. (Encoders trained before checksums were recorded have none: a load failure
    tells for them.)"""
    sums = path.with_name(CHECKSUM)
    if not sums.exists():
        return
    recorded = sums.read_text().split()[:1]
    actual = sha256_of(path)
    if recorded != [actual]:
        raise EncoderCacheError(_refusal(
            path, f"its SHA-256 is {actual}, not the {recorded[0] if recorded else '(none)'} "
            f"recorded in {sums.name} when it was written: it was truncated or changed since"))


def _say(exc: Exception) -> str:
    said = " ".join(str(exc).split()[:40])
    return f"{type(exc).__name__}: {said}" if said else type(exc).__name__


def _refusal(path: Path, why: str) -> str:
    return (f"cached encoder {path} cannot be used: {why}. It is not retrained on its own, since "
            f"training it again can take long: delete the folder {path.parent} to train it "
            "anew, or restore it (git checkout, if it is committed).")


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
