"""Built-in learners: tile-coded SARSA(λ) (the paper's discrete-action learner), PPO
(Stable-Baselines3, the paper's continuous-action learner), the end-to-end pixel
baselines DQN and Double DQN (Stable-Baselines3), and SAC with DrQ, its image-augmented
form, for discrete (on DQN) and continuous (on SAC) actions."""

import senbench
from senbench_agents.dqn import DDQN_SPEC, DQN_SPEC
from senbench_agents.drq import DRQ_SPEC
from senbench_agents.ppo import PPO_SPEC
from senbench_agents.sac import DRQ_SAC_SPEC, SAC_SPEC
from senbench_agents.sarsa import SARSA_SPEC


@senbench.hookimpl
def register_agents(register):
    register(SARSA_SPEC)
    register(PPO_SPEC)
    register(DQN_SPEC)
    register(DDQN_SPEC)
    register(DRQ_SPEC)
    register(SAC_SPEC)
    register(DRQ_SAC_SPEC)
