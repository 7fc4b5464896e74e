"""NHWC (``memory_format: channels_last``) against NCHW (``contiguous``) tensors, side by
side in one process: the state encoder's frames/s at the batch sizes a SEN cell runs (1,
and a seed batch's 3 and 5), and frames/s of each convolutional learner while it learns
(one torch thread, timed from its first update on). The two layouts alternate, round after
round, so a machine that is busy or changes clock speed weighs on both alike.

    .venv/bin/python benchmarks/memory_format.py          (≈ 6 min on an idle core)
"""

from __future__ import annotations

import time

import numpy as np
from learners import learning_rate, timed_settings

from senbench.encoders import EncoderRequest, StateEncoder, build_model, observation_bounds
from senbench.observe.pixels import PixelSpec
from senbench.plugin.manager import registries
from senbench.run.processes import set_threads

FORMATS = ("contiguous", "channels_last")
ROUNDS = 3
LEARNERS = [  # (agent, observation, env, frames timed)
    ("sarsa", "encoded", "mountaincar", 2_000),
    ("dqn", "pixels", "mountaincar", 1_000),
    ("drq", "pixels", "mountaincar", 600),
    ("ppo", "pixels", "pendulum", 1_028),
    ("sac", "pixels", "pendulum", 200),
    ("drq-sac", "pixels", "pendulum", 200),
]


def paper_encoder(env: str = "mountaincar") -> StateEncoder:
    """sen-resnet at the paper's size, untrained: its speed is the trained one's."""
    regs = registries()
    request = EncoderRequest(env, PixelSpec(), "sen-resnet", "uniform", 10, 1.0)
    low, high = observation_bounds(regs.envs.get(env))
    model = build_model(request, regs, len(low))
    return StateEncoder(model, np.zeros(len(low)), np.ones(len(low)), low, high,
                        traceable=regs.encoders.get("sen-resnet").traceable)


def encoder_rates(batch: int, passes: int = 200) -> dict[str, float]:
    base = paper_encoder()
    encoders = {name: base.laid_out(name) for name in FORMATS}
    frames = np.random.default_rng(0).integers(0, 256, (batch, 2, 64, 64), dtype=np.uint8)
    spent = dict.fromkeys(FORMATS, 0.0)
    for encoder in encoders.values():
        for _ in range(20):  # trace, freeze, warm the caches
            encoder(frames)
    for _ in range(ROUNDS):
        for name, encoder in encoders.items():
            start = time.perf_counter()
            for _ in range(passes):
                encoder(frames)
            spent[name] += time.perf_counter() - start
    return {name: ROUNDS * passes * batch / spent[name] for name in FORMATS}


def learner_rates(agent_name: str, observation: str, env_name: str,
                  frames: int) -> dict[str, float]:
    values = timed_settings(agent_name, observation, env_name)
    seconds = dict.fromkeys(FORMATS, 0.0)
    base = paper_encoder(env_name) if observation == "encoded" else None
    for _ in range(ROUNDS):
        for name in FORMATS:
            encoder = None if base is None else base.laid_out(name)
            rate = learning_rate(agent_name, observation, env_name, frames, values,
                                 encoder=encoder, memory_format=name)
            seconds[name] += frames / rate
    return {name: ROUNDS * frames / seconds[name] for name in FORMATS}


def main() -> None:
    set_threads(1)
    print(f"{'what':28s} {'NCHW f/s':>9s} {'NHWC f/s':>9s} {'NHWC/NCHW':>9s}")
    for batch in (1, 3, 5):
        rates = encoder_rates(batch)
        print(f"{f'sen-resnet, batch {batch}':28s} {rates['contiguous']:9.0f} "
              f"{rates['channels_last']:9.0f} "
              f"{rates['channels_last'] / rates['contiguous']:9.2f}", flush=True)
    for agent, observation, env, frames in LEARNERS:
        rates = learner_rates(agent, observation, env, frames)
        print(f"{f'{agent} {observation} {env}':28s} {rates['contiguous']:9.1f} "
              f"{rates['channels_last']:9.1f} "
              f"{rates['channels_last'] / rates['contiguous']:9.2f}", flush=True)


if __name__ == "__main__":
    main()
