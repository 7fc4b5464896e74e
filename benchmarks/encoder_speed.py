"""State encoder speed on this machine: training images/s (batch 128, Adam) and inference
frames/s at batch 1 (what an agent pays per step) and batched, for each architecture at
2x64x64, with 1 thread and with every core; then, at batch 1, the encoder as an agent calls
it (uint8 frames in, clipped estimate out) eager and frozen into TorchScript, side by side.

    .venv/bin/python benchmarks/encoder_speed.py          (≈ 1 min)
"""

from __future__ import annotations

import time

import numpy as np
import torch

from senbench.encoders import EncoderRequest, StateEncoder, build_model
from senbench.observe.pixels import PixelSpec
from senbench.plugin.manager import registries
from senbench.run.processes import set_threads, usable_cores

SECONDS = 3.0


def rate(images_per_call: int, call) -> float:
    call()
    calls, start = 0, time.perf_counter()
    while (elapsed := time.perf_counter() - start) < SECONDS:
        call()
        calls += 1
    return calls * images_per_call / elapsed


def measure(arch: str, threads: int) -> tuple[float, float, float]:
    set_threads(threads)
    torch.manual_seed(0)
    request = EncoderRequest("mountaincar", PixelSpec(), arch, "uniform", 10, 1.0)
    model = build_model(request, registries(), 2)
    optimizer = torch.optim.Adam(model.parameters(), lr=1e-3)
    batch = torch.rand(128, 2, 64, 64)
    target = torch.rand(128, 2)

    def train_step():
        loss = ((model(batch) - target) ** 2).mean()
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()

    training = rate(128, train_step)
    model.eval()
    with torch.no_grad():
        single = rate(1, lambda: model(batch[:1]))
        batched = rate(128, lambda: model(batch))
    return training, single, batched


def agent_call(arch: str, traceable: bool) -> tuple[float, bool]:
    """Frames/s of ``StateEncoder`` at batch 1 on one thread, the per-step cost of an
    encoded observation; and whether it ran frozen (a trace that does not reproduce the
    eager output is dropped, and the encoder stays eager)."""
    set_threads(1)
    torch.manual_seed(0)
    request = EncoderRequest("mountaincar", PixelSpec(), arch, "uniform", 10, 1.0)
    encoder = StateEncoder(build_model(request, registries(), 2), np.zeros(2), np.ones(2),
                           np.full(2, -10.0), np.full(2, 10.0), traceable=traceable)
    frames = np.random.default_rng(0).integers(0, 256, (1, 2, 64, 64), dtype=np.uint8)
    speed = rate(1, lambda: encoder(frames))
    frozen = isinstance(encoder._frozen.get(frames.shape), torch.jit.ScriptModule)
    return speed, frozen


def main() -> None:
    cores = usable_cores()
    print(f"{'architecture':12s} {'threads':>7s} {'train img/s':>12s} {'infer b=1':>10s} "
          f"{'infer b=128':>12s}")
    for arch in ("sen-resnet", "nature-cnn"):
        for threads in sorted({1, cores}):
            training, single, batched = measure(arch, threads)
            print(f"{arch:12s} {threads:7d} {training:12,.0f} {single:10,.0f} {batched:12,.0f}")
    print("\nAs an agent calls it (StateEncoder, batch 1, 1 thread):")
    print(f"{'architecture':12s} {'eager µs':>9s} {'frozen µs':>10s} {'speed-up':>9s}")
    for arch in ("sen-resnet", "nature-cnn"):
        eager, _ = agent_call(arch, False)
        if not registries().encoders.get(arch).traceable:
            print(f"{arch:12s} {1e6 / eager:9.0f} {'— (not traceable)':>21s}")
            continue
        frozen, ok = agent_call(arch, True)
        note = "" if ok else "  (trace rejected: ran eager)"
        print(f"{arch:12s} {1e6 / eager:9.0f} {1e6 / frozen:10.0f} {frozen / eager:8.2f}x{note}")

if __name__ == "__main__":
    main()
