"""State encoders: architectures, training, the cache and its checks, samplers, and the
encoded observation."""

import dataclasses
import hashlib

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
