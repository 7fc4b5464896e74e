"""MountainCar and Pendulum drawn directly at the frame size, as gymnasium draws them.

The scene and its world-to-pixel mapping are gymnasium's (``classic_control/
mountain_car.py`` and ``pendulum.py`` ``render``), scaled from gymnasium's 600×400 and
500×500 screens to H×W; grey levels are the ITU-R 601 luma of gymnasium's colours. So a
frame here is what gymnasium's frame looks like after conversion to grey and area
resizing — without pygame, for a whole batch of states in one call. Gymnasium's
Pendulum also draws an arrow for the last torque; a frame here shows the state only.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from senbench_classic.drawing import (
    FrameTable,
    capsule_sdf,
    convex_polygon_sdf,
    coverage,
    ellipse_sdf,
    supersample,
    window_grid,
    window_origin,
)

WHITE = 255.0


def luma(r: float, g: float, b: float) -> float:
    return 0.299 * r + 0.587 * g + 0.114 * b


# --- MountainCar (gymnasium: 600x400 screen) -----------------------------------------------

MC_SCREEN_W, MC_SCREEN_H = 600, 400
MC_MIN_X, MC_MAX_X, MC_GOAL_X = -1.2, 0.6, 0.5
MC_SCALE = MC_SCREEN_W / (MC_MAX_X - MC_MIN_X)  # screen pixels per metre
CAR_W, CAR_H, CLEARANCE, WHEEL_R = 40.0, 20.0, 10.0, 8.0  # gymnasium: int(carheight / 2.5)
WHEEL_GREY = luma(128, 128, 128)
FLAG_GREY = luma(204, 204, 0)


def mc_height(x):
    return np.sin(3 * x) * 0.45 + 0.55


@functools.lru_cache(maxsize=8)
def _mountaincar_scene(height: int, width: int):
    """Static layers: the background with the track, and the flag drawn over the car as
    (alpha, premultiplied grey)."""
    sx, sy = width / MC_SCREEN_W, height / MC_SCREEN_H

    def screen(x, y):  # output pixel coordinates -> gymnasium screen coordinates (y up)
        return x / sx, (height - y) / sy

    def track(x, y):
        u, v = screen(x, y)
        world = u / MC_SCALE + MC_MIN_X
        slope = 3 * 0.45 * np.cos(3 * world)  # gymnasium's aalines: one screen pixel wide
        return np.abs(v - mc_height(world) * MC_SCALE) * np.cos(np.arctan(slope)) <= 0.5

    flag_x = int((MC_GOAL_X - MC_MIN_X) * MC_SCALE)
    flag_y1 = int(mc_height(MC_GOAL_X) * MC_SCALE)
    flag_y2 = flag_y1 + 50

    def pole(x, y):
        u, v = screen(x, y)
        return (u >= flag_x) & (u < flag_x + 1) & (v >= flag_y1) & (v <= flag_y2)

    def cloth(x, y):  # triangle (flag_x, y2), (flag_x, y2 - 10), (flag_x + 25, y2 - 5)
        u, v = screen(x, y)
        dx = u - flag_x
        return (dx >= 0) & (dx <= 25) & (np.abs(v - (flag_y2 - 5)) <= 5 * (1 - dx / 25))

    background = WHITE * (1 - supersample(track, height, width))
    a_pole, a_cloth = supersample(pole, height, width), supersample(cloth, height, width)
    flag_alpha = 1 - (1 - a_pole) * (1 - a_cloth)
    flag_grey = FLAG_GREY * a_cloth  # the pole is black: it only removes light
    static = (background * (1 - flag_alpha) + flag_grey + 0.5).astype(np.uint8)
    f32 = np.float32
    return background.astype(f32), flag_alpha.astype(f32), flag_grey.astype(f32), static


def draw_mountaincar(positions: np.ndarray, height: int = 64, width: int = 64) -> np.ndarray:
    """Frames (B, height, width) uint8 of the car at ``positions`` (metres), drawn exactly."""
    positions = np.asarray(positions, dtype=np.float64).reshape(-1)
    background, flag_alpha, flag_grey, static = _mountaincar_scene(height, width)
    sx, sy = width / MC_SCREEN_W, height / MC_SCREEN_H
    # The car's anchor (bottom centre of the body) and tilt, as gymnasium computes them:
    # gymnasium rotates the car by cos(3x) radians (not by the slope's angle).
    anchor_u = (positions - MC_MIN_X) * MC_SCALE
    anchor_v = CLEARANCE + mc_height(positions) * MC_SCALE
    angle = np.cos(3 * positions)
    cos, sin = np.cos(angle), np.sin(angle)

    def to_pixels(lx, ly):  # car frame (screen pixels) -> output pixel coordinates
        u = anchor_u + lx * cos - ly * sin
        v = anchor_v + lx * sin + ly * cos
        return (u * sx)[:, None, None], (height - v * sy)[:, None, None]

    reach = math.hypot(CAR_W / 2, CAR_H)  # farthest body point from the anchor
    win_w = min(width, 2 * int(math.ceil(reach * sx + 1.5)) + 1)
    win_h = min(height, 2 * int(math.ceil(reach * sy + 1.5)) + 1)
    cx, cy = to_pixels(0.0, CAR_H / 2)
    x0 = window_origin(cx[:, 0, 0], win_w, width)
    y0 = window_origin(cy[:, 0, 0], win_h, height)
    px, py, rows, cols = window_grid(x0, y0, win_h, win_w)

    corners = [to_pixels(lx, ly) for lx, ly in
               ((-CAR_W / 2, 0), (-CAR_W / 2, CAR_H), (CAR_W / 2, CAR_H), (CAR_W / 2, 0))]
    body = coverage(convex_polygon_sdf(px, py, [c[0] for c in corners], [c[1] for c in corners]))
    wheels = np.zeros_like(body)
    for lx in (CAR_W / 4, -CAR_W / 4):
        wx, wy = to_pixels(lx, 0.0)
        wheels += coverage(ellipse_sdf(px, py, wx, wy, WHEEL_R * sx, WHEEL_R * sy))
    wheels = np.minimum(wheels, 1.0)

    frames = np.empty((len(positions), height, width), dtype=np.uint8)
    frames[:] = static  # track and flag; the window is redrawn with the car in between
    window = background[rows, cols] * (1 - body)  # the body is black
    window = window * (1 - wheels) + WHEEL_GREY * wheels
    window = window * (1 - flag_alpha[rows, cols]) + flag_grey[rows, cols]
    frames[np.arange(len(positions))[:, None, None], rows, cols] = (window + 0.5).astype(np.uint8)
    return frames


# --- Pendulum (gymnasium: 500x500 screen) ---------------------------------------------------

PD_SCREEN = 500
PD_SCALE = PD_SCREEN / (2.2 * 2)  # screen pixels per metre
ROD_LENGTH, ROD_RADIUS = 1.0 * PD_SCALE, 0.2 * PD_SCALE / 2
AXLE_R = int(0.05 * PD_SCALE)  # gymnasium draws the axle with an integer radius
ROD_GREY = luma(204, 77, 77)


@functools.lru_cache(maxsize=8)
def _pendulum_scene(height: int, width: int):
    """The axle, drawn over the rod, as alpha over black; and the frame with no rod."""
    sx, sy = width / PD_SCREEN, height / PD_SCREEN

    def axle(x, y):
        u, v = x / sx - PD_SCREEN / 2, (height - y) / sy - PD_SCREEN / 2
        return u * u + v * v <= AXLE_R * AXLE_R

    alpha = supersample(axle, height, width).astype(np.float32)
    static = (WHITE * (1 - alpha) + 0.5).astype(np.uint8)
    return alpha, static


def draw_pendulum(angles: np.ndarray, height: int = 64, width: int = 64) -> np.ndarray:
    """Frames (B, height, width) uint8 of the pendulum at ``angles`` (rad, 0 = upright),
    drawn exactly."""
    angles = np.asarray(angles, dtype=np.float64).reshape(-1)
    axle_alpha, static = _pendulum_scene(height, width)
    sx, sy = width / PD_SCREEN, height / PD_SCREEN
    # gymnasium rotates the rod by angle + pi/2 from the x axis, about the screen centre.
    centre_x, centre_y = PD_SCREEN / 2 * sx, height - PD_SCREEN / 2 * sy
    end_x = centre_x + ROD_LENGTH * np.cos(angles + np.pi / 2) * sx
    end_y = centre_y - ROD_LENGTH * np.sin(angles + np.pi / 2) * sy
    scale = math.sqrt(sx * sy)  # exact for square frames, the usual case
    half_w = int(math.ceil((ROD_LENGTH / 2 + ROD_RADIUS) * sx + 1.5))
    half_h = int(math.ceil((ROD_LENGTH / 2 + ROD_RADIUS) * sy + 1.5))
    win_w, win_h = min(width, 2 * half_w + 1), min(height, 2 * half_h + 1)
    x0 = window_origin((centre_x + end_x) / 2, win_w, width)
    y0 = window_origin((centre_y + end_y) / 2, win_h, height)
    px, py, rows, cols = window_grid(x0, y0, win_h, win_w)
    rod = coverage(capsule_sdf(px, py, centre_x, centre_y, end_x[:, None, None],
                               end_y[:, None, None], ROD_RADIUS * scale))
    window = WHITE * (1 - rod) + ROD_GREY * rod
    window = window * (1 - axle_alpha[rows, cols])  # the axle is black
    frames = np.empty((len(angles), height, width), dtype=np.uint8)
    frames[:] = static
    frames[np.arange(len(angles))[:, None, None], rows, cols] = (window + 0.5).astype(np.uint8)
    return frames


# --- fast path ------------------------------------------------------------------------------

POSES = 4096
"""Table poses over a pose's range: neighbouring entries differ by ~1/60 of a pixel."""


@functools.lru_cache(maxsize=8)
def mountaincar_table(height: int, width: int) -> FrameTable:
    return FrameTable(lambda p: draw_mountaincar(p, height, width), MC_MIN_X, MC_MAX_X, POSES)


@functools.lru_cache(maxsize=8)
def pendulum_table(height: int, width: int) -> FrameTable:
    return FrameTable(lambda a: draw_pendulum(a, height, width), -np.pi, np.pi, POSES,
                      periodic=True)


def render_mountaincar(states: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """Frames of physical states (B, 2) = (position, velocity); the frame shows position."""
    return mountaincar_table(*size)(np.asarray(states)[:, 0])


def render_pendulum(states: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """Frames of physical states (B, 2) = (angle, angular velocity); the frame shows angle."""
    return pendulum_table(*size)(np.asarray(states)[:, 0])
