"""Encoders as suites and the command line use them: one encoder trained per spec and
shared by its cells, encoder settings checked at validation (swept ones too), SEN-SARSA
learning from frames, and `senbench encoder train`."""

import json
import os

import numpy as np
import pytest

from senbench.encoders import (
    load_or_train,
)
from senbench.observe.pixels import PixelSpec
from senbench.plugin.manager import registries
from senbench.results.store import read_results
from senbench.run.runner import run_suite
from senbench.suite import load_suite

SMALL = PixelSpec(32, 32, 2)

@pytest.mark.slow
def test_a_cell_whose_cached_encoder_is_damaged_fails_saying_so(write_suite, tmp_path):
    text = SEN.replace("seeds: 2", "seeds: 1")
    text = text[:text.index("variants:")]
    suite = load_suite(write_suite(text), registries())
    encoders = tmp_path / "results" / "encoders"
    load_or_train(encoders, suite.cells[0].encoder_request(), registries())
    model = next(encoders.glob("*/model.pt"))
    model.write_bytes(model.read_bytes()[:1000])
    summary = run_suite(suite, tmp_path / "results")
    [failed] = summary.failed
    assert f"cached encoder {model} cannot be used: its SHA-256 is" in failed.error
    assert "Traceback" not in failed.error and "EncoderCacheError(" not in failed.error
    assert read_results(tmp_path / "results" / "sen", include_stale=True)["status"].eq(
        "failed").all()


SEN = """\
name: sen
envs:
  mountaincar: {}
methods:
  sen-sarsa:
    agent: sarsa
    observation: encoded
    encoder:
      arch: sen-resnet
      config: {widths: [8, 8, 16, 16], hidden: 32}
      samples: 300
      fraction: 1.0
      epochs: 2
      test_samples: 100
    pixels: {height: 32, width: 32}
seeds: 2
budget: 600
eval: {every: 300, episodes: 1}
variants:
  sen-sarsa:
    encoder.fraction: [0.5, 1.0]
"""


@pytest.mark.slow
def test_a_suite_trains_each_encoder_once_and_cells_share_it(write_suite, tmp_path):
    suite = load_suite(write_suite(SEN), registries())
    assert len(suite.cells) == 4
    summary = run_suite(suite, tmp_path / "results", workers=2)
    assert summary.ok == 4, [o.error for o in summary.failed]
    encoders = sorted(p.name for p in (tmp_path / "results" / "encoders").iterdir()
                      if p.is_dir())
    assert len(encoders) == 2  # one per fraction, shared by both seeds
    results = read_results(tmp_path / "results" / "sen")
    assert set(results["variant"]) == {"encoder.fraction=0.5", "encoder.fraction=1.0"}


def test_suite_checks_encoder_settings(write_suite):
    from senbench.errors import SuiteError

    bad = SEN.replace("hidden: 32}", "hiden: 32}")
    with pytest.raises(SuiteError, match="unknown sen-resnet setting 'hiden'. Did you mean"):
        load_suite(write_suite(bad), registries())
    bad = SEN.replace("arch: sen-resnet", "arch: resnet")
    with pytest.raises(SuiteError, match="Known encoders: nature-cnn, sen-keypoints, sen-resnet"):
        load_suite(write_suite(bad), registries())
    bad = SEN.replace("widths: [8, 8, 16, 16]", "widths: [8, 8, 16]")
    with pytest.raises(SuiteError, match="widths: List should have at least 4 items"):
        load_suite(write_suite(bad), registries())
    bad = SEN.replace("observation: encoded", "observation: state")
    with pytest.raises(SuiteError, match="an encoder is needed exactly when"):
        load_suite(write_suite(bad), registries())


LEARN = """\
name: sen-learn
envs:
  mountaincar: {}
methods:
  sen-sarsa:
    agent: sarsa
    observation: encoded
    encoder:
      config: {widths: [8, 16, 16, 16], hidden: 64}
      samples: 4000
      fraction: 1.0
      epochs: 8
      test_samples: 500
seeds: 1
budget: 15000
eval: {every: 5000, episodes: 5}
"""


@pytest.mark.slow
def test_sen_sarsa_learns_mountaincar_from_frames(write_suite, tmp_path):
    # SEN-DRL end to end: a small encoder (≈ 1.7% / 4% error) trained from frames, then
    # SARSA on its estimates. A random or untrained policy never reaches the flag in 200
    # steps (-200); measured here: rolling-10 training return -141, final greedy -168.
    suite = load_suite(write_suite(LEARN), registries())
    summary = run_suite(suite, tmp_path / "results", workers=2)
    assert summary.ok == 1, [o.error for o in summary.failed]
    results = read_results(tmp_path / "results" / "sen-learn")
    episodes = results[results["kind"] == "episode"]["return"].to_numpy()
    assert np.convolve(episodes, np.ones(10) / 10, "valid").max() >= -160
    evals = results[results["kind"] == "eval"].sort_values("step")["return"].to_numpy()
    assert evals[0] == -200 and evals[-1] > -190


def test_swept_encoder_values_are_checked_like_written_ones(write_suite):
    from senbench.errors import SuiteError

    bad = SEN.replace("encoder.fraction: [0.5, 1.0]", "encoder.fraction: [0.5, 5]")
    with pytest.raises(SuiteError, match="variants.sen-sarsa.encoder.fraction"):
        load_suite(write_suite(bad), registries())
    same = SEN.replace("encoder.fraction: [0.5, 1.0]", "encoder.fraction: [1]")
    swept = load_suite(write_suite(same), registries()).cells[0]
    written = load_suite(write_suite(SEN.replace("variants:\n  sen-sarsa:\n    encoder.fraction:"
                                                 " [0.5, 1.0]\n", "")), registries()).cells[0]
    assert swept.encoder_request().id == written.encoder_request().id


@pytest.mark.slow
def test_encoder_train_from_the_command_line_names_a_thread_count_other_than_2(tmp_path):
    import subprocess
    import sys

    def train_cli(*extra):
        return subprocess.run(
            [sys.executable, "-m", "senbench", "encoder", "train", "--env", "mountaincar",
             "--samples", "300", "--fraction", "1.0", "--epochs", "1", "--test-samples", "100",
             "--height", "32", "--width", "32", "--cache", str(tmp_path), *extra],
            capture_output=True, text=True, env={**os.environ, "COLUMNS": "200"})

    default, one = train_cli(), train_cli("--threads", "1")
    assert default.returncode == 0 and one.returncode == 0, default.stderr + one.stderr
    assert "velocity" in default.stdout and "1 epochs, trained in" in default.stdout
    folders = sorted(p.name for p in tmp_path.iterdir() if p.is_dir())
    assert len(folders) == 2  # two thread counts: two encoders
    specs = {json.loads((tmp_path / f / "spec.json").read_text())["training"]["threads"]
             for f in folders}
    assert specs == {1, 2}
    assert all(f"encoder {f} →" in default.stdout + one.stdout for f in folders)
    refused = train_cli("--threads", "0")
    assert refused.returncode == 2 and "--threads" in refused.stderr


def test_encoder_train_takes_the_configs_a_suite_sets_and_checks_them_the_same_way(tmp_path):
    from typer.testing import CliRunner

    from senbench.cli.app import app

    def train(*extra):
        return CliRunner().invoke(app, [
            "encoder", "train", "--env", "mountaincar", "--samples", "40", "--fraction", "1.0",
            "--epochs", "1", "--test-samples", "20", "--height", "32", "--width", "32",
            "--cache", str(tmp_path), *extra])

    refused = train("--arch-config", "widths=[8, 16]", "--arch-config", "hiden=8",
                    "--sampler-config", "repeat=2", "--arch-config", "first_stride")
    assert refused.exit_code == 2
    for part in ("--arch-config widths: List should have at least 4 items",
                 "unknown sen-resnet setting 'hiden'. Did you mean 'hidden'?",
                 "--sampler-config repeat: unknown uniform setting 'repeat': uniform has none",
                 "--arch-config 'first_stride': write KEY=VALUE"):
        assert part in refused.output.replace("\n", " "), refused.output
    assert not any(tmp_path.iterdir())  # nothing trained, nothing written
    small = train("--arch", "nature-cnn")  # 32x32 frames: a suite's validation refuses it
    assert small.exit_code == 2 and ("nature-cnn' needs frames of at least 36x36, got 32x32; "
                                     "pass --height 36 --width 36") in small.output
    assert train("--learning-rate", "0").exit_code == 2
    assert not any(tmp_path.iterdir())

    trained = train("--arch-config", "widths=[4, 4, 8, 8]", "--arch-config", "hidden=8",
                    "--sampler", "rollout", "--sampler-config", "repeat=2")
    assert trained.exit_code == 0, trained.output
    [folder] = [p for p in tmp_path.iterdir() if p.is_dir()]
    spec = json.loads((folder / "spec.json").read_text())
    assert spec["arch_config"]["widths"] == [4, 4, 8, 8] and spec["arch_config"]["hidden"] == 8
    assert spec["sampler_config"]["repeat"] == 2
