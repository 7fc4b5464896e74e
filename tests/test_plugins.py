import inspect
import re
import subprocess
import sys
import textwrap

import pytest

import senbench
from senbench import EnvSpec, hookimpl
from senbench.errors import PluginError, SuiteError, UnknownNameError
from senbench.plugin import manager as plugins
from senbench.plugin.hookspecs import register_agents
from senbench.plugin.registry import Origin, Register, Registry
from senbench.suite import load_suite


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


def test_a_duplicate_leaves_out_the_later_ones_thing_and_names_both():
    plugins.registries()
    plugin = DuplicateMountainCar()
    plugins.register_plugin(plugin, distribution="senbench-copycat", version="1.0")
    try:
        regs = plugins.registries()
        assert regs.envs.get("mountaincar").description != "a copy"
        assert regs.envs.origin("mountaincar").distribution == "senbench"
        [problem] = regs.problems
        assert str(problem).startswith(
            "env 'mountaincar' of plugin 'DuplicateMountainCar' (senbench-copycat 1.0) is "
            f"left out: senbench {senbench.__version__} registered env 'mountaincar' first.")
    finally:
        plugins.unregister_plugin(plugin)
    assert plugins.registries().problems == []


class RaisingHook:
    @hookimpl
    def register_envs(self, register):
        from senbench_classic.mountaincar import MOUNTAINCAR

        register(EnvSpec(**{**MOUNTAINCAR.__dict__, "name": "half-registered"}))
        raise RuntimeError("the plugin's own bug")

    @hookimpl
    def register_agents(self, register):
        from plugin_for_tests import CrashAgent, CrashConfig

        register(senbench.AgentSpec("fine-alone", CrashAgent, CrashConfig,
                                    frozenset({"discrete"}), frozenset({"state"})))


def test_a_hook_that_raises_disables_its_plugin_and_says_where(write_suite):
    plugin = RaisingHook()
    plugins.register_plugin(plugin, distribution="senbench-raising", version="2")
    try:
        regs = plugins.registries()
        assert "half-registered" not in regs.envs and "fine-alone" not in regs.agents
        assert "mountaincar" in regs.envs and "sarsa" in regs.agents  # the rest works
        [problem] = regs.problems
        message = str(problem)
        assert message.startswith("plugin 'RaisingHook' (senbench-raising 2) is disabled: its "
                                  "register_envs hook raised RuntimeError: the plugin's own bug")
        lines, first = inspect.getsourcelines(RaisingHook.register_envs)
        line = first + next(i for i, text in enumerate(lines) if "raise" in text)
        assert message.endswith(f"test_plugins.py:{line})")
        with pytest.raises(UnknownNameError, match="Env 'half-registered' is provided by plugin "
                           "'RaisingHook' .senbench-raising 2., which is disabled: its "
                           "register_envs hook raised RuntimeError"):
            regs.envs.get("half-registered")
        with pytest.raises(SuiteError, match="may be provided by a disabled plugin: plugin "
                           "'RaisingHook'"):
            load_suite(write_suite(GOOD.replace("sarsa}", "no-such-agent}")), regs)
        load_suite(write_suite(GOOD), regs)  # a suite that does not need it is fine
    finally:
        plugins.unregister_plugin(plugin)
    assert plugins.registries().problems == []


GOOD = """\
name: good
envs: {mountaincar: {}}
methods: {sarsa-state: {agent: sarsa}}
seeds: 1
budget: 1000
eval: {every: 500, episodes: 1}
"""


def test_the_last_frame_inside_the_plugin_is_named(tmp_path):
    module = tmp_path / "a_plugin_pkg"
    module.mkdir()
    (module / "__init__.py").write_text("from a_plugin_pkg import inner\n")
    (module / "inner.py").write_text("x = 1\nimport a_module_that_is_nowhere\n")
    sys.path.insert(0, str(tmp_path))
    try:
        with pytest.raises(ImportError) as info:
            __import__("a_plugin_pkg")
    finally:
        sys.path.remove(str(tmp_path))
        for name in ("a_plugin_pkg", "a_plugin_pkg.inner"):
            sys.modules.pop(name, None)
    text = plugins.describe(info.value, [module])
    assert text == ("ModuleNotFoundError: No module named 'a_module_that_is_nowhere' "
                    f"({module / 'inner.py'}:2)")


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


def test_a_misspelled_hook_is_refused_not_kept_uncalled():
    import types

    plugin = types.ModuleType("typo_plugin")

    @hookimpl
    def register_env(register):  # register_envs, misspelled: pluggy would never call it
        raise AssertionError("never called")

    plugin.register_env = register_env
    with pytest.raises(ValueError, match=r"@hookimpl 'register_env' \(did you mean "
                       r"'register_envs'\?\) is no senbench hook; the hooks are "
                       "register_agents, register_encoders, register_envs, register_samplers"):
        plugins.register_plugin(plugin, distribution="senbench-typo")
    assert plugins.pm.get_plugin("senbench-typo:typo_plugin") is None  # not left registered


@pytest.mark.parametrize("change, said", [
    ({"actions": frozenset({"Discrete"})}, "actions names ['Discrete']; it chooses from "
     "discrete, continuous"),
    ({"observations": frozenset({"image"})}, "observations names ['image']; it chooses "
     "from state, pixels, encoded"),
    ({"memory_formats": frozenset({"nhwc"})}, "memory_formats names ['nhwc']"),
    ({"defaults": {"mountaincar": senbench.AgentDefaults({"afterr": 3}, "a typo")}},
     "defaults['mountaincar'] sets ['afterr'], which its config CrashConfig has no field for"),
])
def test_an_agent_spec_that_names_what_does_not_exist_is_refused_when_built(change, said):
    from plugin_for_tests import CrashAgent, CrashConfig

    spec = dict(name="odd", make=CrashAgent, config=CrashConfig,
                actions=frozenset({"discrete"}), observations=frozenset({"state"}))
    with pytest.raises(ValueError, match=re.escape(f"agent 'odd': {said}")):
        senbench.AgentSpec(**{**spec, **change})


def test_the_observation_kinds_agents_choose_from_are_the_ones_senbench_builds():
    from senbench.observe.observations import OBSERVATIONS
    from senbench.plugin.specs import OBSERVATION_KINDS

    assert sorted(OBSERVATIONS) == sorted(OBSERVATION_KINDS)


def test_an_optional_hook_of_a_later_senbench_is_kept():
    import types

    plugin = types.ModuleType("later_plugin")

    @hookimpl(optionalhook=True)
    def register_reporters(register):  # a hook this senbench does not have
        raise AssertionError("never called")

    @hookimpl
    def register_envs(register):
        pass

    plugin.register_reporters, plugin.register_envs = register_reporters, register_envs
    plugins.register_plugin(plugin, distribution="senbench-later")
    try:
        assert plugins.pm.get_plugin("senbench-later:later_plugin") is plugin
    finally:
        plugins.unregister_plugin(plugin)


def test_every_hook_is_documented_on_the_plugins_page():
    from pathlib import Path

    page = (Path(__file__).parents[1] / "docs" / "plugins.md").read_text()
    hooks = [name for name in dir(senbench.plugin.hookspecs) if name.startswith("register_")]
    assert len(hooks) == 4
    for hook in hooks:
        assert f"`{hook}(register)`" in page, f"{hook} is not documented in docs/plugins.md"
    assert register_agents.__doc__


@pytest.mark.slow
def test_third_party_autoload_switch(cli_env):
    listing = subprocess.run([sys.executable, "-m", "senbench", "plugins"], env=cli_env,
                             capture_output=True, text=True, check=True).stdout
    assert "crash" in listing and "senbench-tests 0" in listing
    off = {**cli_env, "SENBENCH_NO_THIRD_PARTY_PLUGINS": "1"}
    listing = subprocess.run([sys.executable, "-m", "senbench", "plugins"], env=off,
                             capture_output=True, text=True, check=True).stdout
    assert "crash" not in listing and "mountaincar" in listing


def fake_distribution(site, dist: str, entry: str, module: str, source: str) -> None:
    """Install ``source`` as module ``module`` of a distribution ``dist`` 1.0 whose entry
    point ``entry`` is in the senbench group, as pip would leave it."""
    info = site / f"{dist.replace('-', '_')}-1.0.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {dist}\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text(f"[senbench]\n{entry} = {module}\n")
    (site / f"{module}.py").write_text(textwrap.dedent(source))


@pytest.fixture
def broken_env(cli_env, tmp_path):
    """cli_env, with four broken plugins installed beside plugin_for_tests: two that fail
    to import, one whose hook raises, one that registers a built-in's name."""
    site = tmp_path / "site"
    fake_distribution(site, "senbench-broken", "broken", "broken_import_plugin", """\
        import senbench
        import a_module_that_is_nowhere
        """)
    fake_distribution(site, "senbench-crashing", "crashing", "crashing_plugin", """\
        raise RuntimeError("not an ImportError")
        """)
    fake_distribution(site, "senbench-raising", "raising", "raising_hook_plugin", """\
        import senbench
        from plugin_for_tests import CrashAgent, CrashConfig


        @senbench.hookimpl
        def register_agents(register):
            register(senbench.AgentSpec("boom", CrashAgent, CrashConfig,
                                        frozenset({"discrete"}), frozenset({"state"})))
            raise ValueError("a bug in the plugin")
        """)
    fake_distribution(site, "senbench-copycat", "copy", "copycat_plugin", """\
        import senbench
        from plugin_for_tests import CrashAgent, CrashConfig
        from senbench_classic.mountaincar import MOUNTAINCAR


        @senbench.hookimpl
        def register_envs(register):
            register(senbench.EnvSpec(**{**MOUNTAINCAR.__dict__, "description": "a copy"}))


        @senbench.hookimpl
        def register_agents(register):
            register(senbench.AgentSpec("copycat-agent", CrashAgent, CrashConfig,
                                        frozenset({"discrete"}), frozenset({"state"})))
        """)
    return cli_env


def senbench_cli(env, *args):
    return subprocess.run([sys.executable, "-m", "senbench", *args], env=env,
                          capture_output=True, text=True)


@pytest.mark.slow
def test_broken_plugins_disable_themselves_not_the_tool(broken_env, tmp_path):
    site = tmp_path / "site"
    listing = senbench_cli(broken_env, "plugins")
    assert listing.returncode == 0, listing.stderr
    assert "crash" in listing.stdout and "copycat-agent" in listing.stdout
    assert "boom" not in listing.stdout and "a copy" not in listing.stdout
    warnings = listing.stderr
    assert "Traceback" not in warnings
    assert warnings.count("warning:") == 4, warnings
    assert ("plugin 'broken' (senbench-broken 1.0) is disabled: it failed to import: "
            "ModuleNotFoundError: No module named 'a_module_that_is_nowhere' "
            f"({site / 'broken_import_plugin.py'}:2)") in warnings
    assert ("plugin 'raising' (senbench-raising 1.0) is disabled: its register_agents hook "
            "raised ValueError: a bug in the plugin "
            f"({site / 'raising_hook_plugin.py'}:9)") in warnings
    assert ("env 'mountaincar' of plugin 'copy' (senbench-copycat 1.0) is left out: senbench "
            f"{senbench.__version__} registered env 'mountaincar' first") in warnings
    assert "SENBENCH_DISABLE_PLUGINS=broken to leave it out" in warnings

    (tmp_path / "good.yaml").write_text(GOOD)
    checked = senbench_cli(broken_env, "validate", str(tmp_path / "good.yaml"))
    assert checked.returncode == 0 and "ok" in checked.stdout, checked.stderr
    assert checked.stderr.count("warning:") == 4

    (tmp_path / "bad.yaml").write_text(GOOD.replace(
        "methods: {sarsa-state: {agent: sarsa}}",
        "methods: {a: {agent: boom}, b: {agent: from-broken}}"))
    refused = senbench_cli(broken_env, "validate", str(tmp_path / "bad.yaml"))
    assert refused.returncode == 2 and "Traceback" not in refused.stderr
    error = refused.stderr[refused.stderr.index("error:"):]
    assert ("Agent 'boom' is provided by plugin 'raising' (senbench-raising 1.0), which is "
            "disabled: its register_agents hook raised ValueError") in error
    assert ("unknown agent 'from-broken'. Known agents: ") in error
    assert ("It may be provided by a disabled plugin: plugin 'broken' (senbench-broken 1.0) "
            "is disabled: it failed to import: ModuleNotFoundError") in error

    assert ("plugin 'crashing' (senbench-crashing 1.0) is disabled: it failed to import: "
            f"RuntimeError: not an ImportError ({site / 'crashing_plugin.py'}:1)") in warnings

    (tmp_path / "two.yaml").write_text(GOOD.replace("seeds: 1", "seeds: 2"))
    ran = senbench_cli(broken_env, "run", str(tmp_path / "two.yaml"), "--workers", "2",
                       "--results", str(tmp_path / "results"))  # cells from a process server
    assert ran.returncode == 0, ran.stderr
    assert ran.stderr.count("warning:") == 4 and "Traceback" not in ran.stderr, ran.stderr
    assert "2 finished, 0 failed" in ran.stdout


@pytest.mark.slow
def test_plugins_disabled_by_name_or_distribution(broken_env, tmp_path):
    off = {**broken_env,
           "SENBENCH_DISABLE_PLUGINS": "broken, senbench-raising,copy,senbench-crashing"}
    listing = senbench_cli(off, "plugins")
    assert listing.returncode == 0 and listing.stderr == ""
    assert "crash" in listing.stdout and "copycat-agent" not in listing.stdout
    left_out = listing.stdout.split("left out", 1)[1]  # listed, with why, after the rest
    for plugin in ("broken", "copy"):
        assert plugin in left_out
    assert left_out.count("SENBENCH_DISABLE_PLUGINS names it") == 4

    (tmp_path / "crash.yaml").write_text(GOOD.replace("agent: sarsa", "agent: crash"))
    off["SENBENCH_DISABLE_PLUGINS"] += ",tests"
    refused = senbench_cli(off, "validate", str(tmp_path / "crash.yaml"))
    assert refused.returncode == 2 and refused.stderr.startswith("error:")
    print(refused.stderr)
    assert "unknown agent 'crash'" in refused.stderr
    assert "It may be provided by a disabled plugin: plugin '" in refused.stderr
    for plugin in ("'broken' (senbench-broken 1.0)", "'tests' (senbench-tests 0)"):
        assert f"plugin {plugin} is disabled: SENBENCH_DISABLE_PLUGINS names it" in refused.stderr
