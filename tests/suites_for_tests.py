"""Suite texts that several test modules use."""

# Tile-coded SARSA on the state: three cells of a second or so, 3 episodes each.
SARSA = """\
name: small
envs:
  mountaincar: {}
methods:
  sarsa-state: {agent: sarsa}
seeds: 3
budget: 1500
eval: {every: 500, episodes: 2}
"""

# SEN-SARSA with an encoder small enough to train in seconds: an indented `methods:` entry.
SEN_SARSA = """\
  sen-sarsa:
    agent: sarsa
    observation: encoded
    hyperparams: {tilings: 8, tiles: 6, trace_decay: 0.9}
    encoder:
      config: {widths: [8, 8, 16, 16], hidden: 32}
      samples: 300
      fraction: 1.0
      epochs: 2
      test_samples: 100
    pixels: {height: 32, width: 32}
"""

# An agent that sleeps each frame, so that a test can stop a run in the middle.
SLOW = """\
name: slow
envs:
  mountaincar: {}
methods:
  slow-state: {agent: slow, hyperparams: {sleep_s: 0.002}}
seeds: 6
budget: 600
eval: {every: 300, episodes: 1}
"""
