"""Supervised training of a state encoder (the paper's first stage).

Targets are normalised per dimension; Adam on the mean squared error, its learning rate cut
by ``lr_decay`` after each epoch that does not improve the validation loss; the best epoch
is kept and training stops when none has improved for ``patience`` epochs. Reported errors
come from an independent held-out set drawn with another seed: RMSE per observation
dimension, in its units and as % of its range. Traces follow the env's demo policy along one
successful trajectory, as the paper's Figs. 6 and 10.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from senbench.encoders.model import StateEncoder, build_model, observation_bounds
from senbench.encoders.request import EncoderRequest
from senbench.errors import PluginError
from senbench.observe.observations import make_env
from senbench.plugin.registry import Registries
from senbench.results.atomic import atomic_file

HELD_OUT_SEED = 1_000_003
TRACE_STEPS = 1000
CHECKSUM = "model.sha256"
"""Beside model.pt: its SHA-256, checked before every load (encoders trained before it
was written have none)."""


def sha256_of(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def env_of(request: EncoderRequest, regs: Registries) -> Any:
    """The env plugin whose ``make`` makes the env with the request's options, as the cells
    that read the encoder make it: a sampler or the trace then steps the cells' env."""
    env_spec = regs.envs.get(request.env)
    if not request.env_options:
        return env_spec
    return dataclasses.replace(env_spec, make=functools.partial(env_spec.make,
                                                                **request.env_options))


def draw(request: EncoderRequest, regs: Registries, count: int, seed: int):
    env_spec = env_of(request, regs)
    sampler = regs.samplers.get(request.sampler)
    config = sampler.config(**request.sampler_config)
    frames, targets = sampler.sample(env_spec, count, request.pixels, seed, config)
    return _checked(request, count, np.asarray(frames), np.asarray(targets),
                    len(observation_bounds(env_spec)[0]))


def _checked(request: EncoderRequest, count: int, frames: np.ndarray, targets: np.ndarray,
             k: int) -> tuple[np.ndarray, np.ndarray]:
    """The sampler's pairs, refused (naming the plugin and its contract) unless they are
    what ``SamplerSpec.sample`` promises: a silent cast or broadcast would train an encoder
    on wrong data."""
    pixels = request.pixels
    frame_shape = (count, pixels.stack, *pixels.size)
    problems = []
    if frames.dtype != np.uint8 or frames.shape != frame_shape:
        problems.append(f"frames of shape {frames.shape} and dtype {frames.dtype}, not "
                        f"{frame_shape} uint8")
    if targets.shape != (count, k) or not np.issubdtype(targets.dtype, np.number):
        problems.append(f"observations of shape {targets.shape} and dtype {targets.dtype}, "
                        f"not {(count, k)} numbers (env '{request.env}' has {k} "
                        f"observation values)")
    elif not np.isfinite(targets).all():
        problems.append("observations that are NaN or infinite")
    if problems:
        raise PluginError(f"sampler '{request.sampler}' returned {' and '.join(problems)} "
                          f"for {count} samples; its sample(env_spec, count, pixels, seed, "
                          "config) must return (frames (count, stack, H, W) uint8, "
                          "observations (count, k)) — a fault of the sampler plugin, not of "
                          "the suite")
    return frames, targets.astype(np.float32)


def train(request: EncoderRequest, regs: Registries, out: Path,
          log: Callable[[str], None] = lambda message: None) -> dict[str, Any]:
    """Train, evaluate and save the encoder ``request`` names, on its ``training.threads``
    torch threads whatever the caller's, which are restored after."""
    import torch

    before = torch.get_num_threads()
    torch.set_num_threads(request.training.threads)
    try:
        return _train(request, regs, out, log)
    finally:
        torch.set_num_threads(before)


def _train(request: EncoderRequest, regs: Registries, out: Path,
           log: Callable[[str], None]) -> dict[str, Any]:
    import torch

    torch.manual_seed(request.seed)
    rng = np.random.default_rng(request.seed)
    started = time.perf_counter()
    frames, targets = draw(request, regs, request.samples, request.seed)
    chosen = rng.permutation(request.samples)[:request.train_size]  # the d% of the pool
    n_val = max(1, int(round(request.training.validation * len(chosen))))
    val, fit = chosen[:n_val], chosen[n_val:]
    if len(fit) < 8:
        raise ValueError(f"{len(chosen)} samples ({request.fraction:g} of {request.samples}) "
                         f"leave {len(fit)} to train on after validation: raise samples or "
                         "fraction")
    mean = targets[fit].mean(axis=0)
    std = np.maximum(targets[fit].std(axis=0), 1e-6)
    model = build_model(request, regs, targets.shape[1])
    optimizer = torch.optim.Adam(model.parameters(), lr=request.training.learning_rate)
    scheduler = torch.optim.lr_scheduler.ReduceLROnPlateau(
        optimizer, factor=request.training.lr_decay, patience=0)
    normalised = torch.as_tensor((targets - mean) / std)
    images = torch.from_numpy(frames)  # uint8; scaled per batch to keep memory small

    def loss_on(index: np.ndarray) -> float:
        model.eval()
        total = 0.0
        with torch.no_grad():
            for s in range(0, len(index), 512):
                batch = torch.as_tensor(index[s:s + 512])
                prediction = model(images[batch].float() / 255.0)
                total += float(((prediction - normalised[batch]) ** 2).sum())
        return total / (len(index) * targets.shape[1])

    epochs, best, best_state, stale = [], float("inf"), None, 0
    for epoch in range(1, request.training.epochs + 1):
        model.train()
        order = torch.as_tensor(rng.permutation(fit))
        running, seen = 0.0, 0
        for s in range(0, len(order), request.training.batch_size):
            batch = order[s:s + request.training.batch_size]
            if len(batch) < 2:  # batch norm needs two samples
                continue
            loss = ((model(images[batch].float() / 255.0) - normalised[batch]) ** 2).mean()
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            running += loss.item() * len(batch)
            seen += len(batch)
        val_loss = loss_on(val)
        scheduler.step(val_loss)
        epochs.append({"epoch": epoch, "train_loss": running / seen if seen else np.nan,
                       "val_loss": val_loss, "wall_s": time.perf_counter() - started})
        log(f"  epoch {epoch}: train {epochs[-1]['train_loss']:.4f}, validation {val_loss:.4f}")
        if val_loss < best:
            best, stale = val_loss, 0
            best_state = {k: v.detach().clone() for k, v in model.state_dict().items()}
        else:
            stale += 1
            if stale >= request.training.patience:
                break
    if best_state is None:
        raise ValueError("the validation loss was never finite: training diverged; lower "
                         "learning_rate")
    model.load_state_dict(best_state)
    train_wall = time.perf_counter() - started

    env_spec = env_of(request, regs)
    low, high = observation_bounds(env_spec)
    encoder = StateEncoder(model, mean, std, low, high,
                           traceable=regs.encoders.get(request.arch).traceable)
    test_frames, test_targets = draw(request, regs, request.training.test_samples,
                                     request.seed + HELD_OUT_SEED)
    predicted = np.concatenate([encoder(test_frames[s:s + 512])
                                for s in range(0, len(test_frames), 512)])
    rmse = np.sqrt(((predicted - test_targets) ** 2).mean(axis=0))
    span = high - low
    labels = list(env_spec.observation_labels) or [f"x{i}" for i in range(len(rmse))]
    errors = [{"dimension": labels[i], "rmse": float(rmse[i]),
               "rmse_pct_of_range": float(100 * rmse[i] / span[i])} for i in range(len(rmse))]
    traces = trace(encoder, request, regs)

    out.mkdir(parents=True, exist_ok=True)
    _write_metrics(out, request, epochs, errors, train_wall)
    if traces is not None:
        _atomic_parquet(pa.Table.from_pylist(traces), out / "traces.parquet")
    _atomic_json(out / "spec.json", {"id": request.id, **request.as_dict(),
                                     "train_wall_s": train_wall, "errors": errors})
    with atomic_file(out / "model.pt", stem="model") as tmp:  # last: its presence means
        torch.save({"model": model.state_dict(), "mean": torch.as_tensor(mean),  # complete
                    "std": torch.as_tensor(std)}, tmp)
        with atomic_file(out / CHECKSUM) as sums:  # before model.pt is there, in sha256sum's
            sums.write_text(f"{sha256_of(tmp)}  model.pt\n")  # format: sha256sum -c works
    log("  held-out RMSE: " + ", ".join(
        f"{e['dimension']} {e['rmse']:.4g} ({e['rmse_pct_of_range']:.2f}% of range)"
        for e in errors) + f"; {train_wall:.0f} s")
    return {"errors": errors, "epochs": epochs, "train_wall_s": train_wall}


def trace(encoder: StateEncoder, request: EncoderRequest,
          regs: Registries) -> list[dict[str, Any]] | None:
    """Predicted vs true observation along one episode of the env's demo policy."""
    env_spec = env_of(request, regs)
    if env_spec.demo_policy is None or env_spec.observe is None:
        return None
    steps = min(TRACE_STEPS, env_spec.max_episode_steps)
    game = make_env(env_spec, "pixels", steps, {}, request.pixels)
    frames, info = game.reset(seed=0)
    labels = list(env_spec.observation_labels)
    rows = []
    for step in range(steps):
        true = env_spec.observe(np.asarray(info["state"])[None])[0]
        guess = encoder(frames[None])[0]
        rows += [{"step": step, "dimension": labels[i], "true": float(true[i]),
                  "predicted": float(guess[i])} for i in range(len(true))]
        frames, _, terminated, truncated, info = game.step(env_spec.demo_policy(true))
        if terminated or truncated:
            break
    return rows


def _write_metrics(out: Path, request: EncoderRequest, epochs: list[dict], errors: list[dict],
                   train_wall: float) -> None:
    rows = [{"kind": "epoch", "epoch": e["epoch"], "train_loss": e["train_loss"],
             "val_loss": e["val_loss"], "wall_s": e["wall_s"]} for e in epochs]
    rows += [{"kind": "test", "dimension": e["dimension"], "rmse": e["rmse"],
              "rmse_pct_of_range": e["rmse_pct_of_range"], "wall_s": train_wall}
             for e in errors]
    columns = ["kind", "epoch", "train_loss", "val_loss", "dimension", "rmse",
               "rmse_pct_of_range", "wall_s"]
    table = pa.Table.from_pylist([{c: row.get(c) for c in columns} for row in rows])
    for name, value in (("encoder_id", request.id), ("env", request.env),
                        ("arch", request.arch), ("sampler", request.sampler),
                        ("samples", request.samples), ("fraction", request.fraction),
                        ("train_size", request.train_size), ("seed", request.seed)):
        table = table.append_column(name, pa.array([value] * len(table)))
    _atomic_parquet(table, out / "metrics.parquet")


def _atomic_parquet(table: pa.Table, path: Path) -> None:
    with atomic_file(path) as tmp:
        pq.write_table(table, tmp)


def _atomic_json(path: Path, data: dict[str, Any]) -> None:
    with atomic_file(path) as tmp:
        tmp.write_text(json.dumps(data, indent=2, default=str))
