"""senbench tune: a tiny study runs, resumes, exports a block a suite runs; pruning on a
crafted curve; two processes share one study; a killed trial does not stay RUNNING."""

import os
import subprocess
import sys
import time

import optuna
import pytest
import yaml
from tune_helpers import SEN, SUITE, TWO, study_of, tune

from senbench.plugin.manager import registries
from senbench.plugin.specs import Float, Int
from senbench.suite import load_suite
from senbench.tune import study as tuning


@pytest.mark.slow
def test_a_study_runs_resumes_and_exports_a_block_a_suite_runs(tmp_path):
    # alpha's range leaves out sarsa's own 1.0: the defaults trial runs 0.5, so whichever
    # trial wins, the export spells out what it ran
    (tmp_path / "s.yaml").write_text(SUITE + "tune:\n  sarsa-state:\n"
                                     "    alpha: {low: 0.05, high: 0.5}\n")
    done = tune(tmp_path, "--trials", "2")
    assert done.returncode == 0, done.stderr
    assert "2 complete" in done.stdout
    done = tune(tmp_path, "--trials", "3", "--export", str(tmp_path / "best.yaml"))
    assert done.returncode == 0, done.stderr
    trials = study_of(tmp_path).trials
    assert len(trials) == 3  # resumed: one more, not three more
    assert trials[2].params != trials[1].params  # not the first run's random draw again
    assert {t.params.keys().__len__() for t in trials} == {3}  # tilings is fixed by the suite
    block = yaml.safe_load((tmp_path / "best.yaml").read_text())
    hyperparams = block["sarsa-state"]["hyperparams"]
    assert hyperparams["tilings"] == 8 and set(hyperparams) == {"tilings", "tiles", "alpha",
                                                                "trace_decay"}
    suite = SUITE.replace("  sarsa-state: {agent: sarsa, hyperparams: {tilings: 8}}\n",
                          "  " + yaml.safe_dump(block).replace("\n", "\n  ").rstrip() + "\n")
    (tmp_path / "use.yaml").write_text(suite)
    ran = subprocess.run([sys.executable, "-m", "senbench", "run", str(tmp_path / "use.yaml"),
                          "--results", str(tmp_path / "use")], capture_output=True, text=True)
    assert ran.returncode == 0, ran.stderr
    assert "1 finished, 0 failed" in ran.stdout


@pytest.mark.slow
def test_two_processes_share_one_study(tmp_path):
    (tmp_path / "s.yaml").write_text(SUITE)
    (tmp_path / "results" / "tiny").mkdir(parents=True)
    env = {**os.environ, "COLUMNS": "200"}
    args = [sys.executable, "-m", "senbench", "tune", str(tmp_path / "s.yaml"), "--method",
            "sarsa-state", "--seeds", "1", "--trials", "6", "--results",
            str(tmp_path / "results")]
    procs = [subprocess.Popen(args + ["--seed", str(i)], stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True, env=env) for i in range(2)]
    for proc in procs:
        _, stderr = proc.communicate(timeout=300)
        assert proc.returncode == 0, stderr
    trials = study_of(tmp_path).trials
    assert 6 <= len(trials) <= 7  # each process stops once the study holds 6
    assert len({t.user_attrs["pid"] for t in trials}) == 2
    assert sum(bool(t.user_attrs.get("defaults")) for t in trials) == 1  # queued once


def test_the_pruner_stops_a_trial_whose_seed_mean_curve_falls_behind():
    study = optuna.create_study(direction="maximize", pruner=optuna.pruners.MedianPruner(
        n_startup_trials=2, n_warmup_steps=0))
    curves = {0: [-100.0, -90.0], 1: [-110.0, -95.0], 2: [-400.0, -100.0]}
    reached = {}

    def objective(trial):
        progress = tuning.PruningProgress(trial, ["a", "b"], lambda message: None)
        for i, value in enumerate(curves[trial.number]):
            step = 1000 * (i + 1)
            progress.update("a", step, 1.0, value, step)
            reached[trial.number] = step  # one seed alone reports nothing to the pruner
            progress.update("b", step, 1.0, value + 10, step)
        return curves[trial.number][-1]

    study.optimize(objective, n_trials=3)
    states = [t.state for t in study.trials]
    assert states[:2] == [optuna.trial.TrialState.COMPLETE] * 2
    assert states[2] == optuna.trial.TrialState.PRUNED and reached[2] == 1000
    assert study.trials[0].intermediate_values == {1000: -95.0, 2000: -85.0}  # seed means


def _pruned(objective, direction, curves):
    """Which of three trials the median pruner stops, fed ``curves[trial]``: per step, the
    (evaluation return, training return so far) both seeds report."""
    study = optuna.create_study(direction=direction, pruner=optuna.pruners.MedianPruner(
        n_startup_trials=2, n_warmup_steps=0))

    def run(trial):
        progress = tuning.PruningProgress(trial, ["a", "b"], lambda message: None, objective)
        for i, (last_eval, train) in enumerate(curves[trial.number]):
            step = 1000 * (i + 1)
            for cell in ("a", "b"):
                progress.update(cell, step, 1.0, last_eval, step, train)
                # later progress of the same evaluation does not move the value reported
                progress.update(cell, step + 10, 1.0, last_eval, step, -1e6)
        return 0.0

    study.optimize(run, n_trials=3)
    return [t.state == optuna.trial.TrialState.PRUNED for t in study.trials], study


def test_the_pruner_follows_the_objective_not_always_the_evaluation():
    # evaluations flat at -1,000 (a greedy policy that never escapes) while training
    # returns differ: train-return prunes on the training returns
    curves = {0: [(-1000.0, -800.0), (-1000.0, -600.0)],
              1: [(-1000.0, -850.0), (-1000.0, -650.0)],
              2: [(-1000.0, -990.0), (-1000.0, -990.0)]}
    pruned, study = _pruned("train-return", "maximize", curves)
    assert pruned == [False, False, True]
    assert study.trials[0].intermediate_values == {1000: -800.0, 2000: -600.0}
    assert _pruned("auc", "maximize", curves)[0] == [False, False, False]  # flat: a draw
    # before any training episode has ended there is nothing to report
    pruned, study = _pruned("train-return", "maximize", {0: [(-1000.0, None)]} | {
        1: [(-1000.0, None)], 2: [(-1000.0, None)]})
    assert pruned == [False] * 3 and study.trials[0].intermediate_values == {}
    # steps-to-threshold is minimised: the trial whose returns lag is the one pruned
    lagging = {0: [(-300.0, None)], 1: [(-320.0, None)], 2: [(-900.0, None)]}
    assert _pruned("steps-to-threshold", "minimize", lagging)[0] == [False, False, True]


def test_a_study_runs_the_methods_own_settings_first_and_again_if_killed(write_suite):
    suite = load_suite(write_suite(SUITE), registries())
    tgt = tuning.target(suite, "sarsa-state", None, registries())
    params, outside = tuning.default_params(tgt)
    assert outside == [] and set(params) == {"tiles", "alpha", "trace_decay"}  # tilings fixed
    assert params == {k: tgt.template.hyperparams[k] for k in params}
    study = optuna.create_study(direction="maximize")
    tuning.enqueue_defaults(study, tgt, print)
    first = study.ask()
    assert tuning.suggest(first, tgt.space) == params  # the first trial: the defaults
    tuning.enqueue_defaults(study, tgt, print)  # running: not queued twice
    assert len(study.trials) == 1
    study.tell(first, state=optuna.trial.TrialState.FAIL)  # its process was killed
    tuning.enqueue_defaults(study, tgt, print)  # so the defaults are queued again
    again = study.ask()
    assert again.number == 1 and tuning.suggest(again, tgt.space) == params
    study.tell(again, 1.0)
    tuning.enqueue_defaults(study, tgt, print)  # finished: never again
    assert len(study.trials) == 2
    # a study begun without them (or whose defaults all failed) gets them next
    older = optuna.create_study(direction="maximize")
    older.tell(older.ask(), 0.5)
    tuning.enqueue_defaults(older, tgt, print)
    assert tuning.suggest(older.ask(), tgt.space) == params
    # a number outside the searched range is clipped into it (PPO's ent_coef 0.0)
    ppo = SUITE.replace("sarsa-state: {agent: sarsa, hyperparams: {tilings: 8}}",
                        "ppo-state: {agent: ppo}").replace("mountaincar: {}", "pendulum: {}")
    tgt = tuning.target(load_suite(write_suite(ppo, "ppo.yaml"), registries()), "ppo-state",
                        None, registries())
    params, outside = tuning.default_params(tgt)
    assert tgt.template.hyperparams["ent_coef"] == 0.0 and params["ent_coef"] == 1e-8
    assert params["n_steps"] == 1024 and outside == []
    # a choice the defaults are not among leaves them out, and says so
    narrowed = ppo + "tune:\n  ppo-state:\n    n_steps: {values: [256, 512]}\n"
    tgt = tuning.target(load_suite(write_suite(narrowed, "n.yaml"), registries()), "ppo-state",
                        None, registries())
    logged, study = [], optuna.create_study(direction="maximize")
    tuning.enqueue_defaults(study, tgt, logged.append)
    assert study.trials == [] and "n_steps 1024 not among [256, 512]" in logged[0]


def test_a_resumed_study_draws_new_trials_and_the_same_state_draws_the_same():
    space = {"alpha": Float(0.05, 1.0), "tiles": Int(4, 12)}

    def run_once(study, seed):  # one trial per run, as a study resumed across sessions
        study.sampler = tuning.make_sampler("tpe", seed, held=len(study.trials))
        trial = study.ask()
        study.tell(trial, tuning.suggest(trial, space)["alpha"])

    study, twin = optuna.create_study(), optuna.create_study()
    for _ in range(4):
        run_once(study, 0), run_once(twin, 0)
    drawn = [tuple(t.params.values()) for t in study.trials]
    assert len(set(drawn)) == 4  # seeded as the first run, each run drew that run's trial
    assert drawn == [tuple(t.params.values()) for t in twin.trials]
    other = optuna.create_study()
    run_once(other, 1)  # --seed 1 on a new study: not --seed 0 resumed after one trial
    assert tuple(other.trials[0].params.values()) not in drawn[:2]
    assert tuning.make_sampler("random", None, held=3) is not None  # unseeded: no offset


def test_a_failed_trial_does_not_leave_the_study_short_and_a_resume_keeps_its_budget(
        write_suite, tmp_path, monkeypatch):
    # Optuna counts a failed trial against n_trials; the study must still end with 3
    suite = load_suite(write_suite(SUITE), registries())
    tgt = tuning.target(suite, "sarsa-state", None, registries())
    calls = []

    def value(directory, objective, cell_ids):  # the first trial's cells fail, not the rest
        calls.append(directory)
        if len(calls) == 1:
            raise RuntimeError("1 of the trial's cells failed")
        return -100.0 - len(calls)

    monkeypatch.setattr(tuning, "run_processes", lambda *args: None)
    monkeypatch.setattr(tuning, "objective_value", value)
    storage = optuna.storages.InMemoryStorage()

    def run(name, trials, seeds=1, pruner="none"):
        return tuning.run_study(tgt, trials=trials, seeds=seeds, objective="auc",
                                storage=storage, study_name=name, sampler="random", seed=0,
                                pruner=tuning.make_pruner(pruner, tgt), results_root=tmp_path,
                                workers=1, regs=registries(), log=lambda message: None)

    study = run("s", 3)
    states = [t.state.name for t in study.trials]
    assert states == ["FAIL", "COMPLETE", "COMPLETE", "COMPLETE"]
    # resumed with another budget per trial: refused, nothing run
    for seeds, pruner, what in ((2, "none", "seeds 1, not 2"),
                                (1, "median", "pruner NopPruner, not MedianPruner")):
        with pytest.raises(tuning.SuiteError, match=what):
            run("s", 4, seeds, pruner)
    assert len(study.trials) == 4

    def always_fails(*args):
        raise RuntimeError("every trial fails")

    monkeypatch.setattr(tuning, "objective_value", always_fails)
    study = run("t", 2)
    assert [t.state.name for t in study.trials] == ["FAIL", "FAIL"]  # gives up, no loop


def test_a_sen_trial_trains_its_encoder_on_the_tuning_seed_and_an_older_study_is_kept(
        write_suite, tmp_path):
    tgt = tuning.target(load_suite(write_suite(SEN), registries()), "sen-sarsa", None,
                        registries())
    assert tgt.template.encoder["seed"] == 0  # what the suite reports with
    cells = tuning.trial_cells(tgt, {"alpha": 0.5, "encoder.batch_norm": True}, 2,
                               registries())
    assert {c.encoder["seed"] for c in cells} == {tuning.TUNE_SEED_OFFSET}
    assert {c.seed for c in cells} == {tuning.TUNE_SEED_OFFSET, tuning.TUNE_SEED_OFFSET + 1}
    # a study whose trials ran on the suite's encoder seed is not resumed on another
    storage = optuna.storages.InMemoryStorage()
    older = optuna.create_study(study_name="s", storage=storage, direction="maximize")
    older.tell(older.ask(), -150.0)
    with pytest.raises(tuning.SuiteError, match="encoder_seed 0, not 1000000"):
        tuning.run_study(tgt, trials=2, seeds=1, objective="auc", storage=storage,
                         study_name="s", sampler="random", seed=0,
                         pruner=tuning.make_pruner("none", tgt), results_root=tmp_path,
                         workers=1, regs=registries(), log=lambda message: None)


@pytest.mark.slow
def test_a_time_limit_stops_between_trials_and_a_rerun_goes_on(tmp_path):
    (tmp_path / "s.yaml").write_text(SUITE)
    bad = tune(tmp_path, "--trials", "3", "--time-limit", "soon")
    assert bad.returncode != 0 and "write it as 2h30m" in bad.stderr + bad.stdout
    assert not (tmp_path / "results" / "tiny" / "tune.db").exists()  # nothing stored
    assert tune(tmp_path, "--trials", "1").returncode == 0  # a trial takes seconds
    # the next is not expected to end within 1 s of the start: none starts
    done = tune(tmp_path, "--trials", "3", "--time-limit", "1s")
    assert done.returncode == 75, done.stderr
    assert "holds 1 of 3 trials" in done.stderr and "Run the same command again" in done.stderr
    assert len(study_of(tmp_path).trials) == 1
    done = tune(tmp_path, "--trials", "3")
    assert done.returncode == 0, done.stderr
    assert len(study_of(tmp_path).trials) == 3


def test_a_trial_fits_before_a_deadline_at_the_mean_of_the_finished_ones():
    import time as clock

    study = optuna.create_study(direction="maximize")
    assert tuning.fits(study, None) and tuning.fits(study, clock.monotonic() + 1.0)  # no estimate

    def slow(trial):
        clock.sleep(0.3)
        return 0.0

    study.optimize(slow, n_trials=1)
    assert 0.3 <= tuning.trial_seconds(study) < 1.0
    assert not tuning.fits(study, clock.monotonic() + 0.1)
    assert tuning.fits(study, clock.monotonic() + 5.0)


@pytest.mark.slow
def test_a_killed_trial_is_marked_failed_by_the_next_process(tmp_path, monkeypatch):
    from senbench.tune import optuna_parts

    monkeypatch.setattr(optuna_parts, "HEARTBEAT_S", 1)
    monkeypatch.setattr(optuna_parts, "GRACE_S", 2)
    storage = tuning.storage_for(None, tmp_path / "tune.db")
    study = optuna.create_study(study_name="s", storage=storage)
    orphan = study.ask()  # a process that started this trial and was then killed
    storage.record_heartbeat(orphan._trial_id)
    time.sleep(3)
    study.optimize(lambda trial: 0.0, n_trials=1)
    assert study.trials[0].state == optuna.trial.TrialState.FAIL


@pytest.mark.slow
def test_an_encoder_setting_is_tuned_with_the_agent_and_exported_in_its_block(tmp_path):
    import json

    (tmp_path / "s.yaml").write_text(SEN)
    tgt = tuning.target(load_suite(tmp_path / "s.yaml", registries()), "sen-sarsa", None,
                        registries())
    assert set(tgt.space) == {"alpha", "encoder.batch_norm"}  # widths, hidden fixed
    env = {**os.environ, "COLUMNS": "200"}
    done = subprocess.run([sys.executable, "-m", "senbench", "tune", str(tmp_path / "s.yaml"),
                           "--method", "sen-sarsa", "--seeds", "1", "--trials", "2",
                           "--sampler", "random", "--seed", "3", "--results",
                           str(tmp_path / "results"), "--export", str(tmp_path / "b.yaml")],
                          capture_output=True, text=True, env=env)
    assert done.returncode == 0, done.stderr
    study = optuna.load_study(study_name="sen-sarsa-mountaincar-auc",
                              storage=f"sqlite:///{tmp_path / 'results' / 'sen' / 'tune.db'}")
    norms = {t.params["encoder.batch_norm"] for t in study.trials}
    encoders = [p for p in (tmp_path / "results" / "encoders").iterdir() if p.is_dir()]
    assert len(encoders) == len(norms)  # one encoder per distinct setting
    # on the tuning encoder seed, apart from the encoder a suite reports with (seed 0)
    assert {json.loads((p / "spec.json").read_text())["seed"] for p in encoders} == {
        tuning.TUNE_SEED_OFFSET}
    block = yaml.safe_load((tmp_path / "b.yaml").read_text())["sen-sarsa"]
    assert block["encoder"]["config"]["batch_norm"] == study.best_trial.params[
        "encoder.batch_norm"]
    assert block["encoder"]["config"]["widths"] == [8, 8, 16, 16]
    assert "encoder.batch_norm" not in block["hyperparams"]
    assert 0.3 <= block["hyperparams"]["alpha"] <= 0.8  # sarsa's own 1.0 moved into the range


@pytest.mark.slow
def test_every_method_is_tuned_with_the_same_budget_and_exported_together(tmp_path):
    (tmp_path / "s.yaml").write_text(TWO)
    env = {**os.environ, "COLUMNS": "200"}
    done = subprocess.run([sys.executable, "-m", "senbench", "tune", str(tmp_path / "s.yaml"),
                           "--method", "sarsa-state", "--method", "sarsa-small", "--trials",
                           "2", "--seeds", "1", "--seed", "0", "--results",
                           str(tmp_path / "results"), "--export", str(tmp_path / "b.yaml")],
                          capture_output=True, text=True, env=env)
    assert done.returncode == 0, done.stderr
    budget = done.stdout.split("tuning budget", 1)[1]
    for name in ("sarsa-state-mountaincar-auc", "sarsa-small-mountaincar-auc"):
        assert len(optuna.load_study(study_name=name, storage=f"sqlite:///"
                                     f"{tmp_path / 'results' / 'two' / 'tune.db'}").trials) == 2
        row = next(line for line in budget.splitlines() if name in line)
        assert row.count("2,000") == 2  # frames spent = the cap: 2 trials x 1 seed x 1,000
    blocks = yaml.safe_load((tmp_path / "b.yaml").read_text())
    assert set(blocks) == {"sarsa-state", "sarsa-small"}
    assert blocks["sarsa-small"]["hyperparams"]["tilings"] == 4
    assert (tmp_path / "b.yaml").read_text().count("# senbench tune: study") == 2


def test_train_return_ranks_trials_whose_evaluations_all_score_the_same(tmp_path):
    """Two trials whose greedy evaluations are all -1,000 tie on auc; the mean return of
    their training episodes tells them apart. A trial with no training episode has none."""
    import json

    from senbench.results.store import write_cell

    def trial(name, episode_returns):
        directory = tmp_path / name / "cells"
        directory.mkdir(parents=True)
        ids = []
        for seed, returns in enumerate(episode_returns):
            cell_id = f"{name}{seed:015d}"
            ids.append(cell_id)
            common = {"cell_id": cell_id, "suite": name, "env": "mountaincar", "method": "m",
                      "variant": "", "seed": seed, "threshold": -110.0, "budget": 2000}
            rows = [{**common, "kind": "eval", "step": step, "return": -1000.0}
                    for step in (0, 1000, 2000)]
            rows += [{**common, "kind": "episode", "step": 100 * (i + 1), "return": r}
                     for i, r in enumerate(returns)]
            rows.append({**common, "kind": "cell", "status": "ok", "cell_wall_s": 1.0})
            write_cell(directory, cell_id, rows)
        (tmp_path / name / "cells.json").write_text(json.dumps({"cells": ids}))
        return tmp_path / name

    def value(directory, objective):
        return tuning.objective_value(directory, objective,
                                      [f"{directory.name}{seed:015d}" for seed in (0, 1)])

    stuck = trial("stuck", [[-1000.0, -1000.0], [-1000.0]])
    learning = trial("learning", [[-1000.0, -300.0], [-200.0, -400.0]])
    assert value(stuck, "auc") == value(learning, "auc")
    assert value(stuck, "train-return") == -1000.0
    assert value(learning, "train-return") == (-650.0 + -300.0) / 2
    with pytest.raises(RuntimeError, match="no seed of the trial has a train-return"):
        value(trial("none", [[], []]), "train-return")
    # only the trial's own cells count: another trial's file left in the folder does not
    (stuck / "cells.json").unlink()  # a trial's folder has no cell list
    for other in (learning / "cells").glob("*.parquet"):
        (stuck / "cells" / other.name).write_bytes(other.read_bytes())
    assert value(stuck, "train-return") == -1000.0
    with pytest.raises(RuntimeError, match="1 of the trial's 3 cells have no result"):
        tuning.objective_value(stuck, "auc", ["stuck" + "0" * 15, "stuck" + "1".zfill(15),
                                              "gone"])
