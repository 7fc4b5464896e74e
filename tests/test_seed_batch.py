"""Seed-batched cells (senbench.run.batch): every encoder pass takes the batch's size, so a
seed's curve is bitwise the one it has beside any other seeds, or none; one seed that
raises fails alone; the option is refused where it cannot apply."""

import dataclasses
import shutil
import sys
import threading

import numpy as np
import pytest
from suites_for_tests import SEN_SARSA

import senbench
from senbench.errors import SuiteError
from senbench.plugin import manager as plugins
from senbench.plugin.manager import registries
from senbench.results.store import read_results
from senbench.run.batch import SharedEncoder
from senbench.run.runner import run_suite
from senbench.suite import load_suite
from senbench_encoders.sen_resnet import SEN_RESNET

SUITE = f"""\
name: batched
envs:
  mountaincar: {{max_episode_steps: 200}}
methods:
{SEN_SARSA}
seeds: [0, 1, 2]
seed_batch: 3
budget: 1200
eval: {{every: 400, episodes: 2}}
"""


class _Doubler:
    """A stand-in encoder that records the batches it is given."""

    low, high = np.zeros(1, np.float32), np.ones(1, np.float32)

    def __init__(self, fail_at: int | None = None):
        self.shapes, self.fail_at = [], fail_at

    def __call__(self, frames):
        self.shapes.append(frames.shape)
        if len(self.shapes) == self.fail_at:
            raise ValueError("pass failed on purpose")
        return frames.reshape(len(frames), -1)[:, :1].astype(np.float32) * 2

    def laid_out(self, memory_format):
        assert memory_format == "contiguous"
        return self


def _seeds(shared, calls):
    """Run one thread per slot, each handing in calls[slot] frames; their outputs."""
    outputs = {}

    def run(slot):
        with shared.seat(slot):
            outputs[slot] = [float(shared(np.full((1, 1, 1, 1), 10 * slot + k))[0, 0])
                             for k in range(calls[slot])]

    threads = [threading.Thread(target=run, args=(slot,)) for slot in range(len(calls))]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(timeout=10)
    assert not any(t.is_alive() for t in threads), "a seed is stuck at the barrier"
    return outputs


def test_each_pass_is_the_batch_size_and_a_seed_that_leaves_blocks_no_one():
    encoder = _Doubler()
    outputs = _seeds(SharedEncoder(encoder, 4, 3), [5, 2, 3])  # 3 seeds in a batch of 4
    assert outputs == {s: [2.0 * (10 * s + k) for k in range(n)]
                       for s, n in enumerate([5, 2, 3])}
    assert encoder.shapes == [(4, 1, 1, 1)] * 5  # padded; passes end as the last seed does


def test_a_pass_that_raises_fails_the_seeds_that_waited_on_it():
    shared = SharedEncoder(_Doubler(fail_at=2), 2, 2)
    errors = []

    def run(slot):
        with shared.seat(slot):
            try:
                for _ in range(3):
                    shared(np.zeros((1, 1, 1, 1)))
            except RuntimeError as exc:
                errors.append(str(exc))

    threads = [threading.Thread(target=run, args=(slot,)) for slot in range(2)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(timeout=10)
    assert len(errors) == 2 and "pass failed on purpose" in errors[0]
    with pytest.raises(RuntimeError, match="in its seat"):
        shared(np.zeros((1, 1, 1, 1)))  # outside a seed's thread


def _curves(root):
    frame = read_results(root / "batched")
    evals = frame[frame.kind == "eval"]
    return {seed: group["return"].tolist() for seed, group in evals.groupby("seed")}, frame


@pytest.mark.slow
def test_a_seeds_curve_is_the_same_beside_other_seeds_or_alone(write_suite, tmp_path):
    together = tmp_path / "together"
    summary = run_suite(load_suite(write_suite(SUITE), registries()), together)
    assert [o.status for o in summary.outcomes] == ["ok"] * 3
    curves, frame = _curves(together)
    assert set(frame.seed_batch) == {3}
    # seed 1 again, with no other seed beside it: the same passes, padded
    alone = tmp_path / "alone"
    shutil.copytree(together / "encoders", alone / "encoders")
    suite = load_suite(write_suite(SUITE.replace("[0, 1, 2]", "[1]"), "one.yaml"),
                       registries())
    run_suite(suite, alone)
    alone_curves, _ = _curves(alone)
    assert alone_curves[1] == curves[1]
    # and with seed_batch 1, another computation: another id
    single = load_suite(write_suite(SUITE.replace("seed_batch: 3", ""), "single.yaml"),
                        registries())
    assert single.cells[1].id != suite.cells[0].id


def test_the_encoder_outputs_of_a_batch_differ_from_one_frames_by_rounding_only(
        write_suite, tmp_path):
    """Between batch sizes the outputs differ by rounding (the docs: at most 1.2e-7 of the
    normalised output, measured on the paper's sen-resnet at 64x64; this test's small
    encoder is held to 1e-5 of its range): why the batch size is part of a cell's
    computation."""
    from senbench.encoders import load_or_train

    cell = load_suite(write_suite(SUITE), registries()).cells[0]
    encoder = load_or_train(tmp_path / "encoders", cell.encoder_request(), registries())
    frames = np.random.default_rng(0).integers(0, 256, (5, 2, 32, 32), dtype=np.uint8)
    one = np.concatenate([encoder(frames[i:i + 1]) for i in range(5)])
    batched = encoder(frames)
    scale = encoder.high - encoder.low
    assert np.abs(batched - one).max(axis=0).max() <= 1e-5 * scale.max()


def test_one_seed_that_raises_fails_alone_and_the_batch_finishes(write_suite, tmp_path,
                                                                 test_agents):
    suite = SUITE.replace("agent: sarsa", "agent: crash-seed").replace(
        "hyperparams: {tilings: 8, tiles: 6, trace_decay: 0.9}",
        "hyperparams: {seed: 1, after: 100}")
    summary = run_suite(load_suite(write_suite(suite), registries()), tmp_path, workers=2)
    status = {o.label.split()[-1]: (o.status, o.error) for o in summary.outcomes}
    assert status["0"] == ("ok", None) and status["2"] == ("ok", None)
    assert status["1"][0] == "failed" and "crashed on purpose at frame 100" in status["1"][1]


def test_seed_batch_is_refused_where_it_cannot_batch(write_suite):
    state = """\
name: s
envs:
  mountaincar: {}
methods:
  sarsa-state: {agent: sarsa}
seeds: [0, 1]
seed_batch: 2
budget: 100
eval: {every: 100, episodes: 1}
"""
    with pytest.raises(SuiteError) as error:
        load_suite(write_suite(state, "state.yaml"), registries())
    assert ("state.yaml:7: seed_batch: seed_batch batches an encoder's passes, and method "
            "'sarsa-state' observes state, not encoded: set seed_batch: 1 for method "
            "'sarsa-state'") in str(error.value)
    ppo = """\
name: b
envs:
  pendulum: {}
methods:
  sen-ppo:
    agent: ppo
    observation: encoded
    seed_batch: 2
    encoder: {samples: 300, fraction: 1.0}
seeds: [0, 1]
budget: 100
eval: {every: 100, episodes: 1}
"""
    with pytest.raises(SuiteError) as error:
        load_suite(write_suite(ppo), registries())
    text = str(error.value)
    assert "methods.sen-ppo.seed_batch" in text and "agent 'ppo' cannot run beside" in text
    assert "agents that can: sarsa" in text
    both = ppo.replace("seeds: [0, 1]", "seeds: [0, 1]\nseed_batch: 2")
    with pytest.raises(SuiteError) as error:  # removing the method's own would not do
        load_suite(write_suite(both), registries())
    assert "Set seed_batch: 1 for method 'sen-ppo'" in str(error.value)


def test_a_failure_of_the_callers_writer_reaches_the_caller(write_suite, tmp_path,
                                                           monkeypatch):
    """A seed's ``done`` that raises (its result cannot be written nor recorded) is raised
    again in the calling thread once the batch ends, not lost with the seed's thread."""
    import senbench.run.batch as batch
    from senbench.run.execute import RunInfo

    cells = load_suite(write_suite(SUITE), registries()).cells[:2]
    monkeypatch.setattr(batch, "load_or_train", lambda *a, **k: _Doubler())
    monkeypatch.setattr(batch, "execute_cell", lambda cell, *a, **k: ([], cell.seed))
    finished = []

    def done(cell, result):
        finished.append(cell.seed)
        if cell.seed == cells[0].seed:
            raise OSError("disk full on purpose")

    with pytest.raises(OSError, match="disk full on purpose"):
        batch.execute_cells(cells, RunInfo.gather(tmp_path / "encoders"), None, done)
    assert sorted(finished) == sorted(c.seed for c in cells)  # the other seed still ran


@senbench.hookimpl
def register_encoders(register):
    """sen-resnet under another name, declaring nothing about its batches."""
    register(dataclasses.replace(SEN_RESNET, name="undeclared",
                                 batch_independent=False))


def test_seed_batch_is_refused_for_an_encoder_that_may_mix_its_batch(write_suite):
    module = sys.modules[__name__]
    plugins.register_plugin(module, distribution="senbench-batch-tests", version="0")
    try:
        text = SUITE.replace("    encoder:\n", "    encoder:\n      arch: undeclared\n")
        assert "arch: undeclared" in text
        with pytest.raises(SuiteError) as error:
            load_suite(write_suite(text), plugins.registries())
        assert ("seed_batch encodes several seeds' frames in one pass, and encoder "
                "'undeclared' does not declare that a frame's output is independent of its "
                "batch (EncoderSpec.batch_independent); set seed_batch: 1 for method "
                "'sen-sarsa'") in str(error.value)
        assert "suite.yaml:10: methods.sen-sarsa.encoder.arch:" in str(error.value)
        load_suite(write_suite(text.replace("seed_batch: 3", "seed_batch: 1")),
                   plugins.registries())
    finally:
        plugins.unregister_plugin(module)
