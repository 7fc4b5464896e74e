"""The documentation site (mkdocs.yml, docs/) builds, offline and without a warning; what it
shows runs; and what the code defines — hooks, suite keys, result columns, spec fields — is
on its pages."""

import ast
import os
import re
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from senbench.plugin.manager import registries
from senbench.run.runner import run_suite
from senbench.suite import load_suite

ROOT = Path(__file__).parent.parent
DOCS = ROOT / "docs"
PYTHON_BLOCK = re.compile(r"^```python\n(.*?)^```$", re.MULTILINE | re.DOTALL)

# Loaded first by every Python process of the build (PYTHONPATH): any attempt to reach the
# network fails loudly instead of quietly fetching fonts, inventories or images.
NO_NETWORK = """\
import socket

def _refuse(*args, **kwargs):
    raise OSError("tests/test_docs.py: the docs build must not use the network")

socket.socket.connect = _refuse
socket.socket.connect_ex = _refuse
socket.create_connection = _refuse
socket.getaddrinfo = _refuse
"""


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    """``mkdocs build --strict`` into a temporary folder, offline: (its folder, its log)."""
    tmp = tmp_path_factory.mktemp("docs")
    guard = tmp / "guard"
    guard.mkdir()
    (guard / "sitecustomize.py").write_text(NO_NETWORK)
    env = {**os.environ, "PYTHONPATH": str(guard), "NO_MKDOCS_2_WARNING": "1"}
    out = tmp / "site"
    built = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--config-file",
         str(ROOT / "mkdocs.yml"), "--site-dir", str(out)],
        cwd=tmp, env=env, capture_output=True, text=True, timeout=300, check=False)
    log = built.stdout + built.stderr
    assert built.returncode == 0, log
    return out, log


@pytest.mark.slow
def test_the_site_builds_strict_offline_without_a_warning(site):
    out, log = site
    assert "WARNING" not in log, log
    assert "ERROR" not in log, log
    assert (out / "index.html").is_file()
    pages = list(out.rglob("*.html"))
    for page in pages:
        text = page.read_text()
        assert "fonts.googleapis.com" not in text and "fonts.gstatic.com" not in text, page
    # REPRODUCTION.md is embedded, its figures are served from results/ at the same paths.
    reproduction = (out / "reproduction" / "index.html").read_text()
    assert "Reproducing SEN-DRL with senbench" in reproduction
    assert "include:" not in reproduction
    for figure in re.findall(r"\]\((results/[^)]+\.png)\)", (ROOT / "REPRODUCTION.md").read_text()):
        assert (out / figure).is_file(), figure
    # The built-in plugins' defaults are generated from the registry.
    builtin = (out / "builtin-plugins" / "index.html").read_text()
    for name in ("mountaincar", "pendulum", "sarsa", "ppo", "dqn", "sen-resnet", "uniform"):
        assert f"<code>{name}</code>" in builtin, name
    assert "rl-baselines3-zoo hyperparams/ppo.yml, Pendulum-v1" in builtin


@pytest.mark.slow
def test_the_api_reference_shows_every_exported_name_and_every_spec_field(site):
    import dataclasses

    import senbench

    out, _ = site
    html = (out / "reference" / "index.html").read_text()
    anchors = set(re.findall(r'id="([^"]+)"', html))
    exported = [name for name in senbench.__all__ if name != "__version__"]
    assert not [name for name in exported if f"senbench.{name}" not in anchors]
    missing = []
    for name in exported:
        obj = getattr(senbench, name)
        if dataclasses.is_dataclass(obj):
            missing += [f"{name}.{f.name}" for f in dataclasses.fields(obj)
                        if f"senbench.{name}.{f.name}" not in anchors]
    assert not missing, f"spec fields missing from the API reference: {missing}"
    for hook in hook_names():
        assert f"senbench.plugin.hookspecs.{hook}" in anchors, hook


SUITE = """\
name: quickstart
envs:
  mountaincar: {}
methods:
  sarsa-state: {agent: sarsa}
seeds: 2
budget: 1000
eval: {every: 500, episodes: 1}
"""


@pytest.mark.slow
def test_the_results_page_snippets_run_on_a_results_folder(tmp_path, monkeypatch, capsys):
    """Every Python block of docs/results.md, run as written, on a folder of the layout of
    results/quickstart/; each leaves a non-empty ``curves``."""
    suite = tmp_path / "suite.yaml"
    suite.write_text(SUITE)
    run_suite(load_suite(suite, registries()), tmp_path / "results")
    monkeypatch.chdir(tmp_path)
    blocks = PYTHON_BLOCK.findall((DOCS / "results.md").read_text())
    assert len(blocks) == 4
    libraries = set()
    for block in blocks:
        namespace: dict = {}
        exec(compile(textwrap.dedent(block), "docs/results.md", "exec"), namespace)
        curves = namespace["curves"]
        assert len(curves) == 2 * 3, block  # 2 seeds × evaluations at 0, 500 and 1000 frames
        libraries |= {name for name in ("pandas", "polars", "duckdb") if name in block}
    assert libraries == {"pandas", "polars", "duckdb"}


def hook_names() -> list[str]:
    """The hooks of senbench/plugin/hookspecs.py: its functions decorated ``@hookspec``."""
    tree = ast.parse((ROOT / "senbench" / "plugin" / "hookspecs.py").read_text())
    return [node.name for node in tree.body if isinstance(node, ast.FunctionDef)
            and any(isinstance(d, ast.Name) and d.id == "hookspec" for d in node.decorator_list)]


def test_every_hook_is_documented_on_the_plugins_page():
    hooks = hook_names()
    assert "register_envs" in hooks and len(hooks) >= 4
    page = (DOCS / "plugins.md").read_text()
    assert not [hook for hook in hooks if f"`{hook}(register)`" not in page]


def test_every_suite_key_is_on_the_suites_page():
    from pydantic import BaseModel

    from senbench.suite.schema import SuiteModel

    def keys(model: type[BaseModel]) -> set[str]:
        found = set()
        for name, info in model.model_fields.items():
            found.add(name)
            for arg in _types(info.annotation):
                if isinstance(arg, type) and issubclass(arg, BaseModel):
                    found |= keys(arg)
        return found

    page = (DOCS / "suites.md").read_text()
    table = "\n".join(line for line in page.splitlines() if line.startswith("| `"))
    missing = sorted(key for key in keys(SuiteModel)
                     if not re.search(rf"`[^`|]*\b{key}\b[^`|]*`", table))
    assert not missing, f"suite keys missing from the table of docs/suites.md: {missing}"


def _types(annotation) -> list:
    """Every type inside an annotation: dict[str, X] | None → [dict, str, X, None]."""
    args = getattr(annotation, "__args__", None) or ()
    metadata = getattr(annotation, "__origin__", None)
    return [annotation, *([metadata] if metadata else []),
            *(t for arg in args for t in _types(arg))]


def test_every_result_column_is_on_the_results_page():
    from senbench.results.store import SCHEMA

    page = (DOCS / "results.md").read_text()
    rows = [line for line in page.splitlines() if line.startswith("| `")]
    named = {name for row in rows for name in re.findall(r"`([^`]+)`", row.split(" | ")[0])}
    assert not [column for column in SCHEMA.names if column not in named]


EXAMPLES = ["senbench-cartpole", "senbench-qlearning", "senbench-mlp-encoder",
            "senbench-gaussian-sampler"]


@pytest.mark.slow
def test_the_example_plugins_install_with_pip_and_run_in_a_suite(tmp_path):
    """docs/examples/: the four packages, pip-installed (offline) into a target folder that
    a subprocess puts on its path, are found through their entry points and run together."""
    sources = []
    for name in EXAMPLES:
        shutil.copytree(DOCS / "examples" / name, tmp_path / "src" / name)
        sources.append(str(tmp_path / "src" / name))
    target = tmp_path / "site"
    installed = subprocess.run(
        [sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-index",
         "--no-build-isolation", "--target", str(target), *sources],
        capture_output=True, text=True, timeout=300, check=False)
    assert installed.returncode == 0, installed.stdout + installed.stderr
    env = {k: v for k, v in os.environ.items() if k != "SENBENCH_NO_THIRD_PARTY_PLUGINS"}
    env["PYTHONPATH"] = str(target)
    env["COLUMNS"] = "200"

    def senbench(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, "-m", "senbench", *args], env=env,
                              cwd=tmp_path, capture_output=True, text=True, timeout=300,
                              check=False)

    listed = senbench("plugins")
    assert listed.returncode == 0, listed.stderr
    for name, thing in zip(EXAMPLES, ("cartpole", "qlearning", "mlp", "gaussian"), strict=True):
        row = next((line for line in listed.stdout.splitlines() if f" {thing} " in line), "")
        assert f"{name} 0.1.0" in row, listed.stdout

    suite = DOCS / "examples" / "suite.yaml"
    results = tmp_path / "results"
    ran = senbench("run", str(suite), "--results", str(results))
    assert ran.returncode == 0, ran.stdout + ran.stderr
    assert "3 finished, 0 failed" in ran.stdout, ran.stdout
    report = senbench("report", str(results / "examples-demo"))
    assert report.returncode == 0, report.stderr
    assert "cartpole: evaluation return; threshold 475" in report.stdout
    assert "qlearning-mlp" in report.stdout and "qlearning-state" in report.stdout
