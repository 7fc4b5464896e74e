"""A run's git_commit is '-dirty' only when code differs from the commit."""

import subprocess
from pathlib import Path

import pytest

from senbench.run.provenance import git_commit


def git(cwd, *args):
    subprocess.run(["git", *args], cwd=cwd, check=True, capture_output=True)


@pytest.fixture
def checkout(tmp_path, monkeypatch):
    git(tmp_path, "init", "-q")
    git(tmp_path, "config", "user.email", "t@example.invalid")
    git(tmp_path, "config", "user.name", "t")
    (tmp_path / "pkg").mkdir()
    (tmp_path / "pkg" / "agent.py").write_text("X = 1\n")
    (tmp_path / "tests").mkdir()
    (tmp_path / "tests" / "test_agent.py").write_text("\n")
    (tmp_path / "notes.md").write_text("notes\n")
    (tmp_path / "results").mkdir()
    (tmp_path / "results" / "cell.parquet").write_bytes(b"old")
    (tmp_path / "results" / "helper.py").write_text("\n")
    (tmp_path / "constraints").mkdir()
    (tmp_path / "constraints" / "cpu.txt").write_text("torch==1\n")
    (tmp_path / ".gitignore").write_text("scratch/\n")
    git(tmp_path, "add", "-A")
    git(tmp_path, "commit", "-qm", "one")
    monkeypatch.chdir(tmp_path)
    return tmp_path


def head(path):
    return subprocess.run(["git", "rev-parse", "HEAD"], cwd=path, capture_output=True,
                          text=True, check=True).stdout.strip()


def test_a_clean_checkout_names_its_commit(checkout):
    assert git_commit(checkout / "results", [checkout / "pkg"]) == head(checkout)


def test_results_docs_and_ignored_files_leave_it_clean(checkout):
    (checkout / "results" / "cell.parquet").write_bytes(b"rerun")  # a --force run
    (checkout / "results" / "new.parquet").write_bytes(b"new")
    (checkout / "results" / "helper.py").write_text("# under the results root\n")
    (checkout / "notes.md").write_text("edited beside a long run\n")
    (checkout / "tests" / "test_agent.py").write_text("# a test written beside a run\n")
    (checkout / "tests" / "test_new.py").write_text("\n")
    (checkout / "scratch").mkdir()
    (checkout / "scratch" / "probe.py").write_text("\n")
    assert git_commit(checkout / "results", [checkout / "pkg"]) == head(checkout)


@pytest.mark.parametrize("change", ["edit", "new", "constraints", "rename"])
def test_a_change_to_code_makes_it_dirty(checkout, change):
    if change == "edit":
        (checkout / "pkg" / "agent.py").write_text("X = 2\n")
    elif change == "new":
        (checkout / "pkg" / "plugin.py").write_text("\n")
    elif change == "constraints":
        (checkout / "constraints" / "cpu.txt").write_text("torch==2\n")
    else:
        git(checkout, "mv", "pkg/agent.py", "pkg/learner.py")
    assert git_commit(checkout / "results", [checkout / "pkg"]) == f"{head(checkout)}-dirty"


def test_outside_a_checkout_there_is_no_commit(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("GIT_CEILING_DIRECTORIES", str(tmp_path.parent))
    assert git_commit(tmp_path / "results", [tmp_path]) is None


def test_the_code_is_senbench_and_the_plugins_it_loads():
    import senbench
    import senbench_agents
    from senbench.run.provenance import code_paths

    paths = code_paths()
    assert Path(senbench.__file__).parent.resolve() in paths
    assert Path(senbench_agents.__file__).parent.resolve() in paths
