import subprocess
import sys

import pytest

import senbench
from senbench import EnvSpec, hookimpl
from senbench.errors import PluginError, UnknownNameError
from senbench.plugin import manager as plugins
from senbench.plugin.hookspecs import register_agents
from senbench.plugin.registry import Origin, Register, Registry


def test_builtins_come_through_the_entry_point_group():
    regs = plugins.registries()
    for registry, name in ((regs.envs, "mountaincar"), (regs.envs, "pendulum"),
                           (regs.agents, "sarsa"), (regs.agents, "ppo")):
        origin = registry.origin(name)
        assert origin.distribution == "senbench"
        assert origin.version == senbench.__version__
    names = [name for name, _ in plugins.pm.list_name_plugin()]
    assert "senbench:classic" in names and "senbench:agents" in names


def test_a_registered_plugin_appears_and_unregistering_removes_it(test_agents):
    assert "crash" in test_agents.agents
    assert test_agents.agents.origin("crash") == Origin("senbench-tests", "0")
    plugins.unregister_plugin(__import__("plugin_for_tests"))
    try:
        assert "crash" not in plugins.registries().agents
    finally:
        plugins.register_plugin(__import__("plugin_for_tests"), "senbench-tests", "0")


class DuplicateMountainCar:
    @hookimpl
    def register_envs(self, register):
        from senbench_classic.mountaincar import MOUNTAINCAR

        register(EnvSpec(**{**MOUNTAINCAR.__dict__, "description": "a copy"}))


def test_two_plugins_registering_one_name_is_an_error_naming_both():
    spec = plugins.registries().envs.get("mountaincar")
    registry = Registry("env", EnvSpec)
    registry.add(spec, Origin("senbench", "0.1.0"))
    with pytest.raises(PluginError) as info:
        registry.add(spec, Origin("senbench-copycat", "1.0"))
    assert "'mountaincar' is registered twice, by senbench and senbench-copycat" in str(info.value)


def test_duplicate_through_the_plugin_manager():
    plugins.registries()
    plugin = DuplicateMountainCar()
    plugins.register_plugin(plugin, distribution="senbench-copycat")
    try:
        expected = "mountaincar' is registered twice, by senbench and senbench-copycat"
        with pytest.raises(PluginError, match=expected):
            plugins.registries()
    finally:
        plugins.unregister_plugin(plugin)
    assert plugins.registries().envs.get("mountaincar").description != "a copy"


def test_unknown_name_lists_the_known_ones_and_suggests_the_closest():
    with pytest.raises(UnknownNameError) as info:
        plugins.registries().envs.get("mountaincr")
    message = str(info.value)
    assert "Did you mean 'mountaincar'?" in message
    assert "mountaincar, mountaincar-bars, pendulum, pendulum-bars" in message


def test_register_checks_the_type_and_names_the_distribution():
    register = Register(Registry("env", EnvSpec), Origin("senbench-sloppy", "2"))
    with pytest.raises(PluginError, match="senbench-sloppy.*expected senbench.EnvSpec"):
        register({"name": "not-a-spec"})


def test_every_hook_is_documented_in_the_readme():
    from pathlib import Path

    readme = (Path(__file__).parents[1] / "README.md").read_text()
    hooks = [name for name in dir(senbench.plugin.hookspecs) if name.startswith("register_")]
    assert len(hooks) == 4
    for hook in hooks:
        assert f"`{hook}(register)`" in readme, f"{hook} is not documented in README.md"
    assert register_agents.__doc__


def test_third_party_autoload_switch(cli_env):
    listing = subprocess.run([sys.executable, "-m", "senbench", "plugins"], env=cli_env,
                             capture_output=True, text=True, check=True).stdout
    assert "crash" in listing and "senbench-tests 0" in listing
    off = {**cli_env, "SENBENCH_NO_THIRD_PARTY_PLUGINS": "1"}
    listing = subprocess.run([sys.executable, "-m", "senbench", "plugins"], env=off,
                             capture_output=True, text=True, check=True).stdout
    assert "crash" not in listing and "mountaincar" in listing
