"""Capabilities are checked at validation: what an agent, an encoder architecture or a
sampler needs against what an env offers and what the frames are. Each mismatch that used to
fail a run is a validation error with its file, line, key path and fix, and every problem of
a suite is reported in one run."""

from __future__ import annotations

import dataclasses
import sys

import gymnasium
import numpy as np
import pytest

import senbench
from senbench import AgentSpec, EnvSpec, SamplerSpec
from senbench.errors import SuiteError
from senbench.plugin import manager as plugins
from senbench.suite import load_suite


def make_cartpole(max_episode_steps: int = 500, render_mode: str | None = None):
    return gymnasium.make("CartPole-v1", max_episode_steps=max_episode_steps,
                          render_mode=render_mode)


# gymnasium's CartPole: a raw Box with infinite bounds on both velocities, and none of
# observe, set_state, render.
CARTPOLE = EnvSpec(
    name="cartpole", make=make_cartpole,
    physical_state=lambda env: np.asarray(env.state, dtype=np.float64),
    state_labels=("x", "x_dot", "theta", "theta_dot"),
    state_low=(-2.4, -3.0, -0.21, -3.5), state_high=(2.4, 3.0, 0.21, 3.5),
    actions="discrete", threshold=475.0, threshold_source="gymnasium CartPole-v1",
    max_episode_steps=500)
# The same with observe (so an encoded observation has labels), still no set_state/render.
CARTPOLE_OBSERVED = dataclasses.replace(
    CARTPOLE, name="cartpole-observed", observe=lambda states: np.asarray(states, np.float32),
    observation_labels=("cart position", "cart velocity", "pole angle", "pole velocity"))


@senbench.hookimpl
def register_envs(register):
    register(CARTPOLE)
    register(CARTPOLE_OBSERVED)


@pytest.fixture
def regs():
    """The built-in plugins and this module's envs, for one test."""
    module = sys.modules[__name__]
    plugins.register_plugin(module, distribution="senbench-capability-tests", version="0")
    yield plugins.registries()
    plugins.unregister_plugin(module)


TAIL = """\
seeds: 1
budget: 1000
eval: {every: 500, episodes: 1}
"""


def problems(write_suite, regs, text: str) -> str:
    with pytest.raises(SuiteError) as info:
        load_suite(write_suite(text + TAIL), regs)
    return str(info.value)


def test_encoded_on_an_env_without_observe(write_suite, regs):
    message = problems(write_suite, regs, """\
name: caps
envs:
  cartpole: {}
methods:
  sen-ppo:
    agent: ppo
    observation: encoded
    encoder:
      sampler: rollout
""")
    assert "1 problem\n" in message, message
    assert ("suite.yaml:7: methods.sen-ppo.observation: env 'cartpole' has no observe(): an "
            "encoded observation needs one") in message, message
    assert "use observation: pixels or state" in message
    assert "add observe to the env plugin" in message


def test_uniform_sampler_on_an_env_without_set_state_and_render(write_suite, regs):
    text = """\
name: caps
envs:
  cartpole-observed: {}
methods:
  sen-ppo:
    agent: ppo
    observation: encoded
    encoder:
      arch: sen-resnet
      sampler: uniform
"""
    message = problems(write_suite, regs, text)
    assert "1 problem\n" in message, message
    assert ("suite.yaml:10: methods.sen-ppo.encoder.sampler: env 'cartpole-observed' has no "
            "render() and no set_state(): the uniform sampler needs them; use sampler: "
            "rollout, or add render and set_state to the env plugin") in message, message
    # the rollout sampler needs neither
    suite = load_suite(write_suite(text.replace("uniform", "rollout") + TAIL), regs)
    assert len(suite.cells) == 1


def test_uniform_sampler_with_gymnasiums_frames(write_suite, regs):
    message = problems(write_suite, regs, """\
name: caps
envs:
  mountaincar: {}
methods:
  sen-sarsa:
    agent: sarsa
    observation: encoded
    encoder: {sampler: uniform}
    pixels:
      renderer: gymnasium
""")
    assert ("suite.yaml:10: methods.sen-sarsa.pixels.renderer: the uniform sampler draws "
            "frames with the env plugin's render(), but these observations come from "
            "gymnasium's render() (renderer: gymnasium); use renderer: auto, or sampler: "
            "rollout") in message, message


@pytest.mark.parametrize("agent", ["ppo", "dqn", "ddqn"])
def test_a_pixel_agent_on_frames_smaller_than_its_cnn_takes(write_suite, regs, agent):
    text = f"""\
name: caps
envs:
  mountaincar: {{}}
methods:
  pix:
    agent: {agent}
    observation: pixels
pixels: {{height: 32, width: 48}}
"""
    message = problems(write_suite, regs, text)
    assert "1 problem\n" in message, message
    assert (f"suite.yaml:8: pixels: agent '{agent}' needs frames of at least 36x36, got "
            "32x48; set pixels: {height: 36, width: 48} or more") in message, message
    # a method's own pixels are where the problem is, when it has them
    own = text.replace("    observation: pixels\n",
                       "    observation: pixels\n    pixels: {height: 35, width: 35}\n")
    assert ("suite.yaml:8: methods.pix.pixels: agent" in problems(write_suite, regs, own))
    fits = load_suite(write_suite(text.replace("height: 32", "height: 36") + TAIL), regs)
    assert len(fits.cells) == 1


ENCODER = """\
name: caps
envs:
  mountaincar: {}
methods:
  sen:
    agent: sarsa
    observation: encoded
    encoder:
      arch: ARCH
      config: CONFIG
    pixels: {height: SIZE, width: SIZE}
"""


@pytest.mark.parametrize(("arch", "config", "smallest", "qualifier"), [
    ("nature-cnn", "{}", 36, ""),
    ("sen-keypoints", "{}", 16, ""),
    ("sen-resnet", "{}", 17, " with this config"),
    ("sen-resnet", "{first_stride: 1}", 9, " with this config"),
])
def test_an_encoder_on_frames_smaller_than_it_takes(write_suite, regs, arch, config, smallest,
                                                    qualifier):
    text = ENCODER.replace("ARCH", arch).replace("CONFIG", config)
    message = problems(write_suite, regs, text.replace("SIZE", str(smallest - 1)))
    small = f"{smallest - 1}x{smallest - 1}"
    assert (f"suite.yaml:11: methods.sen.pixels: encoder '{arch}'{qualifier} needs frames of "
            f"at least {smallest}x{smallest}, got {small}; set pixels: {{height: {smallest}, "
            f"width: {smallest}}} or more, or use another arch") in message, message
    assert load_suite(write_suite(text.replace("SIZE", str(smallest)) + TAIL), regs).cells


@pytest.mark.parametrize(("arch", "config", "smallest"), [
    ("nature-cnn", {}, 36), ("sen-keypoints", {}, 16), ("sen-resnet", {}, 17),
    ("sen-resnet", {"first_stride": 1}, 9)])
def test_an_encoders_declared_minimum_is_what_it_builds_from(regs, arch, config, smallest):
    spec = regs.encoders.get(arch)
    assert spec.min_frame_size_for(spec.config(**config)) == smallest
    spec.build((2, smallest, smallest + 20), 2, spec.config(**config))
    with pytest.raises(ValueError, match="at least"):
        spec.build((2, smallest + 20, smallest - 1), 2, spec.config(**config))


@pytest.mark.slow
@pytest.mark.parametrize("agent", ["ppo", "dqn"])
def test_sb3s_nature_cnn_takes_36_and_not_35(agent):
    from stable_baselines3 import DQN, PPO

    def make(size: int):
        class Frames(gymnasium.Env):
            observation_space = gymnasium.spaces.Box(0, 255, (2, size, size), np.uint8)
            action_space = gymnasium.spaces.Discrete(2)

        algorithm, kwargs = ((PPO, {"n_steps": 8, "batch_size": 8}) if agent == "ppo"
                             else (DQN, {"buffer_size": 10}))
        return algorithm("CnnPolicy", Frames(), device="cpu", **kwargs)

    make(36)
    with pytest.raises(RuntimeError):
        make(35)


def test_tile_coding_on_infinite_observation_bounds(write_suite, regs):
    text = """\
name: caps
envs:
  cartpole: {}
methods:
  sarsa:
    agent: sarsa
"""
    message = problems(write_suite, regs, text)
    assert "1 problem\n" in message, message
    assert ("suite.yaml:6: methods.sarsa.agent: agent 'sarsa' needs finite observation bounds "
            "(its spec declares needs_bounded_observations), but env 'cartpole' has infinite "
            "ones on 1, 3; "
            "restrict the method with 'envs: [...]'") in message, message
    # named by the env's observation labels where it has them; on encoded too
    labelled = problems(write_suite, regs, """\
name: caps
envs:
  cartpole-observed: {}
methods:
  sen-sarsa:
    agent: sarsa
    observation: encoded
    encoder: {sampler: rollout}
""")
    assert ("methods.sen-sarsa.agent: agent 'sarsa' needs finite observation bounds (its "
            "spec declares needs_bounded_observations), but env 'cartpole-observed' has "
            "infinite ones on cart velocity, pole velocity") in labelled, labelled
    # an agent that needs no bounds learns there
    ppo = load_suite(write_suite(text.replace("agent: sarsa", "agent: ppo") + TAIL), regs)
    assert len(ppo.cells) == 1


@pytest.mark.parametrize(("encoder", "expected"), [
    ("      arch: resnet\n      sampler: unifrom\n",
     ["suite.yaml:9: methods.sen.encoder.arch: unknown encoder 'resnet'",
      "suite.yaml:10: methods.sen.encoder.sampler: unknown sampler 'unifrom'"]),
    ("      arch: resnet\n      sampler: rollout\n      sampler_config: {repat: 2}\n",
     ["suite.yaml:9: methods.sen.encoder.arch: unknown encoder 'resnet'",
      "suite.yaml:11: methods.sen.encoder.sampler_config.repat: unknown rollout setting "
      "'repat'. Did you mean 'repeat'?"]),
    ("      config:\n        hiden: 32\n      sampler: rollout\n"
     "      sampler_config:\n        repat: 2\n",
     ["suite.yaml:10: methods.sen.encoder.config.hiden: unknown sen-resnet setting 'hiden'",
      "suite.yaml:13: methods.sen.encoder.sampler_config.repat: unknown rollout setting"]),
])
def test_every_typo_in_an_encoder_block_is_reported_at_once(write_suite, regs, encoder,
                                                            expected):
    message = problems(write_suite, regs, f"""\
name: caps
envs:
  mountaincar: {{}}
methods:
  sen:
    agent: sarsa
    observation: encoded
    encoder:
{encoder}""")
    assert f"{len(expected)} problems\n" in message, message
    for fragment in expected:
        assert fragment in message, f"{fragment!r} not in:\n{message}"


def test_a_swept_arch_or_sampler_is_checked_at_the_sweep(write_suite, regs):
    message = problems(write_suite, regs, """\
name: caps
envs:
  cartpole-observed: {}
methods:
  sen:
    agent: ppo
    observation: encoded
    encoder: {sampler: rollout}
variants:
  sen:
    encoder.arch: [sen-resnet, resnet]
    encoder.sampler: [rollout, uniform]
""")
    assert "2 problems\n" in message, message
    assert "suite.yaml:11: variants.sen.encoder.arch: unknown encoder 'resnet'" in message
    assert ("suite.yaml:12: variants.sen.encoder.sampler: env 'cartpole-observed' has no "
            "render() and no set_state(): the uniform sampler needs them") in message, message


def test_every_problem_of_a_suite_is_reported_in_one_run(write_suite, regs):
    message = problems(write_suite, regs, """\
name: caps
envs:
  cartpole: {}
  mountaincar: {}
methods:
  sen-ppo:
    agent: ppo
    observation: encoded
    envs: [cartpole]
    encoder:
      arch: resnet
      sampler: uniform
      sampler_config: {repeat: 2}
  sarsa:
    agent: sarsa
    envs: [cartpole]
  pix:
    agent: dqn
    observation: pixels
    envs: [mountaincar]
    pixels: {height: 32, width: 32}
  sen-sarsa:
    agent: sarsa
    observation: encoded
    envs: [mountaincar]
    encoder: {arch: nature-cnn, sampler: rollout}
    pixels: {height: 24, width: 24}
""")
    expected = [
        "suite.yaml:8: methods.sen-ppo.observation: env 'cartpole' has no observe()",
        "suite.yaml:11: methods.sen-ppo.encoder.arch: unknown encoder 'resnet'",
        "suite.yaml:13: methods.sen-ppo.encoder.sampler_config.repeat: unknown uniform "
        "setting 'repeat'",
        "suite.yaml:15: methods.sarsa.agent: agent 'sarsa' needs finite observation bounds",
        "suite.yaml:21: methods.pix.pixels: agent 'dqn' needs frames of at least 36x36",
        "suite.yaml:27: methods.sen-sarsa.pixels: encoder 'nature-cnn' needs frames of at "
        "least 36x36, got 24x24",
    ]
    for fragment in expected:
        assert fragment in message, f"{fragment!r} not in:\n{message}"
    assert f"{len(expected)} problems\n" in message, message


def test_plugins_that_declare_nothing_need_nothing(write_suite, regs, test_agents):
    """A third-party agent written before these declarations runs on any env."""
    suite = load_suite(write_suite("""\
name: caps
envs:
  cartpole: {}
methods:
  crash: {agent: crash}
""" + TAIL), plugins.registries())
    assert len(suite.cells) == 1
    spec = plugins.registries().agents.get("crash")
    assert spec.min_frame_size is None and not spec.needs_bounded_observations


def test_what_the_built_in_plugins_declare(regs):
    default = {name: regs.agents.get(name).min_frame_size_for(regs.agents.get(name).config())
               for name in regs.agents.names()}
    assert default == {"ddqn": 36, "dqn": 36, "drq": 36, "drq-sac": 36, "ppo": 36, "sac": 36,
                       "sarsa": None}
    drq = regs.agents.get("drq")
    assert drq.min_frame_size_for(drq.config(pad=20)) == 40  # a shift: at most half a frame
    assert [n for n in regs.agents.names() if regs.agents.get(n).needs_bounded_observations] == [
        "sarsa"]
    assert regs.samplers.get("uniform").needs == {"observe", "set_state", "render"}
    assert regs.samplers.get("rollout").needs == {"observe"}
    assert regs.envs.get("mountaincar").capabilities() == {"observe", "set_state", "render"}
    assert regs.envs.get("cartpole").capabilities() == frozenset()
    assert regs.envs.get("mountaincar").unbounded_dimensions() == ()


def test_a_declaration_that_cannot_be_met_is_refused_at_registration():
    with pytest.raises(ValueError, match="needs names"):
        SamplerSpec("s", sample=print, config=object, needs=frozenset({"rendr"}))
    with pytest.raises(ValueError, match="min_frame_size must be a positive int"):
        AgentSpec("a", make=print, config=object, actions=frozenset({"discrete"}),
                  observations=frozenset({"pixels"}), min_frame_size=0)
