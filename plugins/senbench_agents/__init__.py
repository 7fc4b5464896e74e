"""Built-in learners: tile-coded SARSA(λ) (the paper's discrete-action learner), PPO
(Stable-Baselines3, the paper's continuous-action learner), and the end-to-end pixel
baselines DQN and Double DQN (Stable-Baselines3)."""

import senbench
from senbench_agents.dqn import DDQN_SPEC, DQN_SPEC
from senbench_agents.ppo import PPO_SPEC
from senbench_agents.sarsa import SARSA_SPEC


@senbench.hookimpl
def register_agents(register):
    register(SARSA_SPEC)
    register(PPO_SPEC)
    register(DQN_SPEC)
    register(DDQN_SPEC)
