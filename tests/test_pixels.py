import warnings

import gymnasium
import numpy as np
import pytest

from senbench.cli.show import compare, sample_states
from senbench.observe.observations import make_env
from senbench.observe.pixels import PixelSpec, area_resize
from senbench.plugin.manager import registries
from senbench_classic.renderers import (
    draw_mountaincar,
    draw_pendulum,
    render_mountaincar,
    render_pendulum,
)


def darkness(frames, empty):
    """How much darker than the empty scene each pixel is."""
    return np.clip(empty.astype(float) - frames.astype(float), 0, None)


def test_the_car_moves_right_column_by_column_with_position():
    positions = np.linspace(-1.1, 0.45, 60)
    frames = draw_mountaincar(positions)
    empty = draw_mountaincar(np.array([-5.0]))[0]  # car far off screen: track and flag only
    mass = darkness(frames, empty)
    columns = (mass.sum(axis=1) * np.arange(64)).sum(axis=1) / mass.sum(axis=(1, 2))
    assert np.all(np.diff(columns) > 0)
    # gymnasium's mapping: x_pixel = (position + 1.2) * 600 / 1.8 * 64 / 600
    expected = (positions + 1.2) / 1.8 * 64
    assert np.abs(columns - expected).max() < 1.5


def test_a_car_moving_a_fiftieth_of_a_pixel_changes_the_frame():
    positions = np.linspace(-1.0, 0.4, 50)
    step = 0.0005  # metres per frame: 0.018 pixels at 64x64
    for draw in (draw_mountaincar, lambda p: render_mountaincar(np.stack([p, p], 1), (64, 64))):
        a, b = draw(positions), draw(positions + step)
        assert all((a[i] != b[i]).any() for i in range(len(positions)))


@pytest.mark.parametrize("size", [(64, 64), (48, 80)])
def test_the_rod_angle_reads_back_from_the_frame(size):
    angles = np.linspace(-np.pi + 0.01, np.pi - 0.01, 73)
    frames = draw_pendulum(angles, *size)
    mass = darkness(frames, np.full(size, 255))
    h, w = size
    ys, xs = np.mgrid[0:h, 0:w] + 0.5
    cx = (mass * xs).sum(axis=(1, 2)) / mass.sum(axis=(1, 2)) - w / 2
    cy = (mass * ys).sum(axis=(1, 2)) / mass.sum(axis=(1, 2)) - h / 2
    # angle 0 is upright, positive angles turn the rod counter-clockwise (to the left)
    read = np.arctan2(-cx * h / w, -cy)
    error = np.degrees(np.abs(np.angle(np.exp(1j * (read - angles)))))
    assert error.max() < 3.0


@pytest.mark.parametrize("env_name", ["mountaincar", "pendulum"])
def test_frames_are_gymnasiums_frames_greyed_and_area_resized(env_name):
    spec = registries().envs.get(env_name)
    states = sample_states(spec, 12, seed=1)
    _, theirs, ours = compare(spec, states, (64, 64))
    difference = np.abs(theirs.astype(int) - ours.astype(int))
    assert difference.mean() < 1.0  # grey levels, out of 255
    assert np.percentile(difference, 99.5) < 40


def test_the_fast_path_matches_the_exact_drawing():
    positions = np.random.default_rng(0).uniform(-1.2, 0.6, 300)
    angles = np.random.default_rng(1).uniform(-np.pi, np.pi, 300)
    fast = render_mountaincar(np.stack([positions, positions], 1), (64, 64))
    assert np.abs(fast.astype(int) - draw_mountaincar(positions).astype(int)).max() <= 2
    fast = render_pendulum(np.stack([angles, angles], 1), (64, 64))
    assert np.abs(fast.astype(int) - draw_pendulum(angles).astype(int)).max() <= 2
    wrapped = render_pendulum(np.array([[np.pi - 1e-9, 0], [-np.pi, 0]]), (64, 64))
    assert np.abs(wrapped[0].astype(int) - wrapped[1].astype(int)).max() <= 1


@pytest.mark.parametrize("env_id", ["senbench/PixelMountainCar-v0", "senbench/PixelPendulum-v0"])
def test_stack_is_oldest_first_and_refilled_at_reset(env_id):
    env = gymnasium.make(env_id, stack=3)
    render = registries().envs.get("mountaincar" if "Mountain" in env_id else "pendulum").render
    obs, info = env.reset(seed=0)
    assert obs.shape == (3, 64, 64) and obs.dtype == np.uint8
    assert (obs == obs[0]).all()  # a new episode starts with its first frame everywhere
    previous = obs
    for _ in range(5):
        obs, _, _, _, info = env.step(env.action_space.sample())
        assert (obs[:-1] == previous[1:]).all()  # shifted: oldest first, newest last
        assert (obs[-1] == render(info["state"][None], (64, 64))[0]).all()
        previous = obs
    assert not (obs[0] == obs[-1]).all()
    obs, _ = env.reset(seed=1)
    assert (obs == obs[0]).all()


@pytest.mark.parametrize("env_id", ["senbench/PixelMountainCar-v0", "senbench/PixelPendulum-v0"])
def test_pixel_envs_pass_gymnasium_and_sb3_checkers(env_id):
    from gymnasium.utils.env_checker import check_env
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        check_env(gymnasium.make(env_id).unwrapped)
        sb3_check_env(gymnasium.make(env_id))


def test_any_rgb_env_gets_pixels_through_gymnasium_render():
    cartpole = gymnasium.envs.classic_control.CartPoleEnv
    spec = registries().envs.get("mountaincar")
    # an env plugin without a renderer of its own: gymnasium's frames, grey, resized
    from dataclasses import replace

    third_party = replace(spec, name="cartpole", render=None, set_state=None,
                          make=lambda max_episode_steps, render_mode=None: gymnasium.wrappers.
                          TimeLimit(cartpole(render_mode=render_mode), max_episode_steps),
                          physical_state=lambda env: np.asarray(env.state))
    env = make_env(third_party, "pixels", 50, {}, PixelSpec(40, 60, 4))
    obs, info = env.reset(seed=0)
    assert obs.shape == (4, 40, 60) and obs.dtype == np.uint8
    assert env.observation_space.contains(obs)
    obs, *_ = env.step(0)
    assert obs.min() < 100 < obs.max()  # a dark cart on a white background
    assert "state" in info


def test_gymnasium_renderer_can_be_chosen_for_a_builtin_env():
    spec = registries().envs.get("mountaincar")
    ours = make_env(spec, "pixels", 200, {}, PixelSpec())
    theirs = make_env(spec, "pixels", 200, {}, PixelSpec(renderer="gymnasium"))
    a, _ = ours.reset(seed=3)
    b, _ = theirs.reset(seed=3)
    assert np.abs(a.astype(int) - b.astype(int)).mean() < 1.0


def test_area_resize_averages_blocks_and_keeps_constants():
    image = np.arange(36, dtype=float).reshape(6, 6)
    assert np.allclose(area_resize(image, 3, 2), image.reshape(3, 2, 2, 3).mean(axis=(1, 3)))
    assert np.allclose(area_resize(np.full((400, 600), 7.0), 64, 64), 7.0)


@pytest.mark.slow
def test_show_writes_a_comparison_png(tmp_path):
    import subprocess
    import sys

    out = tmp_path / "frames.png"
    done = subprocess.run([sys.executable, "-m", "senbench", "show", "pendulum", "--out",
                           str(out), "--frames", "3"], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "grey levels" in done.stdout
