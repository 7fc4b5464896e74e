"""senbench env plugin: gymnasium's CartPole-v1 as the env ``cartpole``.

It gives senbench everything an env can: the dynamics (``make``), the physical state and
its bounds, a batched renderer (so pixel observations do not go through pygame), a way to
put the env in a chosen state (so the ``uniform`` sampler can draw labelled frames) and
the observation of a state (what a state encoder learns to predict).
"""

import gymnasium
import numpy as np

import senbench

LABELS = ("x", "x_dot", "theta", "theta_dot")
# CartPole-v1 ends an episode at |x| > 2.4 m and |theta| > 12 degrees; its velocities are
# unbounded, so these bounds on them are this example's choice (a tile coder, a grid or an
# encoder's clipping needs finite ones).
LOW = (-2.4, -3.0, -0.2095, -3.5)
HIGH = (2.4, 3.0, 0.2095, 3.5)


class BoundedObservation(gymnasium.ObservationWrapper):
    """CartPole's observation, clipped to the bounds above, with a bounded space."""

    def __init__(self, env: gymnasium.Env):
        super().__init__(env)
        self.observation_space = gymnasium.spaces.Box(
            np.array(LOW, np.float32), np.array(HIGH, np.float32), dtype=np.float32)

    def observation(self, observation):
        return np.clip(observation, LOW, HIGH).astype(np.float32)


def make_cartpole(max_episode_steps: int = 500, render_mode: str | None = None,
                  **options) -> gymnasium.Env:
    env = gymnasium.make("CartPole-v1", max_episode_steps=max_episode_steps,
                         render_mode=render_mode, **options)
    return BoundedObservation(env)


def physical_state(env) -> np.ndarray:
    """senbench passes the unwrapped env: CartPole keeps (x, x_dot, theta, theta_dot)."""
    return np.asarray(env.state, dtype=np.float64)


def set_state(env, state: np.ndarray) -> None:
    env.state = np.asarray(state, dtype=np.float64)
    env.steps_beyond_terminated = None


def observe(states: np.ndarray) -> np.ndarray:
    """The observation an agent on the true state gets: the state, clipped to the bounds."""
    return np.clip(states, LOW, HIGH).astype(np.float32)


def render(states: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """Grey frames of a batch of states, (B, 4) -> (B, H, W) uint8: a white background, a
    grey track, the cart as a dark box and the pole as a black bar. Only x and theta show:
    a stack of frames carries the velocities."""
    height, width = size
    states = np.asarray(states, dtype=np.float64)
    x, theta = states[:, 0, None, None], states[:, 2, None, None]
    # World to pixels: the track spans [-2.4, 2.4] m over the frame's width, with a margin.
    scale = width / 6.0
    rows = np.arange(height, dtype=np.float64)[None, :, None] + 0.5
    cols = np.arange(width, dtype=np.float64)[None, None, :] + 0.5
    track = 0.75 * height
    frame = np.full((len(states), height, width), 255.0)
    frame[:, int(track):int(track) + 1, :] = 160.0
    cart_x = width / 2 + x * scale
    cart_w, cart_h = 0.5 * scale, 0.3 * scale
    cart = (np.abs(cols - cart_x) <= cart_w / 2) & (rows <= track) & (rows >= track - cart_h)
    frame = np.where(cart, 80.0, frame)
    # The pole: a segment from the top of the cart, of 1 m (twice gymnasium's half-length).
    base_r, base_c = track - cart_h, cart_x
    tip_r = base_r - np.cos(theta) * 1.0 * scale
    tip_c = base_c + np.sin(theta) * 1.0 * scale
    seg_r, seg_c = tip_r - base_r, tip_c - base_c
    t = np.clip(((rows - base_r) * seg_r + (cols - base_c) * seg_c)
                / (seg_r**2 + seg_c**2), 0.0, 1.0)
    distance = np.hypot(rows - (base_r + t * seg_r), cols - (base_c + t * seg_c))
    frame = np.where(distance <= max(0.05 * scale, 0.75), 0.0, frame)
    return frame.astype(np.uint8)


CARTPOLE = senbench.EnvSpec(
    name="cartpole",
    make=make_cartpole,
    physical_state=physical_state,
    state_labels=LABELS,
    state_low=LOW,
    state_high=HIGH,
    actions="discrete",
    threshold=475.0,
    threshold_source="gymnasium CartPole-v1 reward_threshold",
    max_episode_steps=500,
    options={"sutton_barto_reward": bool},
    description="gymnasium CartPole-v1 dynamics; push left or right; reward +1 per step",
    render=render,
    set_state=set_state,
    observe=observe,
    observation_labels=LABELS,
)


@senbench.hookimpl
def register_envs(register):
    register(CARTPOLE)
