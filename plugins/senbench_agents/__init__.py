"""Built-in learners: tile-coded SARSA(λ) (the paper's discrete-action learner) and PPO
(Stable-Baselines3, the paper's continuous-action learner)."""

import senbench
from senbench_agents.ppo import PPO_SPEC
from senbench_agents.sarsa import SARSA_SPEC


@senbench.hookimpl
def register_agents(register):
    register(SARSA_SPEC)
    register(PPO_SPEC)
