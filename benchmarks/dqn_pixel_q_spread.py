"""Does a pixel DQN's greedy action depend on the frame? Its Q-values over a fixed set of
frames, probed while it learns.

Pixel DQN on MountainCar plays one action through whole greedy evaluations while its
ε-greedy training episodes reach the flag (REPRODUCTION.md, Positive controls). This learns
a cell (its own settings and seed) and, at frame 0 and every ``--every`` frames from
``--start`` to ``--frames``, feeds its Q-network 64 fixed frames (a random policy's, every
10th step of 640, on the cell's env and observation pipeline) and prints:

- ``one action``: the share of the 64 frames whose greedy action is the most common one,
  and which action that is;
- ``V spread``: the standard deviation over the 64 frames of a frame's mean Q (over
  actions), how much the value the network gives a frame depends on it; ``A spread``: the
  standard deviation over the frames of each action's Q minus that mean (mean over
  actions), how much the preference between actions depends on the frame, against ``gap``:
  the mean difference between each frame's best and second-best Q. An A spread far below
  the gap means the greedy action does not depend on the frame;
- ``live``: the share of the CNN's feature units above 0 for at least one frame, and
  ``feature spread``: their standard deviation over the frames (mean over units);
- the training episodes that ended since the last probe.

    .venv/bin/python benchmarks/dqn_pixel_q_spread.py controls-pixels dqn-pixels mountaincar \
        --frames 40000 --start 20000 --every 2000   (under 10 min beside 3 other runs, 2 cores)
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from senbench.plugin.manager import registries
from senbench.run.execute import agent_context, seed_everything
from senbench.run.processes import set_threads
from senbench.suite import load_suite

SUITES = Path(__file__).resolve().parents[1] / "suites"


def fixed_frames(env, seed: int) -> torch.Tensor:
    """64 frames of a random policy: every 10th of 640 steps from a seeded reset."""
    rng = np.random.default_rng(seed)
    frames = []
    obs, _ = env.reset(seed=seed)
    for step in range(640):
        if step % 10 == 0:
            frames.append(obs.copy())
        obs, _, terminated, truncated, _ = env.step(int(rng.integers(env.action_space.n)))
        if terminated or truncated:
            obs, _ = env.reset()
    return torch.as_tensor(np.array(frames))


def probe(model, frames: torch.Tensor) -> str:
    with torch.inference_mode():
        q = model.policy.q_net(frames).numpy()
        net = model.policy.q_net  # SB3's own preprocessing (uint8 / 255), then the CNN
        features = net.extract_features(frames, net.features_extractor).numpy()
    counts = np.bincount(q.argmax(axis=1), minlength=q.shape[1])
    ranked = np.sort(q, axis=1)
    value = q.mean(axis=1, keepdims=True)
    return (f"one action {counts.max() / len(q):.2f} (action {counts.argmax()})  "
            f"Q mean {q.mean():8.3f}  V spread {value.std():.4f}  "
            f"A spread {(q - value).std(axis=0).mean():.4f}  "
            f"gap {(ranked[:, -1] - ranked[:, -2]).mean():.4f}  "
            f"live {(features > 0).any(axis=0).mean():.2f}  "
            f"feature spread {features.std(axis=0).mean():.4f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("suite"), parser.add_argument("method"), parser.add_argument("env")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--frames", type=int, default=40_000)
    parser.add_argument("--start", type=int, default=20_000)
    parser.add_argument("--every", type=int, default=1_000)
    args = parser.parse_args()
    set_threads(1)
    regs = registries()
    suite = load_suite(SUITES / f"{args.suite}.yaml", regs)
    [cell] = suite.select([args.method], [args.env], [args.seed])
    seed_everything(cell.seed)  # as a run seeds its cell: the same initial network
    ctx = agent_context(cell)
    agent = regs.agents.get(cell.agent).make(ctx)
    frames = fixed_frames(ctx.make_env(), seed=7)
    print(f"{cell.label}: {probe(agent.model, frames)}  [frame 0]", flush=True)
    episodes: list[str] = []

    class Probe:  # the Recorder protocol, probing instead of evaluating
        last = 0

        def step(self, frames_done: int) -> bool:
            if frames_done >= args.start and frames_done - self.last >= args.every:
                self.last = frames_done
                print(f"frame {frames_done:>7,}: {probe(agent.model, frames)}  "
                      f"episodes {' '.join(episodes) or '-'}", flush=True)
                episodes.clear()
            return frames_done < args.frames

        def episode(self, frames_done: int, ret: float, length: int) -> None:
            if frames_done >= args.start:
                episodes.append(f"{ret:.0f}")

    agent.learn(cell.budget, Probe())


if __name__ == "__main__":
    main()
