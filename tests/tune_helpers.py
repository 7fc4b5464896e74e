"""What the tune tests share: suite texts (a tiny one-method suite, SEN-SARSA with a tune block,
two methods over two envs) and a ``senbench tune`` on the tiny one."""

import os
import subprocess
import sys
from pathlib import Path

import optuna
from suites_for_tests import SEN_SARSA

ROOT = Path(__file__).resolve().parents[1]


SUITE = """\
name: tiny
envs:
  mountaincar: {}
methods:
  sarsa-state: {agent: sarsa, hyperparams: {tilings: 8}}
seeds: 1
budget: 2000
eval: {every: 1000, episodes: 1}
"""


def tune(tmp_path, *args):
    env = {**os.environ, "COLUMNS": "200"}
    return subprocess.run([sys.executable, "-m", "senbench", "tune", str(tmp_path / "s.yaml"),
                           "--method", "sarsa-state", "--seeds", "2", "--seed", "0",
                           "--results", str(tmp_path / "results"), *args],
                          capture_output=True, text=True, env=env)


def study_of(tmp_path, name="sarsa-state-mountaincar-auc"):
    return optuna.load_study(study_name=name,
                             storage=f"sqlite:///{tmp_path / 'results' / 'tiny' / 'tune.db'}")


SEN = """\
name: sen
envs:
  mountaincar: {}
methods:
""" + SEN_SARSA + """seeds: 1
budget: 600
eval: {every: 300, episodes: 1}
tune:
  sen-sarsa:
    alpha: {low: 0.3, high: 0.8}
"""


TWO = """\
name: two
envs:
  mountaincar: {}
  pendulum: {}
methods:
  sarsa-state: {agent: sarsa, envs: [mountaincar], hyperparams: {tilings: 8}}
  sarsa-small: {agent: sarsa, envs: [mountaincar], hyperparams: {tilings: 4, tiles: 4}}
  ppo-state: {agent: ppo}
seeds: 1
budget: 1000
eval: {every: 500, episodes: 1}
"""
