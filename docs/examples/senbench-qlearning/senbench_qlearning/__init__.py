"""senbench agent plugin: ``qlearning``, one-step Q-learning on a table indexed by a grid
over the observation's bounds.

It runs on the true state or on an encoder's estimate of it (``state``, ``encoded``), for
any env with discrete actions and a bounded observation space.
"""

from dataclasses import dataclass

import numpy as np

import senbench


@dataclass
class QLearningConfig:
    bins: int = 8
    """Grid cells per observation dimension: the table has bins ** d rows."""
    alpha: float = 0.1
    """Step size of each update."""
    gamma: float = 0.99
    """Discount factor."""
    epsilon: float = 0.1
    """Probability of a random action while learning (evaluation is greedy)."""

    def __post_init__(self):
        # A ValueError here is a validation error at the suite's own key and line.
        if self.bins < 2:
            raise ValueError(f"bins must be at least 2, got {self.bins}")
        if not 0 <= self.epsilon <= 1:
            raise ValueError(f"epsilon must be in [0, 1], got {self.epsilon}")


class QLearningAgent:
    def __init__(self, ctx: senbench.AgentContext):
        self.config = ctx.config
        self.seed = ctx.seed
        self.rng = np.random.default_rng(ctx.seed)
        self.env = ctx.make_env()  # the cell's observation pipeline: state or encoded
        space = self.env.observation_space
        self.low = np.asarray(space.low, dtype=np.float64).ravel()
        self.high = np.asarray(space.high, dtype=np.float64).ravel()
        self.actions = int(self.env.action_space.n)
        self.q = np.zeros((self.config.bins ** self.low.size, self.actions))

    def _row(self, observation: np.ndarray) -> int:
        scaled = (np.asarray(observation, dtype=np.float64).ravel() - self.low) / (
            self.high - self.low)
        cells = np.clip((scaled * self.config.bins).astype(int), 0, self.config.bins - 1)
        return int(np.ravel_multi_index(cells, (self.config.bins,) * cells.size))

    def act(self, observation: np.ndarray) -> int:
        """The greedy action: what evaluation plays."""
        return int(np.argmax(self.q[self._row(observation)]))

    def learn(self, budget: int, recorder: senbench.Recorder) -> None:
        cfg = self.config
        steps = 0
        if not recorder.step(steps):  # evaluates the untrained policy at frame 0
            return
        observation, _ = self.env.reset(seed=self.seed)
        row = self._row(observation)
        episode_return, length = 0.0, 0
        while True:
            if self.rng.random() < cfg.epsilon:
                action = int(self.rng.integers(self.actions))
            else:
                action = int(np.argmax(self.q[row]))
            observation, reward, terminated, truncated, _ = self.env.step(action)
            next_row = self._row(observation)
            target = float(reward) + (0.0 if terminated else cfg.gamma * self.q[next_row].max())
            self.q[row, action] += cfg.alpha * (target - self.q[row, action])
            row = next_row
            steps += 1
            episode_return += float(reward)
            length += 1
            if terminated or truncated:
                recorder.episode(steps, episode_return, length)
                observation, _ = self.env.reset()
                row = self._row(observation)
                episode_return, length = 0.0, 0
            if not recorder.step(steps):  # False once the budget is spent
                return


QLEARNING = senbench.AgentSpec(
    name="qlearning",
    make=QLearningAgent,
    config=QLearningConfig,
    actions=frozenset({"discrete"}),
    observations=frozenset({"state", "encoded"}),
    defaults={
        # Per env (or "env:observation"), with where the values come from: recorded with
        # every result. These are this example's own choice, not tuned.
        "cartpole": senbench.AgentDefaults(
            values={"bins": 6, "alpha": 0.2},
            source="senbench-qlearning example: chosen by hand, not tuned",
        ),
    },
    description="one-step Q-learning on a grid over the observation bounds",
    needs_bounded_observations=True,  # the grid spans the bounds: validation checks them
    search_space={  # what `senbench tune` searches
        "bins": senbench.Int(4, 12),
        "alpha": senbench.Float(0.01, 1.0, log=True),
        "epsilon": senbench.Float(0.01, 0.3),
    },
)


@senbench.hookimpl
def register_agents(register):
    register(QLEARNING)
