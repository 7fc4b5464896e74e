"""Positive controls and charged frames: a suite states a published reference, the report
puts our number beside it with a verdict, and encoded methods are charged their labelled
frames."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from suites_for_tests import SEN_SARSA

from senbench.analysis.compare import Side, compare
from senbench.analysis.summary import per_cell, summarize
from senbench.errors import SuiteError
from senbench.plugin.manager import registries
from senbench.results.store import read_results
from senbench.run.runner import run_suite
from senbench.suite import load_suite

ROOT = Path(__file__).resolve().parent.parent


def cells_frame(finals: list[float], reference: dict | None, labelled: int = 0) -> pd.DataFrame:
    return pd.DataFrame({"final_return": finals, "status": "ok", "reference": [reference] * len(
        finals), "labelled_frames": labelled})


def test_a_control_fails_only_when_our_interval_lies_below_the_reference():
    from senbench.analysis.summary import _control

    reference = {"value": -100.0, "spread": 10.0, "source": "a table"}
    assert _control(cells_frame([-101, -99, -104, -98, -102], reference), reference)[
        "control"] == "pass"
    assert _control(cells_frame([-90, -92, -95, -91, -93], reference), reference)[
        "control"] == "pass"  # better than published: the code path works
    failing = _control(cells_frame([-150, -160, -155, -170, -158], reference), reference)
    assert failing["control"] == "fail" and failing["reference"] == -100.0
    assert _control(cells_frame([], reference), reference)["control"] == "no finished seed"
    assert _control(cells_frame([-120], None), None)["control"] == ""


def test_references_name_methods_and_envs_of_the_suite(write_suite):
    text = (ROOT / "suites" / "controls-state.yaml").read_text()
    load_suite(write_suite(text), registries())  # the shipped control suite is valid
    bad = text.replace("  ppo-state:\n    pendulum:", "  ppo-stat:\n    pendulm:")
    with pytest.raises(SuiteError, match="references.ppo-stat: unknown method"):
        load_suite(write_suite(bad), registries())
    bad = text.replace("  ppo-state:\n    pendulum:", "  ppo-state:\n    pendulm:")
    with pytest.raises(SuiteError, match="references.ppo-state.pendulm: unknown suite env"):
        load_suite(write_suite(bad), registries())
    bad = text.replace('source: "rl-baselines3-zoo benchmark.md, ppo', 'sauce: "x')
    with pytest.raises(SuiteError, match="source"):
        load_suite(write_suite(bad), registries())


def test_an_encoded_cell_records_its_labelled_frames_and_how_they_were_obtained(write_suite):
    suite = load_suite(write_suite(
        "name: s\nenvs:\n  mountaincar: {}\nmethods:\n" + SEN_SARSA
        + "  sarsa-state: {agent: sarsa}\nseeds: 1\nbudget: 600\neval: {every: 300}\n"),
        registries())
    sen = next(c for c in suite.cells if c.method == "sen-sarsa")
    state = next(c for c in suite.cells if c.method == "sarsa-state")
    assert (sen.labelled_frames, sen.labelled_by) == (300, "states set by hand, uniform in "
                                                           "the bounds")
    assert sen.config()["labelled"] == {"frames": 300, "by": sen.labelled_by}
    assert state.labelled_frames == 0 and "labelled" not in state.config()
    assert sen.id == sen.replace(labelled_frames=1).id  # a label: not in the id


def test_compare_charges_labelled_frames_only_where_some_were_used():
    def side(name, steps, labelled):
        return Side(name, pd.DataFrame({
            "final_return": [-110.0, -120.0, -115.0], "auc": [-130.0, -140.0, -135.0],
            "steps_to_threshold": steps, "reached": [True] * 3, "labelled_frames": labelled,
            "charged_frames": [s + labelled for s in steps]}))

    sen, rival = side("sen", [1000.0, 2000.0, 3000.0], 10_000), side("px", [9000.0] * 3, 0)
    table = compare(sen, rival).set_index("metric")
    assert table.loc["steps", "p_better"] == 1.0  # fewer online frames
    assert table.loc["charged", "p_better"] == 0.0  # but more with the labelled ones
    assert "charged" not in set(compare(rival, rival)["metric"])


@pytest.mark.slow
def test_the_control_suite_runs_and_reports_our_number_beside_the_reference(tmp_path):
    text = yaml.safe_load((ROOT / "suites" / "controls-state.yaml").read_text())
    text.update(seeds=1, budget=1500, eval={"every": 500, "episodes": 1})
    text["envs"] = {"mountaincar": {"budget": 1500}, "pendulum": {"budget": 1024}}
    del text["methods"]["ddqn-state"], text["references"]["ddqn-state"]
    suite_file = tmp_path / "controls.yaml"
    suite_file.write_text(yaml.safe_dump(text))
    summary = run_suite(load_suite(suite_file, registries()), tmp_path / "r", workers=2)
    assert not summary.failed
    results = read_results(tmp_path / "r" / "controls-state")
    table = summarize(results).set_index("method")
    assert table.loc["dqn-state", "reference"] == -100.849
    assert table.loc["dqn-state", "control"] == "fail"  # 1,500 frames cannot reach -100.8
    assert table.loc["ppo-state", "reference_source"].startswith("rl-baselines3-zoo")
    assert set(per_cell(results)["labelled_frames"]) == {0}


def test_curves_can_start_an_encoded_method_at_its_labelled_frames():
    import json

    from senbench.cli.plots import learning_curves

    rows = []
    for method, labelled in (("sen", 500), ("px", 0)):
        config = json.dumps({"labelled": {"frames": labelled, "by": "x"}} if labelled else {})
        for seed in (0, 1):
            cell = f"{method}{seed}"
            rows.append(dict(suite="s", cell_id=cell, env="e", method=method, variant="",
                             seed=seed, kind="cell", step=2000, status="ok", config=config))
            rows += [dict(suite="s", cell_id=cell, env="e", method=method, variant="",
                          seed=seed, kind="eval", step=step, status=None, config=config,
                          **{"return": -float(step)}) for step in (0, 1000, 2000)]
    results = pd.DataFrame(rows)
    plain = learning_curves(results)["e"]
    charged = learning_curves(results, charge_labelled=True)["e"]
    assert list(plain["sen"].columns) == [0, 1000, 2000]
    assert list(charged["sen (+500 labelled)"].columns) == [500, 1500, 2500]
    assert list(charged["px"].columns) == [0, 1000, 2000]


def test_the_bars_envs_draw_each_observation_dimension_as_a_bar():
    regs = registries()
    bars, scene = regs.envs.get("mountaincar-bars"), regs.envs.get("mountaincar")
    assert (bars.threshold, bars.state_low, bars.make) == (scene.threshold, scene.state_low,
                                                           scene.make)
    frames = bars.render(np.array([[-1.2, 0.07], [0.6, -0.07], [-0.3, 0.0]]), (16, 20))
    assert frames.shape == (3, 16, 20) and frames.dtype == np.uint8
    position, velocity = frames[:, 0, :], frames[:, 8, :]  # a row of each band
    assert not position[0].any() and (position[1] == 255).all()  # low: empty; high: full
    assert (velocity[0] == 255).all() and not velocity[1].any()
    assert (position[2, :10] == 255).all() and not position[2, 11:].any()  # half way
    assert not frames[:, 7, :].any()  # a blank row between bands
    pendulum = regs.envs.get("pendulum-bars").render(np.array([[0.0, 8.0]]), (30, 10))
    # (cos, sin, θ̇) = (1, 0, 8): full, half, full
    assert (pendulum[0, 0] == 255).all() and (pendulum[0, 10, :5] == 255).all()
    assert not pendulum[0, 10, 6:].any() and (pendulum[0, 20] == 255).all()


PIXEL_CONTROLS = sorted(p for p in (ROOT / "suites").glob("controls-*.yaml")
                        if p.stem != "controls-state")  # which has its own twin above


@pytest.mark.slow
@pytest.mark.parametrize("path", PIXEL_CONTROLS, ids=lambda p: p.stem)
def test_each_control_suite_runs_every_learner_end_to_end_in_a_quick_twin(path, tmp_path):
    """The committed control suite, one seed, a few hundred frames and short episodes:
    every method's pipeline (frames, CNN, replay or rollouts, evaluation, the policy's
    action record) runs, and the report reads it, references included."""
    text = yaml.safe_load(path.read_text())
    text.update(seeds=1, budget=600, eval={**text["eval"], "every": 300, "episodes": 1})
    text["envs"] = {env: {"max_episode_steps": 100} for env in text["envs"]}
    suite_file = tmp_path / path.name
    suite_file.write_text(yaml.safe_dump(text))
    suite = load_suite(suite_file, registries())
    summary = run_suite(suite, tmp_path / "r", workers=2)
    assert not summary.failed and summary.ok == len(suite.cells)
    results = read_results(tmp_path / "r" / suite.name)
    evals = results[results["kind"] == "eval"]
    assert len(evals) == 3 * len(suite.cells)  # at 0, 300 and 600 frames
    recorded = evals["action_share"].notna() | evals["action_mean"].notna()
    assert recorded.all()
    table = summarize(results)
    assert len(table) == len({(c.env, c.method) for c in suite.cells})
    for method, envs in text.get("references", {}).items():
        for env, ref in envs.items():
            row = table[(table["method"] == method) & (table["env"] == env)]
            assert row["reference"].item() == ref["value"]


def test_sarsas_state_control_is_held_to_the_solved_return_gymnasium_registers():
    """Tile-coded SARSA has no published agent number (the zoo has no SARSA; Sutton & Barto
    publish plots): its reference is MountainCar-v0's own reward_threshold, read from
    gymnasium, not copied by hand."""
    import gymnasium

    refs = yaml.safe_load((ROOT / "suites" / "controls-state.yaml").read_text())["references"]
    solved = gymnasium.spec("MountainCar-v0").reward_threshold
    for method in ("sarsa-state", "sarsa-book"):
        assert refs[method]["mountaincar"]["value"] == solved == -110.0
        assert "reward_threshold" in refs[method]["mountaincar"]["source"]
