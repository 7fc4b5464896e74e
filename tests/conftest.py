import os

# Only the plugins shipped with senbench: a plugin installed on the machine must not change
# what the tests see. Worker processes inherit this.
os.environ["SENBENCH_NO_THIRD_PARTY_PLUGINS"] = "1"
os.environ.setdefault("OMP_NUM_THREADS", "1")

import textwrap  # noqa: E402
from pathlib import Path  # noqa: E402

import plugin_for_tests  # noqa: E402
import pytest  # noqa: E402

from senbench.plugin import manager as plugins  # noqa: E402


@pytest.fixture
def write_suite(tmp_path):
    """Write a suite file from (dedented) YAML text and return its path."""

    def write(text: str, name: str = "suite.yaml") -> Path:
        path = tmp_path / name
        path.write_text(textwrap.dedent(text))
        return path

    return write


@pytest.fixture
def test_agents():
    """The agents of tests/plugin_for_tests.py, registered for one test (workers too)."""
    plugins.register_plugin(plugin_for_tests, distribution="senbench-tests", version="0")
    yield plugins.registries()
    plugins.unregister_plugin(plugin_for_tests)


@pytest.fixture
def cli_env(tmp_path):
    """Environment for a ``python -m senbench`` subprocess that sees tests/plugin_for_tests.py
    as an installed third-party distribution (a dist-info with an entry point, as pip
    would leave it)."""
    site = tmp_path / "site"
    dist_info = site / "senbench_tests-0.dist-info"
    dist_info.mkdir(parents=True)
    (dist_info / "METADATA").write_text("Metadata-Version: 2.1\nName: senbench-tests\nVersion: 0\n")
    (dist_info / "entry_points.txt").write_text("[senbench]\ntests = plugin_for_tests\n")
    env = {k: v for k, v in os.environ.items() if k != "SENBENCH_NO_THIRD_PARTY_PLUGINS"}
    here = Path(__file__).parent
    env["PYTHONPATH"] = os.pathsep.join([str(site), str(here)])
    env["COLUMNS"] = "200"
    return env

