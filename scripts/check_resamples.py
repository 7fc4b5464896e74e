"""Do REPRODUCTION.md's P(A better) verdicts depend on the bootstrap's resample count?

senbench's intervals use 2,000 resamples (senbench.analysis.stats.RESAMPLES); rliable's
default is 50,000. For every comparison REPRODUCTION.md quotes (the `senbench compare`
commands there), this recomputes each metric's 95% interval of P(A better) with both and
prints those whose side of 0.5 differs ("flips"; an interval that includes 0.5 is called
inconclusive) or whose bounds move by more than 0.05.

    .venv/bin/python scripts/check_resamples.py          (≈ 1 min)
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from senbench.analysis import stats
from senbench.analysis.compare import pairs_in_one_folder
from senbench.analysis.summary import METRICS, parse_thresholds

COMPARISONS = [  # (results folder, A, B, thresholds), as REPRODUCTION.md's commands
    ("paper-mountaincar", "sen-sarsa", "sarsa-state", []),
    ("paper-mountaincar", "sen-sarsa", "sarsa-state", ["-130"]),
    ("paper-mountaincar", "sen-sarsa", "ddqn-pixels", []),
    ("paper-mountaincar", "sen-sarsa", "dqn-pixels", []),
    *[("paper-mountaincar-d", f"sen-sarsa [encoder.fraction={a}]",
       f"sen-sarsa [encoder.fraction={b}]", [])
      for a, b in (("1.0", "0.2"), ("1.0", "0.5"), ("0.5", "0.2"), ("0.1", "0.2"),
                   ("0.1", "0.02"), ("0.02", "0.2"))],
    ("paper-mountaincar-plus", "sen-sarsa", "drq-pixels-repeat", []),
    ("paper-pendulum", "sen-ppo", "ppo-state", []),
    ("paper-pendulum", "sen-ppo", "ppo-pixels", []),
    ("paper-pendulum-scaled", "sen-ppo", "ppo-pixels-scaled", []),
    ("paper-pendulum-d", "sen-ppo [encoder.fraction=0.02]", "sen-ppo [encoder.fraction=0.2]",
     []),
    ("paper-pendulum-d", "sen-ppo [encoder.fraction=0.02]", "sen-ppo [encoder.fraction=1.0]",
     []),
    ("paper-pendulum-tuned", "sen-ppo", "ppo-state", []),
    ("paper-pendulum-tuned", "sen-ppo", "ppo-pixels", []),
    ("paper-pendulum-plus", "sen-sac", "drq-sac-pixels", []),
    ("paper-pendulum-plus", "sen-sac", "sac-pixels", []),
    ("paper-pendulum-plus", "drq-sac-pixels", "sac-pixels", []),
    ("drq-sac-buffer", "drq-sac-pixels-buffer-200k", "drq-sac-pixels-buffer-100k", []),
]


def interval(prefix: str, a, b, higher_is_better: bool, resamples: int) -> tuple[float, float]:
    column = METRICS[prefix][0]
    x, y = a[column].to_numpy(float), b[column].to_numpy(float)
    if prefix == "charged":
        return stats.censored_improvement_ci(x, ~a["reached"].to_numpy(bool), y,
                                             ~b["reached"].to_numpy(bool), resamples=resamples)
    sign = 1.0 if higher_is_better else -1.0
    return stats.improvement_ci(sign * x, sign * y, resamples=resamples)


def main(results: Path = Path("results")) -> None:
    checked = flips = 0
    for folder, a, b, thresholds in COMPARISONS:
        for _env, side_a, side_b in pairs_in_one_folder(results / folder, a, b,
                                                       thresholds=parse_thresholds(thresholds)):
            for prefix, (_, higher_is_better) in METRICS.items():
                few, many = (interval(prefix, side_a.cells, side_b.cells, higher_is_better, n)
                             for n in (stats.RESAMPLES, 50_000))
                if np.isnan(few[0]):
                    continue
                checked += 1
                flip = (few[0] <= 0.5 <= few[1]) != (many[0] <= 0.5 <= many[1])
                flips += flip
                if flip or max(abs(few[0] - many[0]), abs(few[1] - many[1])) > 0.05:
                    print(f"{'flips ' if flip else 'moves '}{folder}: {a} vs {b} {thresholds} "
                          f"{prefix}: [{few[0]:.2f}, {few[1]:.2f}] at {stats.RESAMPLES:,}, "
                          f"[{many[0]:.2f}, {many[1]:.2f}] at 50,000")
    print(f"{checked} intervals, {flips} on another side of 0.5 at 50,000 resamples")


if __name__ == "__main__":
    main()
