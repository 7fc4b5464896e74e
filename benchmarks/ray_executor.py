"""What running on Ray costs on one machine: the same grid with the local executor (2 worker
processes) and with --executor ray (a local instance of 2 CPUs), side by side.

Ray's time is given with and without starting the instance, which a run on an existing
cluster does not pay. Run: .venv/bin/python benchmarks/ray_executor.py
"""

from __future__ import annotations

import tempfile
import textwrap
import time
from pathlib import Path

import ray

from senbench.plugin.manager import registries
from senbench.run.runner import run_suite
from senbench.suite import load_suite

GRID = textwrap.dedent("""\
    name: executors
    envs:
      pendulum: {}
    methods:
      ppo-state: {agent: ppo}
    seeds: 4
    budget: 24576
    eval: {every: 8192, episodes: 2}
""")


def grid_seconds(**how) -> float:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "grid.yaml"
        path.write_text(GRID)
        suite = load_suite(path, registries())
        start = time.perf_counter()
        summary = run_suite(suite, Path(tmp) / "results", **how)
        assert summary.ok == len(suite.cells), summary.failed
        return time.perf_counter() - start


def main() -> None:
    local = grid_seconds(workers=2)
    start = time.perf_counter()
    ray.init(address="local", num_cpus=2, include_dashboard=False, log_to_driver=False)
    startup = time.perf_counter() - start
    try:
        warm = grid_seconds(executor="ray")
    finally:
        ray.shutdown()
    cold = grid_seconds(executor="ray", workers=2)  # starts and stops its own instance
    print(f"grid of 4 ppo-state cells x 24k frames, 2 CPUs: local {local:.1f} s; ray on a "
          f"running instance {warm:.1f} s ({warm / local:.2f}x); ray starting its own "
          f"{cold:.1f} s ({cold / local:.2f}x); ray.init alone {startup:.1f} s")


if __name__ == "__main__":
    main()
