"""senbench tune --export: each block under the comment naming its study; an earlier
export's blocks of other methods are kept, a method tuned again replaces its own, and a
file that is not an export is refused before any trial runs."""

import optuna
import pytest
import yaml

from senbench.errors import OutputError
from senbench.plugin.manager import registries
from senbench.suite import load_suite
from senbench.tune import study as tuning
from senbench.tune.export import export_best, read_export

SUITE = """\
name: two
envs:
  mountaincar: {}
methods:
  sarsa-state: {agent: sarsa, hyperparams: {tilings: 8}}
  sarsa-small: {agent: sarsa, hyperparams: {tilings: 4}}
  sarsa-new: {agent: sarsa}
seeds: 1
budget: 2000
eval: {every: 1000, episodes: 1}
"""

# an export as senbench wrote them before 2026-12-04: every study's comment at the top
LEGACY = """\
# senbench tune: study 'sarsa-state-mountaincar-auc', trial 2, auc -130.00 over 3 seeds
#   tied with trial 1: the study did not rank them
# senbench tune: study 'sarsa-small-mountaincar-auc', trial 0, auc -150.00 over 3 seeds
sarsa-state:
  agent: sarsa
  hyperparams:
    tilings: 8
    alpha: 0.3
sarsa-small:
  agent: sarsa
  hyperparams:
    tilings: 4
"""


def studied(write_suite, method, value, alpha):
    tgt = tuning.target(load_suite(write_suite(SUITE), registries()), method, None,
                        registries())
    study = optuna.create_study(study_name=f"{method}-mountaincar-auc", direction="maximize")
    study.enqueue_trial({"alpha": alpha})
    trial = study.ask()
    tuning.suggest(trial, tgt.space)
    study.tell(trial, value)
    return study, tgt


def test_each_study_comment_goes_with_its_methods_block(tmp_path):
    path = tmp_path / "tuned.yaml"
    path.write_text(LEGACY)
    segments = read_export(path)
    assert list(segments) == ["sarsa-state", "sarsa-small"]
    assert segments["sarsa-state"].startswith(
        "# senbench tune: study 'sarsa-state-mountaincar-auc'")
    assert "#   tied with trial 1" in segments["sarsa-state"]
    assert "sarsa-small" not in segments["sarsa-state"]
    assert segments["sarsa-small"].startswith(
        "# senbench tune: study 'sarsa-small-mountaincar-auc'")
    assert yaml.safe_load("".join(segments.values())) == yaml.safe_load(LEGACY)
    assert read_export(tmp_path / "none.yaml") == {}


def test_an_export_keeps_other_methods_blocks_and_replaces_its_own(write_suite, tmp_path):
    path = tmp_path / "tuned.yaml"
    path.write_text(LEGACY)
    export_best([studied(write_suite, "sarsa-state", -120.0, 0.25)], path, objective="auc",
                seeds=3)
    text = path.read_text()
    blocks = yaml.safe_load(text)
    assert list(blocks) == ["sarsa-state", "sarsa-small"]  # in their place
    assert blocks["sarsa-state"]["hyperparams"]["alpha"] == 0.25  # the new study's
    assert blocks["sarsa-small"] == yaml.safe_load(LEGACY)["sarsa-small"]  # kept
    assert text.count("# senbench tune: study") == 2
    assert "trial 2" not in text and "tied" not in text  # the replaced block's comment went
    lines = text.splitlines()
    assert lines[lines.index("sarsa-small:") - 1].startswith(
        "# senbench tune: study 'sarsa-small-mountaincar-auc'")
    path.write_text(LEGACY.rstrip("\n"))  # no newline at its end
    export_best([studied(write_suite, "sarsa-new", -99.0, 0.3)], path, objective="auc",
                seeds=3)
    blocks = yaml.safe_load(path.read_text())
    assert list(blocks) == ["sarsa-state", "sarsa-small", "sarsa-new"]
    assert blocks["sarsa-small"] == yaml.safe_load(LEGACY)["sarsa-small"]
    fresh = tmp_path / "fresh.yaml"
    export_best([studied(write_suite, "sarsa-small", -140.0, 0.4)], fresh, objective="auc",
                seeds=3)
    assert list(yaml.safe_load(fresh.read_text())) == ["sarsa-small"]


@pytest.mark.parametrize("text", ["name: a suite\nenvs: {}\n", "- a\n- list\n", "a: [1\n",
                                  "{a: {agent: sarsa}, b: {agent: sarsa}}\n",
                                  "---\na: {agent: sarsa}\n"])
def test_a_file_that_is_not_an_export_is_refused_not_replaced(tmp_path, text):
    path = tmp_path / "mine.yaml"
    path.write_text(text)
    with pytest.raises(OutputError, match="--export .*mine.yaml.*name a new file"):
        read_export(path)
    assert path.read_text() == text
