"""``senbench show``: our frames beside gymnasium's for the same states, as a PNG.

Each column is one state: gymnasium's own frame (full size, colour), gymnasium's frame in
grey area-resized to the observation size, and the env plugin's frame at that size. The
title gives the mean absolute difference of the last two rows in grey levels.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from senbench.errors import SenbenchError
from senbench.observe.pixels import area_resize, headless_pygame, quantize, to_gray
from senbench.plugin.specs import EnvSpec
from senbench.results.outputs import save_figure


def sample_states(spec: EnvSpec, count: int, seed: int) -> np.ndarray:
    """``count`` states drawn uniformly within the env's state bounds, sorted by the first
    dimension so that the row reads left to right."""
    rng = np.random.default_rng(seed)
    states = rng.uniform(spec.state_low, spec.state_high, size=(count, len(spec.state_low)))
    return states[np.argsort(states[:, 0])]


def gymnasium_frame(spec: EnvSpec, env, state: np.ndarray) -> np.ndarray:
    spec.set_state(env.unwrapped, state)
    return np.asarray(env.render())


def compare(spec: EnvSpec, states: np.ndarray, size: tuple[int, int]):
    """(gymnasium RGB frames, gymnasium grey resized, ours) for ``states``."""
    if spec.render is None or spec.set_state is None:
        raise SenbenchError(f"env '{spec.name}' has no renderer of its own to compare: "
                            "its pixel observations already are gymnasium's frames")
    headless_pygame()
    env = spec.make(max_episode_steps=spec.max_episode_steps, render_mode="rgb_array")
    env.reset(seed=0)
    full = [gymnasium_frame(spec, env, s) for s in states]
    env.close()
    resized = np.stack([quantize(area_resize(to_gray(f), *size)) for f in full])
    return full, resized, spec.render(states, size)


def save_comparison(spec: EnvSpec, out: Path, count: int = 8, size: tuple[int, int] = (64, 64),
                    seed: int = 0) -> float:
    """Write the comparison PNG; returns the mean absolute difference in grey levels."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    states = sample_states(spec, count, seed)
    full, resized, ours = compare(spec, states, size)
    difference = float(np.abs(resized.astype(int) - ours.astype(int)).mean())
    rows = [("gymnasium", full), (f"gymnasium, grey, area-resized to {size[0]}x{size[1]}",
                                  resized), (f"senbench at {size[0]}x{size[1]}", ours)]
    fig, axes = plt.subplots(3, count, figsize=(1.9 * count, 6.2), squeeze=False)
    for r, (label, frames) in enumerate(rows):
        for c in range(count):
            ax = axes[r][c]
            ax.imshow(frames[c], cmap="gray", vmin=0, vmax=255, interpolation="nearest")
            ax.set_xticks([])
            ax.set_yticks([])
            if c == 0:
                ax.set_ylabel(label, fontsize=8)
            if r == 0:
                text = ", ".join(f"{v:.3g}" for v in states[c])
                ax.set_title(f"({text})", fontsize=8)
    labels = ", ".join(spec.state_labels)
    fig.suptitle(f"{spec.name}: states ({labels}); mean |difference| of the last two rows "
                 f"{difference:.2f} grey levels", fontsize=10)
    fig.tight_layout()
    save_figure(fig, out, 100)
    return difference
