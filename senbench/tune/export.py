"""``senbench tune --export``: the best trial of each study as a suite ``methods:`` block,
each under a comment naming its study; a file that already holds other methods' blocks
keeps them."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from senbench.errors import OutputError
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
    """Write each study's :func:`best_block` to ``path`` (a ``--export`` .yaml file), each
    under a comment naming its study, its best trial and its objective value. The blocks of
    other methods that ``path`` already holds are kept, in their place: a comparison tuned a
    ``--method`` at a time, over several runs, ends in one file; a method tuned again
    replaces its own block. The file is written whole."""
    import yaml

    segments = read_export(path)
    for study, tgt in studies:
        best = study.best_trial
        own = (" (the defaults: the method's own settings, unchanged)"
               if own_settings_won(study, tgt) else "")
        head = (f"# senbench tune: study '{study.study_name}', trial {best.number}{own}, "
                f"{objective} {best.value:,.2f} over {seeds} seeds\n")
        tied = [t.number for t in study.trials if t.number != best.number
                and t.state.name == "COMPLETE" and t.value == best.value]
        if tied:  # which of them Optuna returns says nothing of the settings
            head += (f"#   tied with trial{'s' if len(tied) > 1 else ''} "
                     f"{', '.join(map(str, tied))}: the study did not rank them\n")
        segments[tgt.method] = head + yaml.safe_dump(best_block(study, tgt), sort_keys=False)
    with written_whole(path, "--export") as tmp:
        tmp.write_text("".join(s if s.endswith("\n") else s + "\n"
                               for s in segments.values()))


def read_export(path: Path) -> dict[str, str]:
    """The text of each method's block in an earlier export at ``path`` (none if there is
    no file), with the comments that name its study: keyed by method, in the file's order.
    A comment naming a study goes with the block of the method the study is named after
    (``<method>-<env>-<objective>``; exports written before 2026-12-04 put them all at the
    top); any other line goes with the block it belongs to or precedes. A file that is not
    such an export is refused, before any trial runs."""
    import yaml

    if not path.exists():
        return {}
    try:
        text = path.read_text()
        blocks = yaml.safe_load(text)
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        why = " ".join(str(exc).split())
        raise OutputError(f"--export {path}: cannot read it as an earlier export ({why}); "
                          "name a new file or an earlier export of senbench tune") from None
    if blocks is None:
        return {}
    if not isinstance(blocks, dict) or not all(isinstance(b, dict) for b in blocks.values()):
        raise OutputError(f"--export {path}: holds something other than suite methods: "
                          "blocks, and exporting would replace it; name a new file or an "
                          "earlier export of senbench tune")
    methods = [str(m) for m in blocks]
    parts: dict[str, list[str]] = {m: [] for m in methods}
    studies: dict[str, list[str]] = {m: [] for m in methods}
    pending: list[str] = []
    current, keys = None, iter(methods)
    owner = None  # the method of the study comment being read (its "tied" line follows it)
    for line in text.splitlines(keepends=True):
        named = re.match(r"# senbench tune: study '([^']*)'", line)
        if named:
            owner = max((m for m in methods if named.group(1).startswith(f"{m}-")),
                        key=len, default=None)
        if owner is not None and (named or line.startswith("#   tied")):
            studies[owner].append(line)
            continue
        owner = None
        if re.match(r"[^\s#]", line):  # a top-level key: the next block begins
            current = next(keys, None)
            if current is None:
                raise _not_laid_out(path, line.strip())
            parts[current] += pending + [line]
            pending = []
        elif current is None or line.startswith("#"):
            pending.append(line)
        else:
            parts[current].append(line)
    if pending:
        parts[methods[-1]] += pending
    segments = {m: "".join(studies[m] + parts[m]) for m in methods}
    for method, segment in segments.items():  # each a block of its own, or kept whole
        try:
            alone = yaml.safe_load(segment)
        except yaml.YAMLError:
            alone = None
        if alone != {method: blocks[method]}:
            raise _not_laid_out(path, method)
    return segments


def _not_laid_out(path: Path, where: str) -> OutputError:
    return OutputError(f"--export {path}: '{where}' is not laid out as senbench tune writes "
                       "its blocks (one top-level key a block, no '---'), so the blocks "
                       "cannot be kept beside a new one; name a new file or an earlier "
                       "export of senbench tune")


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
