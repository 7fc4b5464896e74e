"""``senbench tune --export``: the best trial of each study as a suite ``methods:`` block."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from senbench.results.outputs import written_whole
from senbench.tune.study import ENCODER, Target, default_params, moved_defaults


def best_block(study: Any, tgt: Target) -> dict[str, Any]:
    """The method's suite entry with the best trial's hyperparameters: a ``methods:`` block
    a suite uses unchanged. Where the best trial is the defaults trial and it ran the
    method's own settings (PPO's ent_coef 0.0 tried as the log range's 1e-8 counts as
    such; a default moved into a narrowed range does not), the entry is the method's own,
    as the suite has it, so its cells are the untuned suite's computation and
    ``run --reuse`` can copy them."""
    entry = tgt.suite.model.methods[tgt.method].model_dump(exclude_unset=True)
    if own_settings_won(study, tgt):
        return {tgt.method: entry}
    best = _plain(study.best_trial.params)
    entry["hyperparams"] = {**tgt.fixed,
                            **{k: v for k, v in best.items() if not k.startswith(ENCODER)}}
    tuned = {k[len(ENCODER):]: v for k, v in best.items() if k.startswith(ENCODER)}
    if tuned:
        entry["encoder"]["config"] = {**entry["encoder"].get("config", {}), **tuned}
    return {tgt.method: entry}


def export_best(studies: list[tuple[Any, Target]], path: Path, *, objective: str,
                seeds: int) -> None:
    """Write each study's :func:`best_block` to ``path`` (a ``--export`` .yaml file) whole,
    headed by a comment naming each study, its best trial and its objective value."""
    import yaml

    blocks: dict[str, Any] = {}
    head = []
    for study, tgt in studies:
        blocks.update(best_block(study, tgt))
        best = study.best_trial
        own = (" (the defaults: the method's own settings, unchanged)"
               if own_settings_won(study, tgt) else "")
        head.append(f"# senbench tune: study '{study.study_name}', trial {best.number}{own}, "
                    f"{objective} {best.value:,.2f} over {seeds} seeds\n")
        tied = [t.number for t in study.trials if t.number != best.number
                and t.state.name == "COMPLETE" and t.value == best.value]
        if tied:  # which of them Optuna returns says nothing of the settings
            head.append(f"#   tied with trial{'s' if len(tied) > 1 else ''} "
                        f"{', '.join(map(str, tied))}: the study did not rank them\n")
    text = yaml.safe_dump(blocks, sort_keys=False)
    with written_whole(path, "--export") as tmp:
        tmp.write_text("".join(head) + text)


def own_settings_won(study: Any, tgt: Target) -> bool:
    """Whether the best trial ran the method's own settings as they are today: the defaults
    trial, none of them moved into the searched range, and its parameters the ones the
    method has now (an agent's defaults changed since would make them another method's)."""
    best = study.best_trial
    return (bool(best.user_attrs.get("defaults")) and not moved_defaults(tgt)
            and best.params == default_params(tgt)[0])


def _plain(values: dict[str, Any]) -> dict[str, Any]:
    """numpy scalars → Python numbers, so that safe_dump writes plain YAML."""
    return {k: (v.item() if hasattr(v, "item") else v) for k, v in values.items()}
