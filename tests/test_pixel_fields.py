"""Settings that only act on pixels (an agent config's PIXEL_FIELDS) are refused, at their
line, for a method that learns on the state or on encoded observations."""

from __future__ import annotations

import pytest

from senbench.errors import SuiteError
from senbench.plugin.manager import registries
from senbench.suite import load_suite

SUITE = """\
name: pixel-fields
envs:
  pendulum: {}
methods:
  m: {agent: sac, observation: OBS, hyperparams: {SETTING}}
seeds: 1
budget: 100
eval: {every: 100, episodes: 1}
"""


@pytest.mark.parametrize("setting", ["actor_convs: critic", "features_head: layernorm-tanh"])
def test_a_pixel_setting_on_the_state_is_refused_at_its_line(write_suite, setting):
    text = SUITE.replace("OBS", "state").replace("SETTING", setting)
    with pytest.raises(SuiteError) as err:
        load_suite(write_suite(text), registries())
    message = str(err.value)
    assert "suite.yaml:5: methods.m.hyperparams" in message
    assert f"{setting.split(':')[0]} only acts on pixels" in message
    assert "learns on state" in message


def test_the_same_setting_on_pixels_and_its_default_on_the_state_are_accepted(write_suite):
    pixels = SUITE.replace("OBS", "pixels").replace("SETTING", "actor_convs: critic")
    assert load_suite(write_suite(pixels), registries()).cells
    default = SUITE.replace("OBS", "state").replace("SETTING", "actor_convs: own")
    assert load_suite(write_suite(default, "default.yaml"), registries()).cells


def test_several_pixel_settings_are_named_together(write_suite):
    both = "features_head: layernorm-tanh, actor_convs: critic"
    text = SUITE.replace("OBS", "state").replace("SETTING", both)
    with pytest.raises(SuiteError, match="features_head and actor_convs only act on pixels"):
        load_suite(write_suite(text), registries())
