import dataclasses
import hashlib
import json
import os

import numpy as np
import pytest
import torch

from senbench.encoders import (
    EncoderRequest,
    StateEncoder,
    Training,
    build_model,
    cache_dir,
    complete,
    load,
    load_or_train,
    train,
)
from senbench.encoders.training import draw
from senbench.errors import EncoderCacheError
from senbench.observe.observations import make_env
from senbench.observe.pixels import PixelSpec
from senbench.plugin.manager import registries
from senbench.results.store import read_results
from senbench.run.runner import run_suite
from senbench.suite import load_suite

SMALL = PixelSpec(32, 32, 2)


TINY = {"widths": [8, 8, 16, 16], "hidden": 32}


def request(env="mountaincar", arch="sen-resnet", **kwargs):
    values = dict(env=env, pixels=SMALL, arch=arch, sampler="uniform", samples=300,
                  fraction=1.0, training=Training(epochs=2, test_samples=100),
                  arch_config=TINY if arch == "sen-resnet" else {})
    return EncoderRequest(**{**values, **kwargs})


@pytest.mark.parametrize("arch", ["sen-resnet", "nature-cnn", "sen-keypoints"])
@pytest.mark.parametrize("env,outputs", [("mountaincar", 2), ("pendulum", 3)])
def test_architectures_map_frame_stacks_to_the_observation(arch, env, outputs):
    for pixels in (PixelSpec(64, 64, 2), PixelSpec(48, 80, 3)):
        model = build_model(request(env, arch, pixels=pixels, arch_config={}), registries(),
                            outputs)
        out = model(torch.rand(5, pixels.stack, pixels.height, pixels.width))
        assert out.shape == (5, outputs)


@pytest.mark.slow
def test_a_small_encoder_fits_a_small_dataset(tmp_path):
    torch.set_num_threads(1)
    fit = request(samples=400, training=Training(epochs=25, patience=25, test_samples=200,
                                                 validation=0.1))
    result = train(fit, registries(), tmp_path / "enc")
    losses = [e["train_loss"] for e in result["epochs"]]
    assert losses[-1] < losses[0] / 10
    position = next(e for e in result["errors"] if e["dimension"] == "position")
    assert position["rmse_pct_of_range"] < 15  # far better than guessing the mean (≈ 29%)


@pytest.mark.slow
def test_a_second_request_with_the_same_spec_loads_the_cache(tmp_path):
    torch.set_num_threads(1)
    said = []
    first = load_or_train(tmp_path, request(), registries(), said.append)
    model = cache_dir(tmp_path, complete(request(), registries())) / "model.pt"
    stamp = model.stat().st_mtime_ns
    second = load_or_train(tmp_path, request(), registries(), said.append)
    assert model.stat().st_mtime_ns == stamp
    assert "training" in said[0] and said[-1].endswith("cached, loaded")
    frames = np.random.default_rng(0).integers(0, 255, (3, 2, 32, 32), dtype=np.uint8)
    assert np.array_equal(first(frames), second(frames))
    assert request().id != request(fraction=0.5).id != request(seed=1).id


@pytest.mark.slow
def test_the_same_spec_trained_twice_gives_the_same_encoder(tmp_path):
    # A cache lost with a machine is trained again: the cells that resume must see the
    # encoder the finished cells saw.
    # On another machine the caller's thread count differs: training runs on the spec's.
    spec = request(fraction=0.5)
    for where, threads in (("one", 1), ("two", 3)):
        torch.set_num_threads(threads)
        load_or_train(tmp_path / where, spec, registries())
        assert torch.get_num_threads() == threads  # given back as it was
    torch.set_num_threads(1)
    weights = [torch.load(cache_dir(tmp_path / where, complete(spec, registries())) / "model.pt",
                          weights_only=True) for where in ("one", "two")]
    state, other = weights[0]["model"], weights[1]["model"]
    assert state.keys() == other.keys()
    assert all(torch.equal(state[k], other[k]) for k in state)
    assert torch.equal(weights[0]["mean"], weights[1]["mean"])


def test_encoder_ids_name_the_training_threads_only_when_not_the_default():
    # The paper suites' d = 2% MountainCar encoder, as committed under results/encoders/:
    # its id predates Training.threads and must not change (its cells name it).
    paper = EncoderRequest(
        env="mountaincar", pixels=PixelSpec(64, 64, 2), arch="sen-resnet", sampler="uniform",
        samples=50000, fraction=0.02, seed=0, sampler_config={},
        arch_config={"widths": [16, 32, 64, 64], "hidden": 256, "batch_norm": True,
                     "first_stride": 2})
    assert paper.training.threads == 2 and paper.id == "f4d4c1b831c917c9"
    other = EncoderRequest(**{**paper.__dict__, "training": Training(threads=1)})
    assert other.id != paper.id  # other weights: another encoder
    assert other.as_dict()["training"]["threads"] == 1


def test_env_options_name_the_encoder_and_reach_its_sampler():
    # A suite's env options (pendulum's g) change the env the cells step, so they name
    # another encoder, whose sampler steps the env made with them; no options leave the
    # ids of the committed encoders as they were.
    plain = request("pendulum", sampler="rollout")
    light = request("pendulum", sampler="rollout", env_options={"g": 2.0})
    assert plain.id != light.id
    assert request(env_options={}).id == request().id
    _, states = draw(plain, registries(), 30, seed=0)
    _, moved = draw(light, registries(), 30, seed=0)
    assert np.array_equal(states[0], moved[0])  # the same reset...
    assert not np.allclose(states[5:], moved[5:])  # ...then another gravity


@pytest.mark.parametrize("broken, said", [
    (lambda f, o: (f.astype(np.float64), o), "frames of shape (30, 2, 32, 32) and dtype "
     "float64, not (30, 2, 32, 32) uint8"),
    (lambda f, o: (f[:-1], o[:-1]), "frames of shape (29, 2, 32, 32)"),
    (lambda f, o: (f, o[:, :1]), "observations of shape (30, 1) and dtype float32, not "
     "(30, 2) numbers (env 'mountaincar' has 2 observation values)"),
    (lambda f, o: (f, o * np.nan), "observations that are NaN or infinite"),
])
def test_a_sampler_that_breaks_its_contract_is_refused_naming_it(broken, said, monkeypatch):
    from senbench.errors import PluginError

    regs = registries()
    uniform = regs.samplers.get("uniform")
    faulty = dataclasses.replace(uniform, sample=lambda *a: broken(*uniform.sample(*a)))
    monkeypatch.setattr(regs.samplers, "get", lambda name: faulty)
    with pytest.raises(PluginError) as error:
        draw(request(), regs, 30, seed=0)
    assert said in str(error.value) and "sampler 'uniform' returned" in str(error.value)


@pytest.mark.slow
def test_checkpoints_load_with_weights_only_and_refuse_code(tmp_path):
    torch.set_num_threads(1)
    load_or_train(tmp_path, request(), registries())
    model = cache_dir(tmp_path, complete(request(), registries())) / "model.pt"
    saved = torch.load(model, weights_only=True)
    assert set(saved) == {"model", "mean", "std"}

    class Payload:
        def __reduce__(self):
            return (print, ("this would run code",))

    torch.save({"model": Payload(), "mean": saved["mean"], "std": saved["std"]}, model)
    with pytest.raises(EncoderCacheError, match="its SHA-256 is"):  # changed since written
        load(tmp_path, request(), registries())
    (model.parent / "model.sha256").unlink()  # as an encoder trained before checksums
    with pytest.raises(EncoderCacheError, match=r"does not load, .* \(UnpicklingError: Weights"):
        load(tmp_path, request(), registries())


@pytest.mark.slow
def test_a_damaged_cached_encoder_is_refused_naming_the_folder_to_delete(tmp_path):
    torch.set_num_threads(1)
    load_or_train(tmp_path, request(), registries())
    folder = cache_dir(tmp_path, complete(request(), registries()))
    model = folder / "model.pt"
    whole = model.read_bytes()
    assert (folder / "model.sha256").read_text() == (
        f"{hashlib.sha256(whole).hexdigest()}  model.pt\n")  # sha256sum -c reads it
    model.write_bytes(whole[:len(whole) // 2])
    with pytest.raises(EncoderCacheError) as info:
        load_or_train(tmp_path, request(), registries())
    message = str(info.value)
    assert message.startswith(f"cached encoder {model} cannot be used: its SHA-256 is ")
    assert "truncated or changed since" in message
    assert f"delete the folder {folder} to train it anew" in message
    assert model.read_bytes() == whole[:len(whole) // 2]  # not retrained behind one's back
    (folder / "model.sha256").unlink()  # as the encoders committed before checksums
    with pytest.raises(EncoderCacheError, match=r"cannot be used: it does not load, so it is "
                       r"truncated or damaged \(.*\)\. .*delete the folder"):
        load_or_train(tmp_path, request(), registries())
    assert not (folder / "model.sha256").exists()  # nothing rewritten


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


@pytest.mark.parametrize("sampler", ["uniform", "rollout"])
@pytest.mark.parametrize("env", ["mountaincar", "pendulum"])
def test_sampled_frames_are_the_renderers_frames_of_the_labelled_state(sampler, env):
    spec = registries().envs.get(env)
    frames, labels = registries().samplers.get(sampler).sample(spec, 50, SMALL, 3)
    assert frames.shape == (50, 2, 32, 32) and frames.dtype == np.uint8
    if env == "mountaincar":
        states = np.stack([labels[:, 0], labels[:, 1]], 1)
    else:  # the label is (cos, sin, velocity); the frame shows the angle
        states = np.stack([np.arctan2(labels[:, 1], labels[:, 0]), labels[:, 2]], 1)
    drawn = spec.render(states.astype(np.float64), SMALL.size)
    assert np.abs(drawn.astype(int) - frames[:, -1].astype(int)).max() <= 1
    if sampler == "uniform":  # the stack follows the dynamics: the older frame differs
        assert (frames[:, 0] != frames[:, 1]).any(axis=(1, 2)).mean() > 0.9


@pytest.mark.slow
def test_the_encoded_observation_is_the_encoders_estimate_not_the_state(tmp_path):
    torch.set_num_threads(1)
    encoder = load_or_train(tmp_path, request(), registries())
    spec = registries().envs.get("mountaincar")
    env = make_env(spec, "encoded", 200, {}, SMALL, encoder)
    pixels = make_env(spec, "pixels", 200, {}, SMALL)
    obs, info = env.reset(seed=4)
    frames, _ = pixels.reset(seed=4)
    assert env.observation_space.shape == (2,) and env.observation_space.contains(obs)
    assert np.array_equal(obs, encoder(frames[None])[0])
    for _ in range(20):
        obs, _, _, _, info = env.step(2)
        frames, *_ = pixels.step(2)
        assert np.array_equal(obs, encoder(frames[None])[0])
        assert not np.array_equal(obs, info["state"].astype(np.float32))


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


def test_too_few_samples_to_train_on_is_a_clear_error(tmp_path):
    with pytest.raises(ValueError, match="raise samples or fraction"):
        train(request(samples=100, fraction=0.02), registries(), tmp_path / "enc")


def test_uniform_frames_cannot_stand_in_for_gymnasiums(tmp_path):
    spec = registries().envs.get("mountaincar")
    with pytest.raises(ValueError, match="use the rollout sampler"):
        registries().samplers.get("uniform").sample(spec, 10, PixelSpec(renderer="gymnasium"), 0)


class Branchy(torch.nn.Module):
    """Output depends on the input through Python control flow, which a trace would fix."""

    def forward(self, x):
        if float(x.mean()) > 0.5:
            return x.mean(dim=(2, 3))
        return -x.mean(dim=(2, 3))


def test_the_encoder_runs_frozen_only_for_architectures_that_declare_it():
    torch.set_num_threads(1)
    rng = np.random.default_rng(0)
    frames = rng.integers(0, 256, (1, 2, 32, 32), dtype=np.uint8)
    low, high = np.full(2, -2.0), np.full(2, 2.0)
    # Not declared traceable: every input takes its own branch, as in eager PyTorch.
    branchy = StateEncoder(Branchy(), np.zeros(2), np.ones(2), low, high)
    signs = set()
    for batch in (frames // 4, 255 - frames // 4):
        expected = Branchy()(torch.as_tensor(batch, dtype=torch.float32) / 255).numpy()
        assert np.allclose(branchy(batch), expected)
        signs.add(bool(expected[0, 0] > 0))
    assert signs == {True, False} and not branchy._frozen

    assert registries().encoders.get("sen-resnet").traceable
    model = build_model(request(), registries(), 2)
    encoder = StateEncoder(model, np.zeros(2), np.ones(2), low, high, traceable=True)
    estimate = encoder(frames)
    assert isinstance(encoder._frozen[(1, 2, 32, 32)], torch.jit.ScriptModule)
    with torch.no_grad():
        eager = model(torch.as_tensor(frames, dtype=torch.float32) / 255).numpy()
    assert np.allclose(estimate, np.clip(eager, low, high), atol=1e-5)


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


def test_the_keypoint_encoder_reads_where_a_bright_spot_is():
    """Its spatial softmax returns each map's expected (x, y) in [-1, 1]: with maps that
    peak at one place, the keypoints sit there, whatever the image's size."""
    model = build_model(request("mountaincar", "sen-keypoints", arch_config={}), registries(),
                        2)
    softmax = model[1]
    maps = torch.full((1, 3, 8, 8), -1e4)
    maps[0, 0, 0, 7] = maps[0, 1, 7, 0] = maps[0, 2, 3, 4] = 1e4  # (row, column)
    xs_ys = softmax(maps)[0]
    assert torch.allclose(xs_ys[:3], torch.tensor([1.0, -1.0, 4 / 7 * 2 - 1]), atol=1e-5)
    assert torch.allclose(xs_ys[3:], torch.tensor([-1.0, 1.0, 3 / 7 * 2 - 1]), atol=1e-5)
