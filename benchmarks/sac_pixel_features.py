"""Why a pixel SAC plays one action on every frame: how many of its CNNs' features are alive.

drq-sac with NatureCNN's ReLU head (Linear → ReLU, 50 features) learned the Pendulum bars in
seed 1 and played one constant action at every evaluation of seed 0
(results/controls-drq-relu-head). This rebuilds controls-drq's drq-sac cell of a seed (the
suite's settings and seed; ``--head relu`` for the old head), learns the first frames with
an evaluation every 2,000, then feeds 512 frames of its replay buffer to the actor's and the
critic's CNNs and prints how many of the 50 features are above 0 on any of them (a ReLU
feature at 0 on every frame is dead: no gradient reaches it again), how much they vary over
the frames, and the spread of the actor's deterministic action over those frames.

    .venv/bin/python benchmarks/sac_pixel_features.py --seed 0 --head relu --actor-convs own
    .venv/bin/python benchmarks/sac_pixel_features.py --seed 0 --actor-convs own  (DrQ's head)
    .venv/bin/python benchmarks/sac_pixel_features.py --seed 0    (and DrQ's tie: the defaults)

each ≈ 10 min. With the actor's own convolutions, what its "features above 0" counts is the
actor's CNN; with DrQ's tie (the critic's convolutions under the actor's head) it counts the
actor's head over the critic's convolutions.

``--suite`` and ``--env`` rebuild another suite's drq-sac (or sac) cell instead, e.g. the
real Pendulum scene's (with the actor's own convolutions, its features stop varying over
frames within 2,000 frames; with DrQ's tie they do not):

    .venv/bin/python benchmarks/sac_pixel_features.py --suite paper-pendulum-plus \
        --env pendulum --seed 0 --actor-convs own                    (≈ 10 min)
    .venv/bin/python benchmarks/sac_pixel_features.py --suite paper-pendulum-plus \
        --env pendulum --seed 0 --frames 20000                       (≈ 25 min)
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from senbench.plugin.manager import registries
from senbench.run.evaluation import CellRecorder, Evaluator
from senbench.run.execute import agent_context, seed_everything
from senbench.suite import load_suite

SUITES = Path(__file__).resolve().parents[1] / "suites"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--frames", type=int, default=10_000)
    parser.add_argument("--head", choices=["relu", "layernorm-tanh"], default=None,
                        help="the CNNs' last layer (default: the suite's)")
    parser.add_argument("--suite", default="controls-drq", help="a suite of suites/")
    parser.add_argument("--env", default="pendulum-bars")
    parser.add_argument("--agent", choices=["drq-sac", "sac"], default="drq-sac")
    parser.add_argument("--actor-convs", choices=["own", "critic"], default=None,
                        help="the actor's convolutions (default: the suite's)")
    args = parser.parse_args()
    torch.set_num_threads(1)
    cells = [c for c in load_suite(SUITES / f"{args.suite}.yaml", registries()).cells
             if c.agent == args.agent and c.env == args.env and c.seed == args.seed
             and c.observation == "pixels"]
    if not cells:
        parser.error(f"{args.suite} has no {args.agent} cell on {args.env} pixels, seed "
                     f"{args.seed}")
    cell = cells[0]
    for field, value in (("features_head", args.head), ("actor_convs", args.actor_convs)):
        if value is not None:
            cell = cell.replace(hyperparams={**cell.hyperparams, field: value})
    seed_everything(cell.seed)
    ctx = agent_context(cell)
    agent = registries().agents.get(cell.agent).make(ctx)
    evaluate = Evaluator(ctx.make_env(), cell.eval_episodes, cell.seed)
    recorder = CellRecorder(args.frames, 2_000, lambda: evaluate(agent.act), None, None)
    agent.learn(args.frames, recorder)
    print(f"{cell.label}, head {ctx.config.features_head}, actor's convolutions "
          f"{ctx.config.actor_convs}, {args.frames:,} frames")
    for row in recorder.rows:
        if row.get("kind") == "eval":
            print(f"  eval at {row['step']:>6,}: return {row['return']:9.1f}, "
                  f"action std within it {row['action_std'][0]:.3f}")
    model = agent.model
    buffer = model.replay_buffer
    filled = buffer.buffer_size if buffer.full else buffer.pos
    rows = np.random.default_rng(0).choice(filled, min(512, filled), replace=False)
    observations = torch.as_tensor(buffer.observations[rows, 0])
    with torch.no_grad():
        for name, net in (("actor", model.actor), ("critic", model.critic)):
            features = net.extract_features(observations, net.features_extractor)
            alive = int((features > 0).any(0).sum())
            print(f"  {name:6} CNN: {alive} of {features.shape[1]} features above 0 on some "
                  f"frame; their std over frames, mean over features "
                  f"{float(features.std(0).mean()):.3f}")
        action = model.actor(observations, deterministic=True)
    print(f"  actor's action over {len(rows)} replay frames: mean {float(action.mean()):.3f}, "
          f"std {float(action.std()):.3f}")


if __name__ == "__main__":
    main()
