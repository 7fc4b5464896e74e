"""Anti-aliased drawing of simple shapes into batches of grayscale frames, with NumPy.

A pixel's value is the area of it a shape covers. Moving parts are drawn from signed
distance fields: coverage = clip(0.5 − d, 0, 1), with d the signed distance (in output
pixels) from the pixel's centre to the shape's edge, so that a shift of a hundredth of a
pixel still changes the frame — an encoder can only read a velocity it can see. Static
parts (a track, a flag) are drawn once per frame size by supersampling and composited.

Coordinates are output pixels: x to the right, y down, pixel (i, j) centred at
(j + 0.5, i + 0.5). Shape parameters broadcast against the pixel grids, so one call draws a
whole batch.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np


def coverage(distance: np.ndarray) -> np.ndarray:
    """Share of a pixel inside a shape, from the signed distance of its centre."""
    return np.clip(0.5 - distance, 0.0, 1.0)


def segment_distance(px, py, ax, ay, bx, by) -> np.ndarray:
    """Unsigned distance from points to the segment a–b."""
    pax, pay = px - ax, py - ay
    bax, bay = bx - ax, by - ay
    length2 = np.maximum(bax * bax + bay * bay, 1e-12)
    h = np.clip((pax * bax + pay * bay) / length2, 0.0, 1.0)
    return np.hypot(pax - bax * h, pay - bay * h)


def convex_polygon_sdf(px, py, xs: list, ys: list) -> np.ndarray:
    """Signed distance to a convex polygon with vertices (xs[k], ys[k]) in either winding
    order; negative inside."""
    n = len(xs)
    distance = None
    sides = []
    for k in range(n):
        ax, ay, bx, by = xs[k], ys[k], xs[(k + 1) % n], ys[(k + 1) % n]
        d = segment_distance(px, py, ax, ay, bx, by)
        distance = d if distance is None else np.minimum(distance, d)
        sides.append((bx - ax) * (py - ay) - (by - ay) * (px - ax))
    inside = np.all([s >= 0 for s in sides], axis=0) | np.all([s <= 0 for s in sides], axis=0)
    return np.where(inside, -distance, distance)


def ellipse_sdf(px, py, cx, cy, rx, ry) -> np.ndarray:
    """Approximate signed distance to an axis-aligned ellipse (exact for circles): a
    circle drawn into a non-square frame becomes one."""
    qx, qy = (px - cx) / rx, (py - cy) / ry
    k0 = np.hypot(qx, qy)
    k1 = np.maximum(np.hypot(qx / rx, qy / ry), 1e-12)
    return k0 * (k0 - 1.0) / k1


def capsule_sdf(px, py, ax, ay, bx, by, radius) -> np.ndarray:
    """Signed distance to a segment with round caps (a rod)."""
    return segment_distance(px, py, ax, ay, bx, by) - radius


def supersample(inside: Callable[[np.ndarray, np.ndarray], np.ndarray], height: int,
                width: int, samples: int = 8) -> np.ndarray:
    """Coverage (height, width) of a static shape, by testing samples² points per pixel;
    ``inside(x, y)`` takes output-pixel coordinates."""
    offsets = (np.arange(samples) + 0.5) / samples
    x = (np.arange(width)[:, None] + offsets[None, :]).reshape(-1)
    y = (np.arange(height)[:, None] + offsets[None, :]).reshape(-1)
    hits = inside(x[None, :], y[:, None]).astype(np.float32)
    return hits.reshape(height, samples, width, samples).mean(axis=(1, 3))


def window_grid(x0: np.ndarray, y0: np.ndarray, height: int, width: int):
    """Pixel-centre coordinates (B, h, 1) and (B, 1, w) of per-frame windows whose
    top-left pixels are (x0, y0), and the integer indices to gather or scatter them."""
    rows = y0[:, None, None] + np.arange(height)[None, :, None]
    cols = x0[:, None, None] + np.arange(width)[None, None, :]
    return cols + 0.5, rows + 0.5, rows, cols


def window_origin(centre: np.ndarray, size: int, limit: int) -> np.ndarray:
    """Top-left index of a window of ``size`` pixels centred near ``centre``, kept inside
    ``[0, limit)``."""
    return np.clip(np.floor(centre).astype(np.int64) - size // 2, 0, max(limit - size, 0))


class FrameTable:
    """Frames that depend on one scalar pose (MountainCar's position, Pendulum's angle),
    drawn once on a fine grid and linearly interpolated in between.

    With ``n`` poses over the range, neighbouring table frames differ by a tiny shift, and
    coverage varies linearly with such a shift, so interpolation reproduces the drawn frame
    to about a grey level (tested) at a fraction of the cost.
    """

    def __init__(self, draw: Callable[[np.ndarray], np.ndarray], low: float, high: float,
                 n: int, periodic: bool = False, batch: int = 256):
        self.low, self.high, self.n, self.periodic = low, high, n, periodic
        count = n if periodic else n + 1
        poses = low + (high - low) * np.arange(count) / n
        parts = [draw(poses[i:i + batch]) for i in range(0, count, batch)]
        table = np.concatenate(parts)
        self.table = table.reshape(count, -1)  # uint8: 16 MB for 4096 frames of 64x64
        self.shape = table.shape[1:]

    def __call__(self, poses: np.ndarray) -> np.ndarray:
        t = (np.asarray(poses, dtype=np.float64) - self.low) / (self.high - self.low) * self.n
        if self.periodic:
            t = np.mod(t, self.n)
        else:
            t = np.clip(t, 0.0, self.n)
        i0 = np.minimum(np.floor(t).astype(np.int64), self.n - 1)
        i1 = (i0 + 1) % self.n if self.periodic else i0 + 1
        f = (t - i0).astype(np.float32)[:, None]
        out = np.empty((len(t), self.table.shape[1]), dtype=np.uint8)
        for s in range(0, len(t), 512):  # chunks: float temporaries stay in cache
            a = self.table[i0[s:s + 512]].astype(np.float32)
            frames = a + (self.table[i1[s:s + 512]] - a) * f[s:s + 512]
            out[s:s + 512] = frames + 0.5
        return out.reshape(len(t), *self.shape)
