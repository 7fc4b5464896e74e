"""Files written on request (--out, --export): a path that cannot take the file is refused
before any work, with exit 2 and nothing written; a file is written whole or not at all."""

import subprocess
import sys

import pytest

from senbench.errors import OutputError
from senbench.results.outputs import FIGURES, check_out_file, written_whole


def test_an_out_file_is_checked_for_its_kind_and_its_folder(tmp_path):
    check_out_file(tmp_path / "a.PNG", FIGURES)  # any case
    check_out_file(tmp_path / "new" / "deeper" / "a.svg", FIGURES)  # folders are made
    (tmp_path / "file").write_text("x")
    for path, message in ((tmp_path / "a.txt", "name a .png, .pdf or .svg file"),
                          (tmp_path, "is a folder; name a file in it"),
                          (tmp_path / "file" / "a.png", "is a file, not a folder")):
        with pytest.raises(OutputError, match=message):
            check_out_file(path, FIGURES)
    with pytest.raises(OutputError, match="--export .*name a .yaml or .yml file"):
        check_out_file(tmp_path / "best.txt", (".yaml", ".yml"), "--export")


def test_a_file_is_written_whole_or_the_old_one_stays(tmp_path):
    out = tmp_path / "sub" / "s.csv"
    with written_whole(out) as tmp:
        tmp.write_text("new")
    assert out.read_text() == "new"
    with pytest.raises(RuntimeError), written_whole(out) as tmp:
        tmp.write_text("half")
        raise RuntimeError("the writer failed")
    assert out.read_text() == "new"
    with pytest.raises(OutputError, match="--out .*s.csv"), written_whole(out) as tmp:
        raise IsADirectoryError(21, "Is a directory")
    assert sorted(p.name for p in out.parent.iterdir()) == ["s.csv"]  # no temporary file


def cli(*args):
    return subprocess.run([sys.executable, "-m", "senbench", *args], capture_output=True,
                          text=True)


@pytest.mark.slow
@pytest.mark.parametrize("args", [
    ("plot", "curves", "{tmp}/no-results", "--out", "{tmp}/c.txt"),
    ("plot", "traces", "--out", "{tmp}"),
    ("show", "pendulum", "--out", "{tmp}/frames.jpg"),
    ("tune", "{tmp}/s.yaml", "--method", "sarsa-state", "--trials", "1", "--results",
     "{tmp}/results", "--export", "{tmp}/best.txt"),
])
def test_commands_refuse_an_out_file_before_doing_anything(tmp_path, args):
    (tmp_path / "s.yaml").write_text(
        "name: tiny\nenvs:\n  mountaincar: {}\nmethods:\n  sarsa-state: {agent: sarsa}\n"
        "seeds: 1\nbudget: 1000\neval: {every: 500, episodes: 1}\n")
    before = sorted(tmp_path.rglob("*"))
    done = cli(*(a.format(tmp=tmp_path) for a in args))
    assert done.returncode == 2, done.stdout + done.stderr
    assert "error: --out" in done.stderr or "error: --export" in done.stderr, done.stderr
    assert "Traceback" not in done.stderr
    assert sorted(tmp_path.rglob("*")) == before  # no study, no figure, no folder


@pytest.mark.slow
def test_plot_traces_train_needs_the_results_folder_it_trains_for(tmp_path):
    done = cli("plot", "traces", "--train", "--out", str(tmp_path / "t.png"))
    assert done.returncode == 2 and "--train trains the encoders of --results" in done.stderr
    assert not list(tmp_path.iterdir())
