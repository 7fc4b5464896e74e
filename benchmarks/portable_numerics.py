"""Can a curve carry from one processor to another, and what would it cost?

A cell's curve reproduces bit for bit on the processor it ran on, not on another: MKL and
oneDNN pick their kernels by the processor, and torch vectorises with the widest
instruction set it finds (docs/running.md, "Reproducibility"). Each of those can be pinned
by an environment variable read when torch loads. This script runs, in a fresh process per
setting, a fingerprint of what a learner computes and the speed of the two costs that
dominate the grid:

- ``ppo-state`` and ``ppo-pixels`` on Pendulum, seed 0 (``suites/paper-pendulum.yaml``):
  the return of the evaluation at frame 0, before any update (an MLP's and a NatureCNN's
  forward passes, 10 episodes);
- a NatureCNN DQN update (batch 32 of 2x64x64, forward, backward, Adam, 3 steps from a
  seeded start) and a sen-resnet forward pass (batch 5): a digest of the weights / output;
- ms per NatureCNN update (batch 32) and per sen-resnet forward pass at batch 1.

Run it on two processors and compare the fingerprints: a setting whose fingerprints agree
on both makes curves portable between them, at the speed it prints.

    .venv/bin/python benchmarks/portable_numerics.py          (≈ 3 min)
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

from encoder_speed import rate

SETTINGS: dict[str, dict[str, str]] = {
    "default": {},
    # MKL's conditional numerical reproducibility, its code path common to all x86
    "mkl-compatible": {"MKL_CBWR": "COMPATIBLE"},
    # ... and torch's vector kernels and oneDNN's limited to AVX2, which both have
    "mkl-compatible, avx2": {"MKL_CBWR": "COMPATIBLE", "ATEN_CPU_CAPABILITY": "avx2",
                             "ONEDNN_MAX_CPU_ISA": "AVX2"},
    # ... and no oneDNN at all (convolutions by torch's own im2col + MKL), no vectorising
    "mkl-compatible, no onednn, scalar": {"MKL_CBWR": "COMPATIBLE",
                                          "ATEN_CPU_CAPABILITY": "default",
                                          "SENBENCH_NO_ONEDNN": "1"},
}
ROOT = Path(__file__).resolve().parent.parent


def digest(*tensors) -> str:
    h = hashlib.sha256()
    for t in tensors:
        h.update(t.detach().contiguous().numpy().tobytes())
    return h.hexdigest()[:12]


def per_call_ms(call) -> float:
    return 1000 / rate(1, call)


def frame0_returns() -> dict[str, str]:
    from senbench.plugin.manager import registries
    from senbench.run.batch import execute_cells
    from senbench.run.execute import RunInfo
    from senbench.suite import load_suite

    suite = load_suite(ROOT / "suites" / "paper-pendulum.yaml", registries())
    info = RunInfo.gather(ROOT / "results" / "encoders")
    out = {}
    for method in ("ppo-state", "ppo-pixels"):
        [cell] = suite.select([method], [], [0], [])
        [(rows, outcome)] = execute_cells([cell], info, stop_at=1)
        assert outcome.status == "ok", outcome.error
        first = next(r for r in rows if r["kind"] == "eval")
        out[method] = repr(first["return"])
    return out


def networks() -> dict[str, str]:
    import gymnasium as gym
    import numpy as np
    import torch
    from stable_baselines3.common.torch_layers import NatureCNN

    from senbench.encoders import EncoderRequest, build_model
    from senbench.observe.pixels import PixelSpec
    from senbench.plugin.manager import registries

    space = gym.spaces.Box(0, 255, (2, 64, 64), np.uint8)
    torch.manual_seed(0)
    cnn = torch.nn.Sequential(NatureCNN(space, 512), torch.nn.Linear(512, 3))
    adam = torch.optim.Adam(cnn.parameters(), lr=1e-4)
    frames = torch.randint(0, 256, (32, 2, 64, 64), generator=torch.Generator().manual_seed(1))
    x = frames.float() / 255
    target = torch.randn(32, 3, generator=torch.Generator().manual_seed(2))

    def update():
        loss = torch.nn.functional.smooth_l1_loss(cnn(x), target)
        adam.zero_grad()
        loss.backward()
        adam.step()

    for _ in range(3):
        update()
    out = {"NatureCNN update": digest(*cnn.parameters())}
    request = EncoderRequest("mountaincar", PixelSpec(), "sen-resnet", "uniform", 10, 1.0)
    torch.manual_seed(0)
    encoder = build_model(request, registries(), 2).eval()
    with torch.no_grad():
        out["sen-resnet forward"] = digest(encoder(x[:5]))
        out["ms sen-resnet batch 1"] = f"{per_call_ms(lambda: encoder(x[:1])):.2f}"
    out["ms NatureCNN update"] = f"{per_call_ms(update):.2f}"
    return out


def child() -> None:
    import torch

    from senbench.run.processes import set_threads
    from senbench.run.provenance import cpu_description

    if os.environ.get("SENBENCH_NO_ONEDNN"):
        torch.backends.mkldnn.enabled = False
    set_threads(1)
    result = {"cpu": cpu_description(), "torch dispatch": torch.backends.cpu.get_cpu_capability()}
    result.update(frame0_returns())
    result.update(networks())
    print(json.dumps(result))


def main() -> None:
    rows = {}
    for name, env in SETTINGS.items():
        run = subprocess.run([sys.executable, __file__, "--child"], capture_output=True,
                             text=True, env={**os.environ, **env}, check=True)
        rows[name] = json.loads(run.stdout.strip().splitlines()[-1])
    print(f"processor: {next(iter(rows.values()))['cpu']}")
    keys = [k for k in next(iter(rows.values())) if k != "cpu"]
    width = max(map(len, keys))
    for name, row in rows.items():
        print(f"\n{name}")
        for key in keys:
            print(f"  {key:{width}s}  {row[key]}")


if __name__ == "__main__":
    child() if sys.argv[1:] == ["--child"] else main()
