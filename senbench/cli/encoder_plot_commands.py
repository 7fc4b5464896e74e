"""``senbench encoder ...`` and ``senbench plot ...``: the sub-commands of encoders and
figures."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.markup import escape

from senbench.cli.common import FIGURE_HELP, Threshold, err, out, user_errors
from senbench.encoders.request import EncoderRequest, Training
from senbench.errors import ResultsError, SenbenchError
from senbench.results.outputs import FIGURES, check_out_file

encoder_app = typer.Typer(help="State encoders: train, inspect.", no_args_is_help=True)
plot_app = typer.Typer(help="PNG figures.", no_args_is_help=True)


@encoder_app.command("train")
@user_errors
def encoder_train(
    env: Annotated[str, typer.Option(help="Env plugin.")],
    arch: Annotated[str, typer.Option(help="Encoder architecture.")] = EncoderRequest.arch,
    sampler: Annotated[str, typer.Option(help="Sampler of labelled frames.")
                       ] = EncoderRequest.sampler,
    samples: Annotated[int, typer.Option(min=10, help="Labelled pairs in the pool.")
                       ] = EncoderRequest.samples,
    fraction: Annotated[float, typer.Option(min=0.0001, max=1.0,
                                            help="Share of the pool trained on (d).")
                        ] = EncoderRequest.fraction,
    seed: Annotated[int, typer.Option(min=0)] = EncoderRequest.seed,
    epochs: Annotated[int, typer.Option(min=1)] = Training.epochs,
    batch_size: Annotated[int, typer.Option(min=2)] = Training.batch_size,
    learning_rate: Annotated[float, typer.Option(min=0.0)] = Training.learning_rate,
    patience: Annotated[int, typer.Option(min=1)] = Training.patience,
    test_samples: Annotated[int, typer.Option(min=10)] = Training.test_samples,
    height: Annotated[int, typer.Option(min=8, max=512)] = 64,
    width: Annotated[int, typer.Option(min=8, max=512)] = 64,
    stack: Annotated[int, typer.Option(min=1, max=16)] = 2,
    cache: Annotated[Path, typer.Option(help="Encoder cache.")] = Path("results/encoders"),
    threads: Annotated[int | None, typer.Option(min=1, help="torch threads training runs on "
                                                "(default 2); the weights depend on it, so "
                                                "another count names another encoder.")]
    = None,
    arch_config: Annotated[list[str] | None, typer.Option(
        metavar="KEY=VALUE", help="A setting of the architecture's config, as a suite's "
        "encoder.config sets it (repeat for several); VALUE is read as YAML: 32, true, "
        "[16, 32].")] = None,
    sampler_config: Annotated[list[str] | None, typer.Option(
        metavar="KEY=VALUE", help="A setting of the sampler's config, as a suite's "
        "encoder.sampler_config sets it (repeat for several).")] = None,
) -> None:
    """Train a state encoder (or load it if this spec was trained before) and print its
    held-out error per dimension."""
    import pandas as pd

    from senbench.cli.tables import show_encoder
    from senbench.encoders import TRAINING_THREADS, cache_dir, complete, load_or_train
    from senbench.observe.pixels import PixelSpec
    from senbench.plugin.manager import registries
    regs = registries()
    regs.envs.get(env), regs.encoders.get(arch), regs.samplers.get(sampler)
    if not learning_rate > 0:
        raise SenbenchError(f"--learning-rate must be above 0, got {learning_rate}")
    configs = checked_configs(regs, arch, sampler, arch_config or [], sampler_config or [])
    spec = regs.encoders.get(arch)  # as a suite's validation checks it, before any sampling
    smallest = spec.min_frame_size_for(spec.config(**configs["arch_config"]))
    if smallest and min(height, width) < smallest:
        raise SenbenchError(f"encoder '{arch}' needs frames of at least {smallest}x{smallest}, "
                            f"got {height}x{width}; pass --height {max(height, smallest)} "
                            f"--width {max(width, smallest)} or more, or another --arch")
    request = EncoderRequest(
        env=env, pixels=PixelSpec(height, width, stack), arch=arch, sampler=sampler,
        samples=samples, fraction=fraction, seed=seed, **configs,
        training=Training(epochs=epochs, batch_size=batch_size, learning_rate=learning_rate,
                          patience=patience, test_samples=test_samples,
                          threads=threads or TRAINING_THREADS))
    request = complete(request, regs)
    load_or_train(cache, request, regs, err.print)
    folder = cache_dir(cache, request)
    show_encoder(pd.read_parquet(folder / "metrics.parquet"),
                   f"{env}: {arch}, {request.train_size} of {samples} {sampler} samples "
                   f"(d = {100 * fraction:g}%), held-out RMSE on {test_samples}", out)
    out.print(f"encoder {request.id} → {folder}")


def checked_configs(regs, arch: str, sampler: str, arch_settings: list[str],
                    sampler_settings: list[str]) -> dict:
    """``arch_config`` and ``sampler_config`` from KEY=VALUE settings (VALUE read with YAML's
    safe loader), checked against the architecture's and the sampler's config classes as a
    suite's are; every problem reported at once."""
    import yaml

    from senbench.suite.resolve import resolve_encoder

    problems: list[str] = []
    parsed = {}
    for option, settings in (("--arch-config", arch_settings),
                             ("--sampler-config", sampler_settings)):
        parsed[option] = {}
        for setting in settings:
            key, equals, text = setting.partition("=")
            if not equals or not key.strip():
                problems.append(f"{option} {setting!r}: write KEY=VALUE, a field of the "
                                "config and its value")
                continue
            try:
                parsed[option][key.strip()] = yaml.safe_load(text)
            except yaml.YAMLError as exc:
                problems.append(f"{option} {key.strip()}: {text!r} is not a YAML value "
                                f"({exc.problem if hasattr(exc, 'problem') else exc})")
    options = {"config": "--arch-config", "sampler_config": "--sampler-config"}

    def where(key: str, field: str = "") -> tuple[str, ...]:
        return (options.get(key, f"--{key}"), field)

    def problem(loc: tuple[str, ...], message: str) -> None:
        problems.append(f"{' '.join(part for part in loc if part)}: {message}")

    resolved = resolve_encoder({"arch": arch, "sampler": sampler,
                                "config": parsed["--arch-config"],
                                "sampler_config": parsed["--sampler-config"]},
                               regs, where, problem)
    if problems or resolved is None:
        raise SenbenchError("; ".join(problems))
    return {"arch_config": resolved["config"], "sampler_config": resolved["sampler_config"]}


@plot_app.command("curves")
@user_errors
def plot_curves_command(
    results_dir: Annotated[Path, typer.Argument(help="A suite's results folder.")],
    png: Annotated[Path | None, typer.Option(
        "--out", help=FIGURE_HELP + " (default: RESULTS_DIR/curves.png)")] = None,
    all_cells: Annotated[bool, typer.Option(
        "--all", help="Include cells of earlier versions of the suite.")] = False,
    threshold: Threshold = None,
    charge_labelled: Annotated[bool, typer.Option(
        "--charge-labelled", help="Start each encoded method's curve at the labelled frames "
                                  "its encoder was trained on, not at 0.")] = False,
) -> None:
    """Evaluation return against frames, mean and 95% CI band over seeds per method (the
    paper's Figs. 4, 5, 8 and 9)."""
    from senbench.analysis.summary import parse_thresholds, with_thresholds
    from senbench.cli.plots import plot_curves
    from senbench.results.store import read_results

    if png is None:  # its default lies in the results folder, which must be one
        if not results_dir.is_dir():
            raise ResultsError(f"{results_dir}: no such results folder")
        png = results_dir / "curves.png"
    check_out_file(png, FIGURES)
    results = with_thresholds(read_results(results_dir, include_stale=all_cells),
                              parse_thresholds(threshold or []))
    suite = results["suite"].iloc[0]
    envs = plot_curves(results, png, f"{suite}: learning curves"
                       + (", labelled frames charged" if charge_labelled else ""),
                       charge_labelled)
    out.print(f"{escape(str(png))}: {', '.join(envs)}")


@plot_app.command("traces")
@user_errors
def plot_traces_command(
    paths: Annotated[list[Path] | None, typer.Argument(
        help="Encoder folders, or caches holding them.")] = None,
    env: Annotated[str | None, typer.Option(help="Only this env's encoders.")] = None,
    results: Annotated[Path | None, typer.Option(
        help="The encoders a suite's cells used, from its results folder (and the "
        "encoders/ cache beside it).")] = None,
    png: Annotated[Path, typer.Option("--out", help=FIGURE_HELP)] = Path("traces.png"),
    train: Annotated[bool, typer.Option(help="With --results: train the encoders missing "
                                        "from the cache, from the cells' spec.")] = False,
) -> None:
    """Predicted vs true observation along a successful trajectory, one line per encoder
    (the paper's Figs. 6 and 10)."""
    from senbench.cli.plots import encoders_of_results, find_encoders, plot_traces

    check_out_file(png, FIGURES)
    if train and results is None:
        raise SenbenchError("--train trains the encoders of --results DIR: name the folder")
    if results is not None:
        paths = [*(paths or []), *encoders_of_results(
            results, env, train, lambda message: err.print(escape(message), highlight=False))]
    encoders = find_encoders(paths or [Path("results/encoders")], env)
    plot_traces(encoders, png)
    out.print(f"{escape(str(png))}: {len(encoders)} encoders")
