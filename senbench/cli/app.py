"""The ``senbench`` command line."""

from __future__ import annotations

import signal
import time
from pathlib import Path
from typing import Annotated

import typer
from rich.markup import escape

from senbench.cli.common import (
    FIGURE_HELP,
    PickEnvs,
    PickMethods,
    PickSeeds,
    PickVariants,
    Table,
    Threshold,
    err,
    load_suite_file,
    out,
    user_errors,
)
from senbench.cli.encoder_plot_commands import encoder_app, plot_app
from senbench.cli.verify import verify
from senbench.errors import SenbenchError
from senbench.results.outputs import FIGURES, check_out_file

app = typer.Typer(
    help="Benchmark data-efficient RL from images: state encoders (SEN-DRL) vs pixel RL.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
)
app.add_typer(encoder_app, name="encoder")
app.add_typer(plot_app, name="plot")
app.command()(verify)


@app.command()
@user_errors
def validate(suite_file: Annotated[Path, typer.Argument(help="Suite YAML file.")]) -> None:
    """Check a suite file and show the cells it expands into; runs nothing."""
    suite = load_suite_file(suite_file)
    model = suite.model
    variants = {(c.env, c.method, c.variant) for c in suite.cells}
    out.print(
        f"[green]ok[/]: suite '{suite.name}': {len(suite.cells)} cells = "
        f"{len(variants)} env × method × variant combinations × {len(model.seeds)} seeds"
    )


@app.command()
@user_errors
def status(
    suite_file: Annotated[Path, typer.Argument(help="Suite YAML file.")],
    results: Annotated[Path, typer.Option(help="Results root the suite runs under.")]
    = Path("results"),
    workers: Annotated[int, typer.Option(
        "--workers", "-w", min=1, help="Workers to estimate the wall clock left for.")] = 1,
) -> None:
    """How many cells of a suite have finished, failed or are still to run, and the cell
    time left, at the mean of the finished cells of each env, method and variant."""
    from senbench.cli.views import show_status
    from senbench.results.store import cells_dir
    from senbench.run.status import suite_status

    suite = load_suite_file(suite_file)
    if not cells_dir(results, suite.name).is_dir():
        err.print(f"[yellow]warning:[/] {escape(str(cells_dir(results, suite.name)))} does not "
                  "exist: nothing of this suite has run under this results root (--results)",
                  highlight=False)
    show_status(suite_status(suite, results), f"suite '{suite.name}' under {results}", workers, out)


@app.command()
@user_errors
def run(
    suite_file: Annotated[Path, typer.Argument(help="Suite YAML file.")],
    workers: Annotated[int | None, typer.Option(
        "--workers", "-w", min=1, help="Cells run in parallel processes (default 1). With "
        "--executor ray and no --address: the local Ray instance's CPUs (default: all).")] = None,
    results: Annotated[Path, typer.Option(help="Results root; cells go to RESULTS/<suite>/.")]
    = Path("results"),
    force: Annotated[bool, typer.Option(help="Redo cells that already finished.")] = False,
    executor: Annotated[str, typer.Option(
        help="local: processes on this machine; ray: Ray tasks (pip install 'senbench\\[ray]')."
    )] = "local",
    address: Annotated[str | None, typer.Option(
        help="With --executor ray: the cluster (auto, or ray://host:10001). Without it, a "
             "local Ray instance with --workers CPUs is started for the run.")] = None,
    retries: Annotated[int, typer.Option(
        min=0, help="With --executor ray: how often a cell whose worker died is retried "
                    "before it is recorded as failed.")] = 2,
    method: PickMethods = None,
    env: PickEnvs = None,
    seed: PickSeeds = None,
    variant: PickVariants = None,
    time_limit: Annotated[str | None, typer.Option(
        help="Start a cell only if it is expected to end within this time of the run's "
             "start (2h30m, 150m, 90s), at the mean of the finished cells of its env, method "
             "and variant; exit 75 with the rest left for the next run.")] = None,
    reuse: Annotated[list[Path] | None, typer.Option(
        help="Another suite's results folder: a cell it holds finished, the same in all "
             "but its method and variant names, is copied, not run (repeat for several).")
    ] = None,
) -> None:
    """Run every cell of a suite that has not finished yet (resumable).

    --method, --env, --seed and --variant run a part of the grid; the rest stays as it is."""
    from senbench.cli.progress import GridProgress, print_summary
    from senbench.run.runner import EXECUTORS, run_suite
    from senbench.run.schedule import parse_duration

    if executor not in EXECUTORS:
        raise SenbenchError(f"--executor {executor!r}: use one of {', '.join(EXECUTORS)}")
    if address is not None and executor != "ray":
        raise SenbenchError("--address names a Ray cluster: add --executor ray")
    limit_s = None if time_limit is None else parse_duration(time_limit)
    suite = load_suite_file(suite_file)
    cells = suite.select(method or [], env or [], seed or [], variant or [])
    signal.signal(signal.SIGTERM, _stop_like_ctrl_c)  # batch schedulers stop jobs this way
    summary = run_suite(suite, results, workers=workers, force=force,
                        progress=GridProgress(err), executor=executor, address=address,
                        retries=retries, cells=cells, reuse=reuse or [],
                        time_limit_s=limit_s)
    print_summary(summary, suite.name, results / suite.name, len(suite.cells), time_limit,
                  out, err)
    if summary.exit_code:
        raise typer.Exit(summary.exit_code)


def _stop_like_ctrl_c(signum, frame) -> None:
    raise KeyboardInterrupt


@app.command()
@user_errors
def report(
    results_dir: Annotated[Path, typer.Argument(help="A suite's results folder.")],
    all_cells: Annotated[bool, typer.Option(
        "--all", help="Include cells of earlier versions of the suite.")] = False,
    threshold: Threshold = None,
    at: Annotated[list[int] | None, typer.Option(
        min=0, help="Also the mean evaluation return at this frame, over seeds (repeat for "
                    "several; a seed's last evaluation at or before it).")] = None,
    export: Table = None,
    actions: Annotated[bool, typer.Option(
        "--actions", help="Also what each method's evaluated policy did: the share of each "
                          "discrete action, or each action's mean ± std, at its last "
                          "evaluation and at each --at frame.")] = False,
) -> None:
    """Final return, frames to threshold and AUC per env and method, over seeds."""
    from senbench.analysis.summary import (
        actions_at,
        parse_thresholds,
        returns_at,
        summarize,
        summary_table,
        with_thresholds,
    )
    from senbench.cli.views import show_actions, show_report, show_returns_at
    from senbench.results.outputs import check_table_path, write_export
    from senbench.results.store import read_results

    thresholds = parse_thresholds(threshold or [])
    if export is not None:
        check_table_path(export)
    results = with_thresholds(read_results(results_dir, include_stale=all_cells), thresholds)
    summary = summarize(results)
    show_report(summary, out)
    if export is not None:
        write_export(summary_table(summary), export)
        out.print(f"summary written to {escape(str(export))}")
    if at:
        show_returns_at(returns_at(results, sorted(set(at))), out)
    if actions:
        show_actions(actions_at(results, [None, *sorted(set(at or []))]), out)
    if results.attrs.get("stale"):
        err.print(f"left out {results.attrs['stale']} cells of earlier versions of the suite "
                  "(--all includes them)")
    if results.attrs.get("missing"):
        err.print(f"{results.attrs['missing']} cells of the suite have no result yet: the "
                  "table counts the seeds that have one (`senbench run` runs the rest)")


@app.command()
@user_errors
def compare(
    a: Annotated[str, typer.Argument(help="A method of --results, or a results folder.")],
    b: Annotated[str, typer.Argument(help="Another method of --results, or another folder.")],
    results: Annotated[Path | None, typer.Option(
        help="The results folder holding methods A and B.")] = None,
    all_cells: Annotated[bool, typer.Option(
        "--all", help="Include cells of earlier versions of the suite.")] = False,
    threshold: Threshold = None,
    export: Table = None,
) -> None:
    """A against B per env: IQM with CIs and the probability that A does better."""
    from senbench.analysis.compare import comparison_table, pairs_for
    from senbench.analysis.summary import parse_thresholds
    from senbench.cli.views import show_comparison
    from senbench.results.outputs import check_table_path, write_export

    if export is not None:
        check_table_path(export)
    pairs = pairs_for(a, b, results, all_cells, parse_thresholds(threshold or []))
    show_comparison(pairs, out)
    if export is not None:
        write_export(comparison_table(pairs), export)
        out.print(f"comparison written to {escape(str(export))}")


@app.command()
@user_errors
def tune(
    suite_file: Annotated[Path, typer.Argument(help="Suite YAML file.")],
    trials: Annotated[int, typer.Option(min=1, help="Trials each study should hold in all "
                                        "(finished and pruned); a rerun resumes.")],
    method: Annotated[list[str] | None, typer.Option(
        help="A method of the suite to tune (repeat for several; default: every method, "
        "each with the same trials, seeds and frames: an equal tuning budget).")] = None,
    env: Annotated[str | None, typer.Option(help="Only this env (default: every env each "
                                            "method runs on, one study each).")] = None,
    seeds: Annotated[int, typer.Option(min=1, help="Seeds per trial, run at once.")] = 3,
    objective: Annotated[str, typer.Option(
        help="auc, final, steps-to-threshold (of the evaluation curve) or train-return "
        "(mean return of the training episodes); the mean over the trial's seeds.")] = "auc",
    storage: Annotated[str | None, typer.Option(
        help="Optuna storage URL (default: sqlite:///RESULTS/<suite>/tune.db).")] = None,
    study: Annotated[str | None, typer.Option(
        help="Study name, with one method on one env (default: <method>-<env>-<objective>)."
    )] = None,
    sampler: Annotated[str, typer.Option(help="tpe or random.")] = "tpe",
    pruner: Annotated[str, typer.Option(help="median, hyperband or none.")] = "median",
    seed: Annotated[int | None, typer.Option(
        help="The sampler's seed; a resumed study draws from it and the trials it holds.")
    ] = None,
    workers: Annotated[int, typer.Option(min=0, help="Processes per trial (0: one per "
                                         "seed, all at once, so that the pruner sees every "
                                         "seed at each evaluation early).")] = 0,
    export: Annotated[Path | None, typer.Option(
        help="Write each method's best trial as a suite 'methods:' block to this .yaml "
        "file (the blocks of other methods an earlier export left in it are kept).")] = None,
    time_limit: Annotated[str | None, typer.Option(
        help="Start a trial only if it is expected to end within this time of the "
             "command's start (2h30m, 150m, 90s), at the mean of the study's finished "
             "trials; exit 75 with the rest left for the next run.")] = None,
    results: Annotated[Path, typer.Option(help="Results root.")] = Path("results"),
) -> None:
    """Tune methods' hyperparameters with Optuna: seed-averaged trials, pruning on the
    seed mean of the objective's running value at each evaluation, a resumable shared study
    per method and env, each with the same budget, and the best blocks exported."""
    from senbench.cli.views import budget_table, trials_table
    from senbench.plugin.manager import registries
    from senbench.run.processes import usable_cores
    from senbench.run.schedule import parse_duration
    from senbench.tune.export import export_best, read_export
    from senbench.tune.study import (
        check_objective,
        fits,
        make_pruner,
        make_sampler,
        run_study,
        storage_for,
        trial_counts,
        tune_targets,
    )

    check_objective(objective)  # before a study is stored
    deadline = (None if time_limit is None
                else time.monotonic() + parse_duration(time_limit))
    if export is not None:
        check_out_file(export, (".yaml", ".yml"), "--export")
        read_export(export)  # a file it would not keep is refused before any trial
    suite = load_suite_file(suite_file)
    regs = registries()
    targets = tune_targets(suite, method, env, regs, named_study=study is not None,
                           export=export is not None)
    for tgt in targets:  # a bad --sampler or --pruner before any storage is made
        make_sampler(sampler, seed), make_pruner(pruner, tgt)
    processes = min(workers or seeds, seeds)
    if processes > usable_cores():
        err.print(f"[yellow]warning:[/] each trial runs {processes} seeds at once on "
                  f"{usable_cores()} cores (--workers caps them)")
    studies = []
    signal.signal(signal.SIGTERM, _stop_like_ctrl_c)  # its running trial is marked failed
    for tgt in targets:  # one after another, each with the same settings
        name = study or f"{tgt.method}-{tgt.env}-{objective}"
        try:
            done = run_study(  # the storage is opened only once all is checked
                tgt, trials=trials, seeds=seeds, objective=objective,
                storage=storage_for(storage, results / suite.name / "tune.db"),
                study_name=name, sampler=sampler, seed=seed, pruner=make_pruner(pruner, tgt),
                results_root=results, workers=processes, regs=regs,
                log=lambda message: err.print(escape(message), highlight=False),
                deadline=deadline)
        except KeyboardInterrupt:
            err.print(f"interrupted: study '{name}' keeps its finished trials; run the same "
                      "command again to go on")
            raise typer.Exit(130) from None
        studies.append((name, done, tgt))
        table = trials_table(done, name, objective)
        if table is None:
            err.print(f"study '{name}': no trial finished yet ({trial_counts(done)})")
        else:
            out.print(table)
        counts = trial_counts(done)
        held = counts["complete"] + counts["pruned"]
        if held < trials and not fits(done, deadline):
            err.print(f"--time-limit {time_limit}: study '{name}' holds {held} of {trials} "
                      "trials; the "
                      "next was not expected to end in time. Run the same command again "
                      "to go on.")
            raise typer.Exit(75)
    if len(studies) > 1:
        out.print(budget_table(studies, seeds))
    if export is not None:
        unfinished = [name for name, done, _ in studies if trials_table(done, name, objective)
                      is None]
        if unfinished:
            err.print(f"study {', '.join(unfinished)} has no finished trial yet: nothing "
                      "to export; run more trials")
            raise typer.Exit(1)
        export_best([(done, tgt) for _, done, tgt in studies], export, objective=objective,
                    seeds=seeds)
        out.print(f"best {'trials' if len(studies) > 1 else 'trial'} written to "
                  f"{escape(str(export))}")


@app.command()
@user_errors
def show(
    env: Annotated[str, typer.Argument(help="An env plugin's name.")],
    png: Annotated[Path, typer.Option("--out", help=FIGURE_HELP)] = Path("frames.png"),
    frames: Annotated[int, typer.Option(min=1, max=32, help="States to show.")] = 8,
    height: Annotated[int, typer.Option(min=8, max=512)] = 64,
    width: Annotated[int, typer.Option(min=8, max=512)] = 64,
    seed: Annotated[int, typer.Option(min=0, help="Seed of the sampled states.")] = 0,
) -> None:
    """Sample frames of an env, with gymnasium's frame for the same state beside each."""
    from senbench.cli.show import save_comparison
    from senbench.plugin.manager import registries

    spec = registries().envs.get(env)
    check_out_file(png, FIGURES)
    difference = save_comparison(spec, png, frames, (height, width), seed)
    out.print(f"{escape(str(png))}: {frames} states of {env}; mean |difference| from "
              f"gymnasium's resized frames: {difference:.2f} grey levels")


@app.command()
@user_errors
def plugins() -> None:
    """Every env, agent, encoder and sampler installed, and which distribution provided it."""
    from senbench.cli.tables import show_plugins
    from senbench.plugin.manager import registries

    show_plugins(registries(), out)
