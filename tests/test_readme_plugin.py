"""The plugin page of the docs (docs/plugins.md, "Writing a plugin") works as written: its
package, installed as pip would leave it (a dist-info with an entry point, no pip run),
shows up in ``senbench plugins`` and runs its suite next to the built-in env and agent."""

import os
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

DOC = Path(__file__).parent.parent / "docs" / "plugins.md"
BLOCK = re.compile(r"^File: `([^`]+)`\n+```(\w+)\n(.*?)^```$", re.MULTILINE | re.DOTALL)
PACKAGE = "senbench-acrobot/senbench_acrobot/__init__.py"


def doc_files() -> dict[str, tuple[str, str]]:
    """File path → (language, text) of every code block the doc heads with ``File:``."""
    return {path: (lang, body) for path, lang, body in BLOCK.findall(DOC.read_text())}


def test_the_doc_has_the_three_files_in_order():
    files = doc_files()
    assert list(files) == ["senbench-acrobot/pyproject.toml", PACKAGE, "suite.yaml"]
    assert [lang for lang, _ in files.values()] == ["toml", "python", "yaml"]
    text = DOC.read_text()
    assert "# Writing a plugin" in text
    for command in ("pip install -e senbench-acrobot", "senbench plugins",
                    "senbench run suite.yaml", "senbench report results/acrobot-demo"):
        assert command in text


@pytest.fixture
def installed(tmp_path):
    """The doc's package on a fake site dir, and the environment a subprocess needs."""
    files = doc_files()
    project = tomllib.loads(files["senbench-acrobot/pyproject.toml"][1])["project"]
    name, version = project["name"], project["version"]
    assert name == "senbench-acrobot"
    site = tmp_path / "site"
    package = site / "senbench_acrobot"
    package.mkdir(parents=True)
    (package / "__init__.py").write_text(files[PACKAGE][1])
    dist_info = site / f"{name.replace('-', '_')}-{version}.dist-info"
    dist_info.mkdir()
    (dist_info / "METADATA").write_text(
        f"Metadata-Version: 2.1\nName: {name}\nVersion: {version}\n"
    )
    groups = project["entry-points"]
    (dist_info / "entry_points.txt").write_text("".join(
        f"[{group}]\n" + "".join(f"{key} = {value}\n" for key, value in table.items()) + "\n"
        for group, table in groups.items()
    ))
    suite = tmp_path / "suite.yaml"
    suite.write_text(files["suite.yaml"][1])
    env = {k: v for k, v in os.environ.items() if k != "SENBENCH_NO_THIRD_PARTY_PLUGINS"}
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(site), env.get("PYTHONPATH")]))
    env["COLUMNS"] = "200"
    return suite, env


def senbench(env: dict[str, str], *args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "senbench", *args], env=env, cwd=cwd,
                          capture_output=True, text=True, timeout=120, check=False)


@pytest.mark.slow
def test_the_doc_plugin_lists_runs_and_reports(installed, tmp_path):
    suite, env = installed

    listed = senbench(env, "plugins", cwd=tmp_path)
    assert listed.returncode == 0, listed.stderr
    rows = {line.split("│")[2].strip(): line for line in listed.stdout.splitlines()
            if line.count("│") >= 4}
    assert "senbench-acrobot 0.1.0" in rows["acrobot"]
    assert "senbench-acrobot 0.1.0" in rows["random"]
    assert "senbench 0.1.0" in rows["sarsa"]

    off = senbench({**env, "SENBENCH_NO_THIRD_PARTY_PLUGINS": "1"}, "plugins", cwd=tmp_path)
    assert off.returncode == 0, off.stderr
    provided, _, left_out = off.stdout.partition("left out")
    assert "acrobot" not in provided and "mountaincar" in provided
    assert "SENBENCH_NO_THIRD_PARTY_PLUGINS switches third-party plugins off" in left_out

    results = tmp_path / "results"
    ran = senbench(env, "run", str(suite), "--results", str(results), cwd=tmp_path)
    assert ran.returncode == 0, ran.stdout + ran.stderr
    assert "4 finished, 0 failed" in ran.stdout
    assert len(list((results / "acrobot-demo" / "cells").glob("*.parquet"))) == 4

    report = senbench(env, "report", str(results / "acrobot-demo"), cwd=tmp_path)
    assert report.returncode == 0, report.stderr
    assert "acrobot: evaluation return; threshold -100" in report.stdout
    assert "mountaincar: evaluation return; threshold -110" in report.stdout
    assert "random" in report.stdout and "sarsa-state" in report.stdout
