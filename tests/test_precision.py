"""precision: bf16 network updates under autocast, acting in fp32; fp32 leaves every id as
it was; an agent without bf16 is refused at validation."""

import pytest
import torch
from stable_baselines3 import DQN

from senbench.errors import SuiteError
from senbench.plugin.manager import registries
from senbench.suite import load_suite
from senbench_agents.sb3 import with_precision

SUITE = """\
name: precision
envs:
  mountaincar: {}
methods:
  dqn-state: {agent: dqn}
  dqn-bf16: {agent: dqn, precision: bf16}
seeds: [0]
budget: 100
eval: {every: 100, episodes: 1}
"""


@pytest.fixture(autouse=True)
def any_cpu_runs_bf16(monkeypatch):
    """These tests check what bf16 does, on any CPU (emulated where it has no bf16
    instructions); the refusal of such a CPU is tested on its own below."""
    import senbench.suite.expand as expand

    monkeypatch.setattr(expand, "bf16_native", lambda: True)


def test_fp32_is_left_out_of_the_id_and_bf16_is_in_it(write_suite):
    cells = {c.method: c for c in load_suite(write_suite(SUITE), registries()).cells}
    fp32, bf16 = cells["dqn-state"], cells["dqn-bf16"]
    assert (fp32.precision, bf16.precision) == ("fp32", "bf16")
    assert "precision" not in fp32.curve() and "precision" not in fp32.config()
    assert bf16.curve()["precision"] == "bf16" and fp32.id != bf16.id
    assert fp32.replace(precision="bf16", method="dqn-bf16").id == bf16.id
    assert type(bf16).from_config(bf16.config(), "precision").precision == "bf16"


def test_an_agent_without_bf16_is_refused_where_precision_is_set(write_suite):
    path = write_suite(SUITE.replace("dqn-state: {agent: dqn}", "sarsa-state: {agent: sarsa}")
                       + "precision: bf16\n")
    with pytest.raises(SuiteError) as error:
        load_suite(path, registries())
    text = str(error.value)
    assert "precision: agent 'sarsa' computes in fp32, not bf16" in text
    assert "dqn" not in text  # dqn offers bf16


def test_bf16_on_a_cpu_without_bf16_instructions_is_refused_at_its_line(write_suite,
                                                                         monkeypatch):
    import senbench.suite.expand as expand

    monkeypatch.setattr(expand, "bf16_native", lambda: False)
    with pytest.raises(SuiteError) as error:
        load_suite(write_suite(SUITE), registries())
    text = str(error.value)
    assert "methods.dqn-bf16.precision" in text and "no bf16 instructions" in text
    assert "set precision: fp32" in text
    monkeypatch.setattr(expand, "bf16_native", lambda: True)
    assert len(load_suite(write_suite(SUITE), registries()).cells) == 2


def test_bf16_runs_the_updates_under_autocast_and_fp32_is_the_class_itself(monkeypatch):
    seen = []
    monkeypatch.setattr(DQN, "train", lambda self, *a, **k: seen.append(
        (torch.is_autocast_enabled("cpu"), torch.get_autocast_dtype("cpu"))))
    assert with_precision(DQN, "fp32") is DQN
    bf16 = with_precision(DQN, "bf16")
    bf16.train(object.__new__(bf16), 1, 32)
    assert seen == [(True, torch.bfloat16)]
    assert not torch.is_autocast_enabled("cpu")  # acting, outside train, stays fp32
    with pytest.raises(ValueError, match="fp32 or bf16"):
        with_precision(DQN, "fp16")


def test_a_bf16_cell_runs_and_records_its_precision(write_suite, tmp_path):
    from senbench.results.store import read_results
    from senbench.run.runner import run_suite

    suite = load_suite(write_suite(SUITE.replace(
        "dqn-bf16: {agent: dqn, precision: bf16}",
        "dqn-bf16: {agent: dqn, precision: bf16, hyperparams: {learning_starts: 20, "
        "train_freq: 4, batch_size: 16}}").replace("dqn-state: {agent: dqn}\n", "")),
        registries())
    summary = run_suite(suite, tmp_path)
    assert summary.ok == 1, [o.error for o in summary.failed]
    rows = read_results(tmp_path / "precision")
    assert '"precision": "bf16"' in rows["config"].iloc[0]
