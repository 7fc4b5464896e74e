"""The Nature-DQN convolutional network (Mnih et al. 2015) with a regression head: three
convolutions (8×8 stride 4, 4×4 stride 2, 3×3 stride 1), a hidden layer, the state."""

from __future__ import annotations

from typing import Annotated

from pydantic import Field
from pydantic.dataclasses import dataclass

from senbench import MEMORY_FORMATS, Choice, EncoderSpec

MIN_FRAME = 36
"""Its convolutions (8x8 stride 4, 4x4 stride 2, 3x3 stride 1) leave nothing of 35x35."""


@dataclass
class NatureCNNConfig:
    hidden: Annotated[int, Field(ge=1)] = 512
    """Units of the fully connected layer."""


def build(input_shape: tuple[int, int, int], outputs: int, config: NatureCNNConfig):
    import torch
    from torch import nn

    stack, height, width = input_shape
    if min(height, width) < MIN_FRAME:
        raise ValueError(f"nature-cnn needs frames of at least 36x36, got {height}x{width}")
    convolutions = nn.Sequential(
        nn.Conv2d(stack, 32, 8, 4), nn.ReLU(),
        nn.Conv2d(32, 64, 4, 2), nn.ReLU(),
        nn.Conv2d(64, 64, 3, 1), nn.ReLU(),
        nn.Flatten(),
    )
    with torch.no_grad():
        features = convolutions(torch.zeros(1, stack, height, width)).shape[1]
    return nn.Sequential(convolutions, nn.Linear(features, config.hidden), nn.ReLU(),
                         nn.Linear(config.hidden, outputs))


NATURE_CNN = EncoderSpec(
    name="nature-cnn",
    build=build,
    config=NatureCNNConfig,
    description="Nature-DQN CNN (3 convolutions, 1 hidden layer) regressing the state",
    traceable=True,
    batch_independent=True,
    memory_formats=MEMORY_FORMATS,  # reshape, not view, after its convolutions
    min_frame_size=MIN_FRAME,
    search_space={"hidden": Choice((128, 256, 512))},
)
