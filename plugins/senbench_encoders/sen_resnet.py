"""The SEN-DRL state encoder network (Fang et al., Section 3, Fig. 2).

Four basic blocks, each two 3×3 convolutions with a shortcut jumping over them, the
resolution halved by each block; then two fully connected layers to the state. The
feature map is flattened, not pooled: where the car or the rod is in the frame is the
state, and global pooling would throw that away.
"""

from __future__ import annotations

from dataclasses import field
from typing import Annotated

import numpy as np
from pydantic import Field
from pydantic.dataclasses import dataclass

from senbench import MEMORY_FORMATS, Choice, EncoderSpec

PositiveInt = Annotated[int, Field(ge=1)]


@dataclass
class SenResNetConfig:
    widths: Annotated[list[PositiveInt], Field(min_length=4, max_length=4)] = field(
        default_factory=lambda: [16, 32, 64, 64])
    """Channels of the four blocks."""
    hidden: PositiveInt = 256
    """Units of the first fully connected layer."""
    batch_norm: bool = True
    first_stride: Annotated[int, Field(ge=1, le=2)] = 2
    """Stride of the first block. 2 (64×64 → 32, 16, 8, 4): 1.2k images/s training on 2
    cores; 1 keeps the first block at full resolution: 5× slower."""


def min_frame_size(config: SenResNetConfig) -> int:
    """Each block halves the resolution (the first by ``first_stride``), and the last
    feature map must keep at least 2x2 of where things are: 17 pixels a side at stride 2,
    9 at stride 1 (found by building every size from 8)."""
    return 8 * config.first_stride + 1


def build(input_shape: tuple[int, int, int], outputs: int, config: SenResNetConfig):
    import torch
    from torch import nn

    def norm(channels: int) -> nn.Module:
        return nn.BatchNorm2d(channels) if config.batch_norm else nn.Identity()

    class BasicBlock(nn.Module):
        def __init__(self, c_in: int, c_out: int, stride: int):
            super().__init__()
            self.conv1 = nn.Conv2d(c_in, c_out, 3, stride, 1, bias=not config.batch_norm)
            self.norm1 = norm(c_out)
            self.conv2 = nn.Conv2d(c_out, c_out, 3, 1, 1, bias=not config.batch_norm)
            self.norm2 = norm(c_out)
            self.shortcut = nn.Identity() if stride == 1 and c_in == c_out else nn.Sequential(
                nn.Conv2d(c_in, c_out, 1, stride, bias=not config.batch_norm), norm(c_out))

        def forward(self, x):
            y = torch.relu(self.norm1(self.conv1(x)))
            return torch.relu(self.norm2(self.conv2(y)) + self.shortcut(x))

    stack, height, width = input_shape
    widths = config.widths
    blocks = [BasicBlock(stack, widths[0], config.first_stride)]
    blocks += [BasicBlock(widths[i - 1], widths[i], 2) for i in range(1, 4)]
    trunk = nn.Sequential(*blocks).eval()  # eval: sizing must not touch batch-norm stats
    with torch.no_grad():
        shape = trunk(torch.zeros(1, stack, height, width)).shape
    trunk.train()
    if min(shape[2:]) < 2:
        raise ValueError(f"sen-resnet needs frames of at least {min_frame_size(config)}"
                         f" pixels a side, got {height}x{width}")
    features = int(np.prod(shape))
    return nn.Sequential(
        *blocks,
        nn.Flatten(),
        nn.Linear(features, config.hidden),
        nn.ReLU(),
        nn.Linear(config.hidden, outputs),
    )


SEN_RESNET = EncoderSpec(
    name="sen-resnet",
    build=build,
    config=SenResNetConfig,
    description="SEN-DRL's encoder: 4 residual blocks of two 3x3 convolutions, 2 FC layers",
    traceable=True,
    batch_independent=True,
    memory_formats=MEMORY_FORMATS,  # reshape, not view, after its convolutions
    min_frame_size=min_frame_size,
    search_space={"hidden": Choice((64, 128, 256, 512)), "batch_norm": Choice((True, False))},
)
