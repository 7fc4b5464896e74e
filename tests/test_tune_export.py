"""senbench tune --export: each block under the comment naming its study; an earlier
export's blocks of other methods are kept, a method tuned again replaces its own, and a
file that is not an export is refused before any trial runs; the best block, ties, and the
trials table."""

import optuna
import pytest
import yaml
from tune_helpers import SUITE as TINY
from tune_helpers import tune

from senbench.cli.views import trials_table
from senbench.errors import OutputError
from senbench.plugin.manager import registries
from senbench.suite import load_suite
from senbench.tune import study as tuning
from senbench.tune.export import best_block, export_best, read_export

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


def test_an_export_says_when_its_best_trial_tied_with_others(write_suite, tmp_path):
    from senbench.tune.export import export_best

    tgt = tuning.target(load_suite(write_suite(TINY), registries()), "sarsa-state", None,
                        registries())
    study = optuna.create_study(direction="minimize")  # frames to threshold: all the budget
    for _ in range(3):
        trial = study.ask()
        tuning.suggest(trial, tgt.space)
        study.tell(trial, 2000.0)
    export_best([(study, tgt)], tmp_path / "b.yaml", objective="steps-to-threshold", seeds=1)
    head = (tmp_path / "b.yaml").read_text().splitlines()[:2]
    assert head[1] == "#   tied with trials 1, 2: the study did not rank them"


def test_a_best_defaults_trial_exports_the_methods_own_entry_unchanged(write_suite):
    ppo = TINY.replace("sarsa-state: {agent: sarsa, hyperparams: {tilings: 8}}",
                        "ppo-state: {agent: ppo}").replace("mountaincar: {}", "pendulum: {}")
    tgt = tuning.target(load_suite(write_suite(ppo, "ppo.yaml"), registries()), "ppo-state",
                        None, registries())
    study = optuna.create_study(direction="maximize")
    tuning.enqueue_defaults(study, tgt, print)
    defaults = study.ask()
    tuning.suggest(defaults, tgt.space)
    study.tell(defaults, -500.0)
    other = study.ask()
    tuning.suggest(other, tgt.space)
    study.tell(other, -900.0)
    # not ent_coef 1e-8 (the defaults clipped into the range): the suite's own entry, so
    # the tuned suite's cells are the untuned one's and `run --reuse` can copy them
    assert best_block(study, tgt) == {"ppo-state": {"agent": "ppo"}}
    # the defaults trial ran other settings than the method has today (its agent's
    # defaults changed since): the block spells out what the trial ran
    changed = ppo.replace("ppo-state: {agent: ppo}",
                          "ppo-state: {agent: ppo, hyperparams: {gae_lambda: 0.9}}")
    today = tuning.target(load_suite(write_suite(changed, "c.yaml"), registries()),
                          "ppo-state", None, registries())
    assert best_block(study, today)["ppo-state"]["hyperparams"]["gae_lambda"] == 0.95
    study.enqueue_trial({**other.params, "ent_coef": 0.01})
    tuned = study.ask()
    tuning.suggest(tuned, tgt.space)
    study.tell(tuned, -100.0)
    assert best_block(study, tgt)["ppo-state"]["hyperparams"]["ent_coef"] == 0.01
    # a default moved into a narrowed range was not what the defaults trial ran: its block
    # is the values the trial ran, as for any other trial
    narrowed = ppo + "tune:\n  ppo-state:\n    learning_rate: {low: 1e-4, high: 5e-4}\n"
    tgt = tuning.target(load_suite(write_suite(narrowed, "n.yaml"), registries()),
                        "ppo-state", None, registries())
    assert tuning.moved_defaults(tgt) == ["learning_rate 0.001 -> 0.0005"]
    study = optuna.create_study(direction="maximize")
    tuning.enqueue_defaults(study, tgt, print)
    defaults = study.ask()
    tuning.suggest(defaults, tgt.space)
    study.tell(defaults, -500.0)
    assert best_block(study, tgt)["ppo-state"]["hyperparams"]["learning_rate"] == 5e-4


def test_the_trials_table_lists_the_best_finished_trials_first_with_the_counts():
    study = optuna.create_study(direction="maximize")
    assert trials_table(study, "s", "auc") is None  # nothing finished: no table
    for value in (-300.0, -100.0, -200.0):
        study.enqueue_trial({"alpha": 0.5})
        study.optimize(lambda trial, v=value: trial.suggest_float("alpha", 0, 1) and v,
                       n_trials=1)
    pruned = study.ask({"alpha": optuna.distributions.FloatDistribution(0, 1)})
    study.tell(pruned, state=optuna.trial.TrialState.PRUNED)
    table = trials_table(study, "s", "auc", top=2)
    assert table.title == "study 's': best trials by auc; 3 complete, 1 pruned, 0 fail, 0 running"
    assert [c.header for c in table.columns] == ["trial", "auc", "alpha"]
    assert list(table.columns[0].cells) == ["1", "2"]  # -100 then -200; -300 is cut
    assert list(table.columns[1].cells) == ["-100.00", "-200.00"]
    minimize = optuna.create_study(direction="minimize")
    minimize.add_trials(study.trials[:3])
    assert list(trials_table(minimize, "m", "auc").columns[0].cells) == ["0", "2", "1"]


@pytest.mark.slow
def test_exporting_a_study_with_no_finished_trial_fails_and_writes_nothing(tmp_path):
    (tmp_path / "s.yaml").write_text(TINY)
    (tmp_path / "results" / "tiny").mkdir(parents=True)
    study = optuna.create_study(study_name="sarsa-state-mountaincar-auc", direction="maximize",
                                storage=f"sqlite:///{tmp_path / 'results' / 'tiny' / 'tune.db'}")
    pruned = study.ask()
    study.tell(pruned, state=optuna.trial.TrialState.PRUNED)  # the study already holds 1
    done = tune(tmp_path, "--trials", "1", "--export", str(tmp_path / "best.yaml"))
    assert done.returncode == 1
    assert "no trial finished yet ({'complete': 0, 'pruned': 1" in done.stderr
    assert "nothing to export" in done.stderr
    assert not (tmp_path / "best.yaml").exists()
