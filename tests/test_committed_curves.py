"""Committed curves still come out of today's code: the first frames of one committed cell
per learner and observation are run again and compared row for row (what `senbench verify`
does). A change that moves what a learner computes without a new CURVE_VERSION fails here,
not in a reader's hands. Each cell's prefix reaches past the learner's first updates and
holds episodes that differ from one another.

Bit for bit only on the processor the cell was computed on (its `cpu` column): another
processor's math kernels round differently and a learner grows that into another curve, so
a cell computed elsewhere, or before the column, is skipped, saying so.

Only cells whose code needs no trained encoder (a fresh clone has none cached): the SEN
methods are checked by `senbench verify` where their encoders are."""

from pathlib import Path

import pandas as pd
import pytest

from senbench.plugin.manager import registries
from senbench.results.store import cell_path
from senbench.run.execute import RunInfo
from senbench.run.provenance import cpu_description
from senbench.run.verify import committed_cpu, verify_cells
from senbench.suite import load_suite

ROOT = Path(__file__).resolve().parents[1]

CELLS = [  # suite, method, env, seed, frames
    ("controls-state", "ddqn-state", "mountaincar", 2, 15000),
    ("controls-state", "ppo-state", "pendulum", 0, 9000),
    ("paper-mountaincar", "sarsa-state", "mountaincar", 0, 6000),
    ("controls-sac", "sac-state", "pendulum", 4, 1500),
    ("controls-pixels", "dqn-pixels", "mountaincar-bars", 1, 11000),
    ("controls-pixels", "ppo-pixels", "pendulum-bars", 1, 5000),
]


@pytest.mark.slow
@pytest.mark.parametrize("suite_name, method, env, seed, frames", CELLS,
                         ids=[f"{c[0]}-{c[1]}-{c[2]}-{c[3]}" for c in CELLS])
def test_a_committed_curve_comes_out_of_todays_code(suite_name, method, env, seed, frames,
                                                    tmp_path):
    suite = load_suite(ROOT / "suites" / f"{suite_name}.yaml", registries())
    [cell] = suite.select([method], [env], [seed])
    folder = ROOT / "results" / suite_name / "cells"
    then = committed_cpu(pd.read_parquet(cell_path(folder, cell.id)))
    now = cpu_description()
    if then != now:
        pytest.skip(f"computed on {then or 'an unrecorded processor'}; this is {now}")
    [verdict] = verify_cells([cell], folder, frames,
                             RunInfo.gather(tmp_path / "encoders"))
    assert verdict.outcome == "same", verdict.detail
    assert verdict.compared >= 8  # episodes and evaluations, not an empty prefix
