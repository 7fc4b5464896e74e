import subprocess
import sys

import pytest

from senbench.errors import SuiteError
from senbench.plugin.manager import registries
from senbench.suite import load_suite

GOOD = """\
name: grid
envs:
  mountaincar: {max_episode_steps: 300, threshold: -120}
  pendulum: {budget: 4000}
methods:
  sarsa-state:
    agent: sarsa
    envs: [mountaincar]
    hyperparams: {alpha: 0.8}
  ppo-state:
    agent: ppo
    observation: state
seeds: [0, 1, 2]
budget: 2000
eval: {every: 1000, episodes: 2}
variants:
  sarsa-state:
    hyperparams.trace_decay: [0.8, 0.9]
"""


def load(write_suite, text):
    return load_suite(write_suite(text), registries())


def test_a_good_suite_expands_into_its_grid(write_suite):
    suite = load(write_suite, GOOD)
    # sarsa: 1 env x 2 variants x 3 seeds; ppo: 2 envs x 3 seeds
    assert len(suite.cells) == 6 + 6
    sarsa = [c for c in suite.cells if c.method == "sarsa-state"]
    assert {c.variant for c in sarsa} == {"hyperparams.trace_decay=0.8",
                                          "hyperparams.trace_decay=0.9"}
    cell = sarsa[0]
    assert cell.hyperparams["alpha"] == 0.8  # the suite overrides the env default
    assert cell.hyperparams["tilings"] == 16  # sarsa's mountaincar default
    assert (cell.env, cell.max_episode_steps, cell.env_options, cell.threshold) == (
        "mountaincar", 300, {}, -120)
    ppo_pendulum = next(c for c in suite.cells if c.env == "pendulum")
    assert ppo_pendulum.budget == 4000
    assert ppo_pendulum.hyperparams["n_envs"] == 4  # zoo default for Pendulum
    assert "rl-baselines3-zoo" in ppo_pendulum.hyperparams_source


def test_cell_ids_are_stable_and_follow_the_config(write_suite):
    ids = [c.id for c in load(write_suite, GOOD).cells]
    assert ids == [c.id for c in load(write_suite, GOOD).cells]
    assert len(set(ids)) == len(ids)
    reordered = GOOD.replace("seeds: [0, 1, 2]\nbudget: 2000\n", "budget: 2000\nseeds: [0, 1, 2]\n")
    assert sorted(ids) == sorted(c.id for c in load(write_suite, reordered).cells)
    changed = load(write_suite, GOOD.replace("alpha: 0.8", "alpha: 0.7")).cells
    moved = {c.id for c in changed} - set(ids)
    assert len(moved) == 6 and all(c.method == "sarsa-state" for c in changed if c.id in moved)


def test_seed_count_means_seeds_from_zero(write_suite):
    suite = load(write_suite, GOOD.replace("seeds: [0, 1, 2]", "seeds: 2"))
    assert sorted({c.seed for c in suite.cells}) == [0, 1]


BAD = {
    "typo in a key": (
        GOOD.replace("    agent: sarsa\n", "    agnet: sarsa\n"),
        ["suite.yaml:7", "methods.sarsa-state.agnet", "Did you mean 'agent'?"],
    ),
    "unknown agent": (
        GOOD.replace("agent: sarsa", "agent: sarsaa"),
        ["suite.yaml:7", "methods.sarsa-state.agent", "unknown agent 'sarsaa'",
         "Known agents: ddqn, dqn, drq, drq-sac, ppo, sac, sarsa"],
    ),
    "unknown env": (
        GOOD.replace("  pendulum: {budget: 4000}", "  cartpole: {}"),
        ["suite.yaml:4", "envs.cartpole", "Known envs: mountaincar, mountaincar-bars, pendulum"],
    ),
    "unknown hyperparameter": (
        GOOD.replace("alpha: 0.8", "alhpa: 0.8"),
        ["suite.yaml:9", "hyperparams.alhpa", "Did you mean 'alpha'?"],
    ),
    "wrong type": (
        GOOD.replace("alpha: 0.8", "alpha: fast"),
        ["suite.yaml:9", "hyperparams.alpha", "'fast'"],
    ),
    "discrete agent on a continuous env": (
        GOOD.replace("    envs: [mountaincar]\n", ""),
        ["methods.sarsa-state", "continuous actions", "envs: [...]"],
    ),
    "observation not available": (
        GOOD.replace("    observation: state", "    observation: pixel"),
        ["suite.yaml:12", "unknown observation 'pixel'"],
    ),
    "duplicate key": (
        GOOD.replace("seeds: [0, 1, 2]", "seeds: [0, 1, 2]\nseeds: [3]"),
        ["suite.yaml:14", "'seeds' appears twice (first on line 13)"],
    ),
    "not yaml": (
        GOOD.replace("eval: {every: 1000, episodes: 2}", "eval: {every: 1000, episodes: 2"),
        ["suite.yaml:", "not valid YAML"],
    ),
    "missing key": (
        GOOD.replace("budget: 2000\n", ""),
        ["budget: required key is missing"],
    ),
    "evaluation sparser than the budget": (
        GOOD.replace("every: 1000", "every: 3000"),
        ["eval.every", "budget on mountaincar is 2000"],
    ),
    "variant of an unknown parameter": (
        GOOD.replace("hyperparams.trace_decay", "hyperparams.trace_decy"),
        ["variants.sarsa-state.hyperparams.trace_decy", "Did you mean 'trace_decay'?"],
    ),
    "env option unknown": (
        GOOD.replace("{max_episode_steps: 300, threshold: -120}",
                     "{max_episode_steps: 300, options: {goal_speed: 0.1}}"),
        ["envs.mountaincar.options.goal_speed", "goal_velocity"],
    ),
    "negative seed": (GOOD.replace("seeds: [0, 1, 2]", "seeds: [0, -1]"),
                      ["seeds.1", "greater than or equal to 0"]),
    "seed past 2**32": (GOOD.replace("seeds: [0, 1, 2]", "seeds: [4294967296]"),
                        ["seeds.0", "less than 4294967296"]),
    "no seeds": (GOOD.replace("seeds: [0, 1, 2]", "seeds: []"),
                 ["suite.yaml:13", "seeds", "at least 1 item"]),
    "a method on no env": (GOOD.replace("envs: [mountaincar]", "envs: []"),
                           ["methods.sarsa-state.envs", "at least 1"]),
    "an empty sweep": (GOOD.replace("[0.8, 0.9]", "[]"),
                       ["variants.sarsa-state.hyperparams.trace_decay", "at least 1"]),
    "budget as a string": (GOOD.replace("budget: 2000", 'budget: "2000"'),
                           ["suite.yaml:14", "budget", "valid integer"]),
    "a boolean seed": (GOOD.replace("seeds: [0, 1, 2]", "seeds: [true, 1]"),
                       ["seeds.0", "valid integer"]),
    "not a number threshold": (GOOD.replace("threshold: -120", "threshold: .nan"),
                               ["envs.mountaincar.threshold", "finite"]),
    "hyperparameter out of range": (GOOD.replace("alpha: 0.8", "alpha: 0.8, tilings: 0"),
                                    ["suite.yaml:9", "hyperparams.tilings",
                                     "greater than or equal to 1 (got 0)"]),
    "a boolean for a count": (GOOD.replace("alpha: 0.8", "alpha: 0.8, tiles: true"),
                              ["hyperparams.tiles", "expected int"]),
    "a number as a string": (GOOD.replace("threshold: -120", 'threshold: "-120"'),
                             ["envs.mountaincar.threshold", "valid number"]),
    "a boolean for a number": (GOOD.replace("every: 1000, episodes: 2",
                                            "every: 1000, episodes: 2, epsilon: true"),
                               ["eval.epsilon", "valid number"]),
    "an infinite hyperparameter": (GOOD.replace("alpha: 0.8", "alpha: .inf"),
                                   ["hyperparams.alpha", "finite number, got inf"]),
    "a NaN env option": (GOOD.replace("{max_episode_steps: 300, threshold: -120}",
                                      "{max_episode_steps: 300, options: {goal_velocity: .nan}}"),
                         ["envs.mountaincar.options.goal_velocity", "a finite float"]),
    "a negative gradient clip": (GOOD.replace("    observation: state\n",
                                              "    observation: state\n"
                                              "    hyperparams: {max_grad_norm: -1.0}\n"),
                                 ["hyperparams.max_grad_norm", "greater than 0"]),
    "a negative entropy bonus": (GOOD.replace("    observation: state\n",
                                              "    observation: state\n"
                                              "    hyperparams: {ent_coef: -5.0}\n"),
                                 ["hyperparams.ent_coef", "greater than or equal to 0"]),
    "a reference on an env the method does not run on": (
        GOOD + "references:\n  sarsa-state:\n    pendulum: {value: -150, source: x}\n",
        ["references.sarsa-state.pendulum", "sarsa-state does not run on pendulum"]),
    "self-referencing alias": (GOOD.replace("name: grid", "name: grid\ndescription: &a [*a]"),
                               ["description", "valid string"]),
}


def test_a_hyperparameter_out_of_range_is_reported_at_its_own_line(write_suite):
    text = GOOD.replace("    hyperparams: {alpha: 0.8}\n",
                        "    hyperparams:\n      alpha: 0.8\n      gamma: 1.5\n")
    with pytest.raises(SuiteError) as info:
        load(write_suite, text)
    message = str(info.value)
    assert "1 problem\n" in message
    assert ("suite.yaml:11: methods.sarsa-state.hyperparams.gamma: Input should be less than "
            "or equal to 1 (got 1.5)") in message, message


def test_two_hyperparameters_out_of_range_in_one_method_are_both_reported(write_suite):
    text = GOOD.replace("    hyperparams: {alpha: 0.8}\n",
                        "    hyperparams:\n      alpha: -0.8\n      tiles: 0\n")
    with pytest.raises(SuiteError) as info:
        load(write_suite, text)
    message = str(info.value)
    assert "2 problems" in message, message
    assert ("suite.yaml:10: methods.sarsa-state.hyperparams.alpha: Input should be greater "
            "than 0 (got -0.8)") in message, message
    assert ("suite.yaml:11: methods.sarsa-state.hyperparams.tiles: Input should be greater "
            "than or equal to 1 (got 0)") in message, message


def test_a_check_across_hyperparameters_lands_on_the_key_it_names(write_suite):
    text = GOOD.replace("    observation: state\n",
                        "    observation: state\n    hyperparams:\n      n_steps: 16\n"
                        "      batch_size: 64\n")
    with pytest.raises(SuiteError) as info:
        load(write_suite, text)
    assert ("suite.yaml:15: methods.ppo-state.hyperparams.batch_size: batch_size must be at "
            "most a rollout, n_steps * n_envs = 16, got 64") in str(info.value)


def test_scientific_notation_reads_as_a_number(write_suite):
    suite = load(write_suite, GOOD.replace("alpha: 0.8", "alpha: 8e-1"))
    assert suite.cells[0].hyperparams["alpha"] == 0.8


def test_nested_aliases_validate_quickly(write_suite):
    import time

    laughs = "name: grid\ndescription: &l0 [x, x, x, x, x, x, x, x, x, x]\n"
    for level in range(1, 8):
        laughs += f"l{level}: &l{level} [" + ", ".join([f"*l{level - 1}"] * 10) + "]\n"
    start = time.perf_counter()
    with pytest.raises(SuiteError):
        load(write_suite, laughs)
    assert time.perf_counter() - start < 5


@pytest.mark.parametrize("case", list(BAD))
def test_a_bad_suite_is_refused_with_a_located_message(write_suite, case):
    text, expected = BAD[case]
    with pytest.raises(SuiteError) as info:
        load(write_suite, text)
    message = str(info.value)
    for fragment in expected:
        assert fragment in message, f"{fragment!r} not in:\n{message}"


@pytest.mark.slow
def test_cli_refuses_a_bad_suite_with_exit_2_no_traceback_and_writes_nothing(write_suite,
                                                                               tmp_path):
    path = write_suite(BAD["typo in a key"][0])
    results = tmp_path / "results"
    for command in (["validate", str(path)], ["run", str(path), "--results", str(results)]):
        done = subprocess.run([sys.executable, "-m", "senbench", *command],
                              capture_output=True, text=True, env={"COLUMNS": "200",
                                                                   **_env()})
        assert done.returncode == 2, done.stderr
        assert "Traceback" not in done.stderr + done.stdout
        assert "suite.yaml:7" in done.stderr and "agnet" in done.stderr
    assert not results.exists()


def _env():
    import os

    return dict(os.environ)


@pytest.mark.slow
def test_cli_validate_counts_the_cells(write_suite):
    done = subprocess.run([sys.executable, "-m", "senbench", "validate", str(write_suite(GOOD))],
                          capture_output=True, text=True, env={**_env(), "COLUMNS": "200"})
    assert done.returncode == 0, done.stderr
    assert "12 cells" in done.stdout
