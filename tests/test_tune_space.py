"""senbench tune's search space and refusals: each method's own settings as trial 0, a
suite narrows a space and cannot widen it, a study is never resumed over another space,
and a bad tune block, option or method is refused before anything runs."""


import optuna
import pytest
from tune_helpers import ROOT, SEN, SUITE, TWO, study_of, tune

from senbench.plugin.manager import registries
from senbench.suite import load_suite
from senbench.tune import study as tuning


@pytest.mark.parametrize("suite_file", ["tune-paper-pendulum.yaml",
                                        "tune-paper-pendulum-ppo.yaml",
                                        "tune-paper-mountaincar.yaml",
                                        "tune-mountaincar-bars.yaml"])
def test_every_method_of_the_paper_tuning_suites_runs_its_own_settings_as_trial_0(
        suite_file):
    # a default outside its agent's space (DrQ's target copy at every update, once) or
    # moved by a suite's tune: block would leave the defaults out of that method's study,
    # and its "tuned" block could then lose to them
    regs = registries()
    suite = load_suite(ROOT / "suites" / suite_file, regs)
    for method in suite.model.methods:
        tgt = tuning.target(suite, method, None, regs)
        assert tuning.default_params(tgt)[1] == [], method
        assert tuning.moved_defaults(tgt) == [], method


def test_every_committed_study_was_drawn_from_its_suites_space_today():
    """A committed study can be resumed (and so re-checked) with the repository as it is:
    growing an agent's space must leave the old suite's studies on their own space."""
    from senbench.tune.space import check_same_space

    regs = registries()
    databases = sorted((ROOT / "results").glob("*/tune.db"))
    checked = 0
    for db in databases:
        suite = load_suite(ROOT / "suites" / f"{db.parent.name}.yaml", regs)
        url = f"sqlite:///{db}"
        for summary in optuna.get_all_study_summaries(url):
            study = optuna.load_study(study_name=summary.study_name, storage=url)
            tgt = tuning.target(suite, study.user_attrs["method"], study.user_attrs["env"],
                                regs)
            check_same_space(study, tgt.space, summary.study_name)
            checked += 1
    assert checked >= 3  # the paper's Pendulum PPO studies at least


@pytest.mark.slow
def test_tune_refuses_to_resume_a_study_over_a_changed_space_and_runs_nothing(tmp_path):
    (tmp_path / "s.yaml").write_text(SUITE)
    assert tune(tmp_path, "--trials", "1").returncode == 0
    (tmp_path / "s.yaml").write_text(SUITE + "tune:\n  sarsa-state:\n"
                                     "    alpha: {low: 0.5, high: 1.0}\n")
    done = tune(tmp_path, "--trials", "2")
    assert done.returncode == 2, done.stderr
    assert "was drawn from another search space (alpha:" in done.stderr
    assert "Traceback" not in done.stderr
    assert len(study_of(tmp_path).trials) == 1


def test_tune_refuses_what_it_cannot_tune(write_suite):
    suite = load_suite(write_suite(SUITE.replace("tilings: 8", "tilings: 8, tiles: 6, alpha: "
                                                 "1.0, trace_decay: 0.9")), registries())
    with pytest.raises(Exception, match="no search space left"):
        tuning.target(suite, "sarsa-state", None, registries())
    with pytest.raises(Exception, match="no method 'ppo'"):
        tuning.target(suite, "ppo", None, registries())


def test_a_suite_narrows_the_declared_space_and_cannot_widen_it(write_suite):
    narrowed = SUITE + "tune:\n  sarsa-state:\n    alpha: {low: 0.5, high: 1.0}\n" \
        "    tiles: {low: 5, high: 7}\n"
    tgt = tuning.target(load_suite(write_suite(narrowed), registries()), "sarsa-state", None,
                        registries())
    assert tgt.space["alpha"] == tuning.Float(0.5, 1.0, log=True)
    assert tgt.space["tiles"] == tuning.Int(5, 7)
    for bad, message in [("alpha: {low: 0.01}", "must lie within"),
                         ("tilings: {values: [8]}", "fixes it in hyperparams"),
                         ("tiles: {values: [5]}", "narrowed with 'low' and 'high'"),
                         ("gamma: {low: 0.9}", "searches")]:
        text = SUITE + "tune:\n  sarsa-state:\n    " + bad + "\n"
        with pytest.raises(Exception, match=message):
            tuning.target(load_suite(write_suite(text), registries()), "sarsa-state", None,
                          registries())


def test_a_study_is_not_resumed_over_another_search_space(write_suite):
    """Trials drawn from an older space (a narrowed range, a new setting) are refused, not
    mixed into the new study; the space a study was drawn from passes."""
    from senbench.errors import SuiteError
    from senbench.tune.space import check_same_space, suggest

    regs = registries()
    whole = tuning.target(load_suite(write_suite(SUITE), regs), "sarsa-state", None, regs)
    narrowed = SUITE + "tune:\n  sarsa-state:\n    alpha: {low: 0.5, high: 1.0}\n"
    tgt = tuning.target(load_suite(write_suite(narrowed), regs), "sarsa-state", None, regs)
    study = optuna.create_study(sampler=optuna.samplers.RandomSampler(seed=0))
    study.optimize(lambda trial: suggest(trial, whole.space)["alpha"], n_trials=2)
    check_same_space(study, whole.space, "s")
    with pytest.raises(SuiteError, match=r"study 's': its trial 0 .*alpha: \[.*\] -> "
                       r"\[0\.5, 1\.0, log\]\); .*--study NAME"):
        check_same_space(study, tgt.space, "s")
    grown = {**whole.space, "extra": tuning.Choice((True, False))}
    with pytest.raises(SuiteError, match=r"extra: absent -> \[True, False\]"):
        check_same_space(study, grown, "s")


def test_validation_checks_the_tune_block(write_suite):
    from senbench.errors import SuiteError

    text = SUITE + "tune:\n  sarsa-statee:\n    alpha: {low: 0.5}\n  sarsa-state:\n" \
        "    gamma: {low: 0.9}\n"
    with pytest.raises(SuiteError) as info:
        load_suite(write_suite(text), registries())
    message = str(info.value)
    assert "tune.sarsa-statee" in message and "sarsa-state" in message
    assert "tune.sarsa-state.gamma" in message
    assert "searches alpha, tiles, tilings, trace_decay" in message
    # the ranges themselves, at their lines, before any tuning runs
    text = SUITE + "tune:\n  sarsa-state:\n    alpha: {low: 0.01}\n" \
        "    tiles: {values: [5]}\n    tilings: {low: 4}\n"
    with pytest.raises(SuiteError) as info:
        load_suite(write_suite(text), registries())
    message, lines = str(info.value), len(SUITE.splitlines())
    assert f"suite.yaml:{lines + 3}: tune.sarsa-state.alpha: [0.01, " in message
    assert "must lie within" in message
    assert (f"suite.yaml:{lines + 4}: tune.sarsa-state.tiles: a number is narrowed with "
            "'low' and 'high'") in message
    assert f"suite.yaml:{lines + 5}: tune.sarsa-state.tilings: not searched: the method " \
        "fixes it in hyperparams" in message
    # an encoder setting the method fixes in its encoder's config is not searched either
    text = SEN.replace("alpha: {low: 0.3, high: 0.8}", "encoder.hidden: {values: [64]}")
    with pytest.raises(SuiteError) as info:
        load_suite(write_suite(text), registries())
    assert "tune.sen-sarsa.encoder.hidden: not searched: the method fixes it in its " \
        "encoder's config (hidden: 32)" in str(info.value)


@pytest.mark.slow
def test_a_bad_option_is_refused_before_any_storage_is_made(tmp_path):
    (tmp_path / "s.yaml").write_text(SUITE)
    for bad in (["--objective", "median"], ["--sampler", "grid"], ["--pruner", "asha"]):
        done = tune(tmp_path, "--trials", "1", *bad)
        assert done.returncode == 2 and bad[1] in done.stderr
    assert not (tmp_path / "results").exists()


def test_what_a_tune_of_several_methods_refuses_before_it_runs(tmp_path):
    (tmp_path / "s.yaml").write_text(TWO)
    suite = load_suite(tmp_path / "s.yaml", registries())
    regs = registries()
    every = tuning.tune_targets(suite, None, None, regs, named_study=False, export=False)
    assert [(t.method, t.env) for t in every] == [
        ("sarsa-state", "mountaincar"), ("sarsa-small", "mountaincar"),
        ("ppo-state", "mountaincar"), ("ppo-state", "pendulum")]
    on_pendulum = tuning.tune_targets(suite, None, "pendulum", regs, named_study=False,
                                      export=True)
    assert [(t.method, t.env) for t in on_pendulum] == [("ppo-state", "pendulum")]
    with pytest.raises(tuning.SuiteError, match="--study names one study"):
        tuning.tune_targets(suite, None, None, regs, named_study=True, export=False)
    with pytest.raises(tuning.SuiteError, match="ppo-state runs on several envs"):
        tuning.tune_targets(suite, ["ppo-state"], None, regs, named_study=False, export=True)
    with pytest.raises(tuning.SuiteError, match="--method sarsa: not a method"):
        tuning.tune_targets(suite, ["sarsa"], None, regs, named_study=False, export=False)
