"""Every suite the project ships loads and validates with today's code: a change to the
schema, a plugin's settings or its capability checks that would break a committed suite
(a paper suite, a control, a tuned suite pasted from `senbench tune --export`) fails here
rather than hours into a run."""

from pathlib import Path

import pytest

from senbench.plugin.manager import registries
from senbench.suite import load_suite

SUITES = sorted((Path(__file__).resolve().parents[1] / "suites").glob("*.yaml"))


def test_the_project_ships_suites():
    assert len(SUITES) >= 20  # the paper, controls, tuning, precision and quick suites


@pytest.mark.parametrize("path", SUITES, ids=lambda p: p.stem)
def test_a_committed_suite_validates(path):
    suite = load_suite(path, registries())
    assert suite.name == path.stem  # its results go under results/<file name>
    assert suite.cells
