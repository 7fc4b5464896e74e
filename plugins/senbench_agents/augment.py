"""DrQ's image augmentation (Kostrikov, Yarats & Fergus 2020, section 3.1): a random shift.

Each frame stack of a batch is padded by ``pad`` pixels on every side, its edge pixels
repeated, and cropped back to its size at a random offset: a shift of up to ``pad`` pixels in
each direction. The stack's frames shift together (they show one moment and the motion
since the last); each stack of the batch draws its own shift. Padding then cropping is the
same as reading each output pixel from the input at the shifted position, clamped to the
frame, which is what :func:`random_shift` does: no padded copy, and uint8 stays uint8.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # torch is imported on first use: listing plugins does not import it
    import torch as th

from senbench_agents.sb3 import NATURE_CNN_MIN_FRAME

DRQ_PAD, DRQ_FRAME = 4, 84
"""DrQ pads its 84x84 frames by 4 pixels."""


def scaled_pad(height: int, width: int) -> int:
    """DrQ's pad scaled to a frame size: 4 pixels at 84, 3 at 64 (the same share of the
    frame), at least 1."""
    return max(1, round(DRQ_PAD * min(height, width) / DRQ_FRAME))


def min_frame_size(config: Any) -> int:
    """The smallest frame a DrQ learner (a config with ``pad``) takes: NatureCNN's 36, and
    twice the pad, since a shift moves a frame by at most half of it."""
    return max(NATURE_CNN_MIN_FRAME, 2 * (config.pad or 0))


def random_shift(frames: th.Tensor, pad: int, generator: th.Generator | None = None
                 ) -> th.Tensor:
    """``frames`` (B, stack, H, W), any dtype, each stack shifted by its own offsets
    (dy, dx), each uniform in [-pad, pad], edges repeated. ``pad`` 0 returns ``frames``."""
    if frames.ndim != 4:
        raise ValueError(f"random_shift takes (batch, stack, height, width) frames, got shape "
                         f"{tuple(frames.shape)}")
    batch, stack, height, width = frames.shape
    if pad < 0 or 2 * pad > min(height, width):
        raise ValueError(f"random_shift: pad must be in [0, {min(height, width) // 2}] for "
                         f"{height}x{width} frames (at most half the frame), got {pad}")
    if pad == 0:
        return frames
    import torch as th

    offsets = th.randint(-pad, pad + 1, (2, batch), generator=generator)
    rows = (th.arange(height)[None, :] + offsets[0][:, None]).clamp_(0, height - 1)
    cols = (th.arange(width)[None, :] + offsets[1][:, None]).clamp_(0, width - 1)
    index = (th.arange(batch)[:, None, None, None], th.arange(stack)[None, :, None, None],
             rows[:, None, :, None], cols[:, None, None, :])
    device = frames.device
    return frames[tuple(i.to(device) for i in index)]
