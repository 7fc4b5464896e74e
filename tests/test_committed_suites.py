"""Every suite the project ships loads and validates with today's code: a change to the
schema, a plugin's settings or its capability checks that would break a committed suite
(a paper suite, a control, a tuned suite pasted from `senbench tune --export`) fails here
rather than hours into a run."""

from pathlib import Path

import pytest

from senbench.plugin.manager import registries
from senbench.suite import expand, load_suite

ROOT = Path(__file__).resolve().parents[1]
SUITES = sorted((ROOT / "suites").glob("*.yaml"))
RESULTS = ROOT / "results"


def test_the_project_ships_suites():
    assert len(SUITES) >= 20  # the paper, controls, tuning, precision and quick suites


@pytest.mark.parametrize("path", SUITES, ids=lambda p: p.stem)
def test_a_committed_suite_validates(path, monkeypatch):
    # bf16 suites validate only where the CPU has bf16 instructions, and the machines this
    # runs on differ (tests/test_precision.py checks the refusal): the suite is what is
    # tested here, not the machine
    monkeypatch.setattr(expand, "bf16_native", lambda: True)
    suite = load_suite(path, registries())
    assert suite.name == path.stem  # its results go under results/<file name>
    assert suite.cells


RUN_SUITES = [p for p in SUITES if any((RESULTS / p.stem / "cells").glob("*.parquet"))
              and not p.stem.startswith("tune-")]  # a study's cells run on tuning seeds


def test_some_committed_suites_have_results():
    assert len(RUN_SUITES) >= 6  # the paper suites and the controls


@pytest.mark.parametrize("path", RUN_SUITES, ids=lambda p: p.stem)
def test_every_committed_result_is_a_cell_of_its_suite_today(path):
    # A cell's id hashes what it computes; a change that moved it (a new agent setting
    # left in the id at its default, say) would orphan the committed results: `run` would
    # compute them again and `report` would not find them.
    ids = {cell.id for cell in load_suite(path, registries()).cells}
    committed = {p.stem for p in (RESULTS / path.stem / "cells").glob("*.parquet")}
    assert committed <= ids, sorted(committed - ids)
