"""memory_format: channels_last lays out the agents' and the state encoder's convolutions
NHWC; contiguous (NCHW) leaves every id as it was; an agent without the choice is refused
at validation."""

import numpy as np
import pytest
import torch
from suites_for_tests import SEN_SARSA

from senbench.encoders import EncoderRequest, StateEncoder, build_model, observation_bounds
from senbench.errors import SuiteError
from senbench.observe.pixels import PixelSpec
from senbench.plugin.manager import registries
from senbench.plugin.specs import AgentContext
from senbench.suite import load_suite

SUITE = """\
name: layout
envs:
  mountaincar: {}
methods:
  dqn-pixels: {agent: dqn, observation: pixels}
  dqn-nhwc: {agent: dqn, observation: pixels, memory_format: channels_last}
seeds: [0]
budget: 100
eval: {every: 100, episodes: 1}
"""


def test_contiguous_is_left_out_of_the_id_and_channels_last_is_in_it(write_suite):
    cells = {c.method: c for c in load_suite(write_suite(SUITE), registries()).cells}
    nchw, nhwc = cells["dqn-pixels"], cells["dqn-nhwc"]
    assert (nchw.memory_format, nhwc.memory_format) == ("contiguous", "channels_last")
    assert "memory_format" not in nchw.curve() and "memory_format" not in nchw.config()
    assert nhwc.curve()["memory_format"] == "channels_last" and nchw.id != nhwc.id
    assert nchw.replace(memory_format="channels_last", method="dqn-nhwc").id == nhwc.id
    assert type(nhwc).from_config(nhwc.config(), "").memory_format == "channels_last"
    assert nhwc.batch_key != nchw.batch_key  # never in one seed batch


def test_a_suite_wide_layout_applies_to_every_method_on_frames(write_suite):
    text = (SUITE.replace("{agent: dqn, observation: pixels, memory_format: channels_last}",
                          "{agent: sarsa}") + "memory_format: channels_last\n")
    cells = {c.method: c for c in load_suite(write_suite(text), registries()).cells}
    assert cells["dqn-pixels"].memory_format == "channels_last"
    # a state cell has no convolutions: it stays as it was, its id too
    assert cells["dqn-nhwc"].memory_format == "contiguous"
    plain = load_suite(write_suite(text.replace("memory_format: channels_last\n", "")),
                       registries()).cells
    assert {c.method: c.id for c in plain}["dqn-nhwc"] == cells["dqn-nhwc"].id


def test_an_unknown_layout_is_refused_at_its_line(write_suite):
    with pytest.raises(SuiteError) as error:
        load_suite(write_suite(SUITE.replace("memory_format: channels_last",
                                             "memory_format: nhwc")), registries())
    text = str(error.value)
    assert "methods.dqn-nhwc.memory_format" in text
    assert "'contiguous' or 'channels_last'" in text


def test_an_agent_without_the_choice_is_refused_naming_it(write_suite, monkeypatch):
    import dataclasses

    regs = registries()
    dqn = regs.agents.get("dqn")
    plain = dataclasses.replace(dqn, memory_formats=frozenset({"contiguous"}))
    monkeypatch.setattr(regs.agents, "get", lambda name: plain)
    text = ("name: layout\nenvs: {mountaincar: {}}\nmethods:\n"
            "  plain: {agent: dqn, observation: pixels}\n"
            "seeds: [0]\nbudget: 100\neval: {every: 100, episodes: 1}\n"
            "memory_format: channels_last\n")
    with pytest.raises(SuiteError) as error:
        load_suite(write_suite(text), regs)
    said = str(error.value)
    assert ("memory_format: agent 'dqn' offers memory_format contiguous, not "
            "channels_last (its spec's memory_formats)") in said
    assert "set memory_format: contiguous for method 'plain'" in said
    # on the state it is not asked for: there are no convolutions to lay out
    state = text.replace("observation: pixels", "observation: state")
    assert len(load_suite(write_suite(state), regs).cells) == 1


def test_an_encoder_without_the_choice_is_refused_naming_it(write_suite, monkeypatch):
    import dataclasses

    regs = registries()
    resnet = regs.encoders.get("sen-resnet")
    view_only = dataclasses.replace(resnet, memory_formats=frozenset({"contiguous"}))
    monkeypatch.setattr(regs.encoders, "get", lambda name: view_only)
    text = ("name: layout\nenvs: {mountaincar: {}}\nmethods:\n"
            "  sen: {agent: sarsa, observation: encoded, memory_format: channels_last,\n"
            "        encoder: {}}\n"
            "seeds: [0]\nbudget: 100\neval: {every: 100, episodes: 1}\n")
    with pytest.raises(SuiteError) as error:
        load_suite(write_suite(text), regs)
    assert ("methods.sen.memory_format: encoder 'sen-resnet' offers memory_format "
            "contiguous, not channels_last") in str(error.value)


def _dqn(memory_format: str):
    regs = registries()
    spec, agent = regs.envs.get("mountaincar"), regs.agents.get("dqn")
    from senbench.observe.observations import make_env

    def make():
        return make_env(spec, "pixels", 200, {}, PixelSpec(36, 36, 2))

    cfg = agent.config(learning_starts=10, train_freq=2, batch_size=8, buffer_size=200,
                       target_update_interval=20)
    return agent.make(AgentContext(cfg, spec, make, 0, 1, "fp32", memory_format))


class _Count:
    def __init__(self, budget):
        self.budget = budget

    def step(self, steps):
        return steps < self.budget

    def episode(self, *args):
        pass


def _convolutions(learner):
    return [m.weight for m in learner.model.policy.modules()
            if isinstance(m, torch.nn.Conv2d)]


def test_channels_last_learns_as_contiguous_does_within_float_rounding():
    torch.set_num_threads(1)
    runs = {}
    for layout in ("contiguous", "channels_last", "channels_last"):
        learner = _dqn(layout)
        weights = _convolutions(learner)
        assert len(weights) == 6  # NatureCNN under the online and the target network
        nhwc = layout == "channels_last"
        assert all(w.is_contiguous(memory_format=torch.channels_last) == nhwc
                   for w in weights)
        learner.learn(60, _Count(60))  # 25 updates, 2 target copies
        assert all(w.is_contiguous(memory_format=torch.channels_last) == nhwc
                   for w in _convolutions(learner))  # the optimiser kept the layout
        runs.setdefault(layout, []).append(
            [p.detach().clone() for p in learner.model.policy.parameters()])
    first, again = runs["channels_last"]
    assert all(torch.equal(a, b) for a, b in zip(first, again, strict=True))  # same seed
    moved = [(a - b).abs().max().item()
             for a, b in zip(runs["contiguous"][0], first, strict=True)]
    assert max(moved) < 1e-4  # at most another order of float sums: the same learning


def test_a_laid_out_encoder_reads_frames_as_the_contiguous_one_does():
    torch.set_num_threads(1)
    regs = registries()
    request = EncoderRequest("mountaincar", PixelSpec(), "sen-resnet", "uniform", 10, 1.0)
    low, high = observation_bounds(regs.envs.get("mountaincar"))
    torch.manual_seed(0)
    encoder = StateEncoder(build_model(request, regs, 2), np.zeros(2), np.ones(2) * 0.1,
                           low, high, traceable=True)
    assert encoder.laid_out("contiguous") is encoder
    nhwc = encoder.laid_out("channels_last")
    frames = np.random.default_rng(0).integers(0, 256, (3, 2, 64, 64), dtype=np.uint8)
    for batch in (frames[:1], frames):
        assert np.allclose(nhwc(batch), encoder(batch), rtol=0, atol=1e-5)
    conv = next(m for m in encoder.model.modules() if isinstance(m, torch.nn.Conv2d))
    assert conv.weight.is_contiguous()  # a copy was laid out, not the shared encoder
    with pytest.raises(ValueError, match="contiguous or channels_last"):
        encoder.laid_out("nhwc")


@pytest.mark.slow
def test_an_encoded_cell_runs_channels_last_and_records_it(write_suite, tmp_path):
    from senbench.results.store import read_results
    from senbench.run.runner import run_suite

    text = ("name: sen\nenvs: {mountaincar: {}}\nmethods:\n" + SEN_SARSA + "seeds: 1\n"
            "budget: 300\neval: {every: 300, episodes: 1}\nmemory_format: channels_last\n")
    summary = run_suite(load_suite(write_suite(text), registries()), tmp_path)
    assert summary.ok == 1, [o.error for o in summary.failed]
    rows = read_results(tmp_path / "sen")
    assert '"memory_format": "channels_last"' in rows["config"].iloc[0]
