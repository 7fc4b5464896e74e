"""A state encoder built to read positions: convolutions to K feature maps, a spatial
softmax that turns each map into the expected (x, y) of where it fires — a keypoint — and
a small MLP from the 2K coordinates to the state (the deep spatial autoencoder's encoder of
Finn et al. 2016, "Deep Spatial Autoencoders for Visuomotor Learning", and Levine et al.
2016's visuomotor policies).

Where a car or a rod is in the frame is the state; the spatial softmax reads it as
coordinates in [-1, 1] at sub-pixel precision from coarse maps, so the network can be far
smaller than one that flattens a feature map. The frames of the stack enter as channels:
keypoints of the older and newer frame give velocity by their difference.
"""

from __future__ import annotations

from dataclasses import field
from typing import Annotated

from pydantic import Field
from pydantic.dataclasses import dataclass

from senbench import MEMORY_FORMATS, Choice, EncoderSpec

PositiveInt = Annotated[int, Field(ge=1)]


@dataclass
class KeypointsConfig:
    widths: Annotated[list[PositiveInt], Field(min_length=2, max_length=2)] = field(
        default_factory=lambda: [16, 32])
    """Channels of the two convolutions before the keypoint maps (5x5 stride 2, then 3x3
    stride 2: a 64x64 frame gives 16x16 maps)."""
    keypoints: PositiveInt = 16
    """Feature maps, each read as one (x, y) by the spatial softmax."""
    hidden: PositiveInt = 128
    """Units of the MLP's hidden layer."""


MIN_FRAME = 16
"""Two stride-2 convolutions leave 4x4 maps of a 16x16 frame: the coarsest a softmax
expectation still places a point in."""


def build(input_shape: tuple[int, int, int], outputs: int, config: KeypointsConfig):
    import torch
    from torch import nn

    stack, height, width = input_shape
    if min(height, width) < MIN_FRAME:
        raise ValueError(f"sen-keypoints needs frames of at least {MIN_FRAME} pixels a "
                         f"side, got {height}x{width}")

    class SpatialSoftmax(nn.Module):
        """(B, K, H, W) maps → (B, 2K): each map's softmax-weighted mean x and y, in
        [-1, 1], with a learned temperature."""

        def __init__(self, map_height: int, map_width: int):
            super().__init__()
            ys, xs = torch.meshgrid(torch.linspace(-1, 1, map_height),
                                    torch.linspace(-1, 1, map_width), indexing="ij")
            self.register_buffer("xs", xs.reshape(-1))
            self.register_buffer("ys", ys.reshape(-1))
            self.log_temperature = nn.Parameter(torch.zeros(()))

        def forward(self, maps):
            weights = torch.softmax(maps.flatten(2) / self.log_temperature.exp(), dim=-1)
            return torch.cat([weights @ self.xs, weights @ self.ys], dim=1)

    convolutions = nn.Sequential(
        nn.Conv2d(stack, config.widths[0], 5, 2, 2), nn.ReLU(),
        nn.Conv2d(config.widths[0], config.widths[1], 3, 2, 1), nn.ReLU(),
        nn.Conv2d(config.widths[1], config.keypoints, 3, 1, 1),
    )
    with torch.no_grad():
        maps = convolutions(torch.zeros(1, stack, height, width)).shape
    return nn.Sequential(
        convolutions,
        SpatialSoftmax(maps[2], maps[3]),
        nn.Linear(2 * config.keypoints, config.hidden), nn.ReLU(),
        nn.Linear(config.hidden, outputs),
    )


KEYPOINTS = EncoderSpec(
    name="sen-keypoints",
    build=build,
    config=KeypointsConfig,
    description="3 convolutions to K maps, a spatial softmax to K keypoints (x, y), an MLP",
    traceable=True,
    batch_independent=True,
    memory_formats=MEMORY_FORMATS,  # reshape, not view, after its convolutions
    min_frame_size=MIN_FRAME,
    search_space={"keypoints": Choice((8, 16, 32)), "hidden": Choice((64, 128, 256))},
)
