"""The sweep commands of ``mitlc``: ``sweep`` and ``report`` (registered on the app by
:mod:`mitlc.cli`, which owns error reporting). They need the extra ``mitlc[sweep]`` (Ray Tune
and rliable)."""

# No `from __future__ import annotations` here: typer reads every command's annotations at each
# start (all commands, for any one), and evaluating them once at import spares it compiling and
# evaluating them as strings (about 10 ms of the start-up; bench/startup_bench.py).

import importlib.util
import os
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any

import typer

from mitlc.errors import MitlcError


class SweepExtraError(MitlcError):
    """The sweep extra is not installed."""


def _require(*modules: str) -> None:
    missing = [m for m in modules if importlib.util.find_spec(m) is None]
    if missing:
        raise SweepExtraError(
            f"mitlc: {' and '.join(missing)} not installed: pip install 'mitlc[sweep]'"
        )


def sweep_command(
    sweep_file: Annotated[Path, typer.Argument(metavar="SWEEP", help="A sweep file (YAML).")],
    out: Annotated[
        Path | None,
        typer.Option("--out", help="The sweep's directory (default: runs/sweep-NAME)."),
    ] = None,
    address: Annotated[
        str | None,
        typer.Option(
            "--address",
            help="Join this Ray cluster (auto, HOST:PORT or ray://HOST:10001); its nodes must "
            "share --out. Default: Ray on this machine's cores.",
        ),
    ] = None,
    resume: Annotated[
        bool,
        typer.Option("--resume", help="Go on with the sweep in --out: skip finished trials."),
    ] = False,
    reps: Annotated[int, typer.Option("--reps", help="Bootstrap resamples of the report.")] = 2000,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No progress display.")] = False,
) -> None:
    """Train and evaluate every trial of a sweep on Ray, then write its report."""
    from mitlc.learn.bounds import check_option

    check_option("sweep", "--reps", reps)
    _require("ray", "rliable")
    from mitlc.sweep.ray_run import Event, run_sweep
    from mitlc.sweep.report import report
    from mitlc.sweep.spec import load_sweep

    sweep = load_sweep(sweep_file)
    directory = out if out is not None else Path("runs") / f"sweep-{sweep.name}"
    total = len(sweep.trials)
    counts = {"running": 0, "done": 0, "failed": 0, "retried": 0}

    def show(event: Event) -> None:
        if event.kind == "start":
            counts["running"] += 1
        elif event.kind in ("done", "skipped"):
            counts["running"] -= event.kind == "done"
            counts["done"] += 1
        elif event.kind == "error":
            counts["running"] -= 1
            counts["failed"] += 1
        elif event.kind == "retry":
            counts["retried"] += 1
        if not quiet:
            line = (f"trials: {counts['done']}/{total} done, {counts['running']} running, "
                    f"{counts['failed']} failed, {counts['retried']} retried  "
                    f"[{event.kind} {event.trial}]")  # fmt: skip
            typer.echo(line, err=True)

    result = run_sweep(sweep, directory, address=address, resume=resume, on_event=show)
    written = report(directory, reps=reps) if result.results else None
    typer.echo(f"{len(result.results)} of {total} trials finished -> {directory}")
    if written is not None:
        for path in written.files:
            typer.echo(str(path))
    if result.failed:
        typer.echo(f"failed: {', '.join(result.failed)} (go on with --resume)", err=True)
        raise typer.Exit(1)


def report_command(
    directory: Annotated[Path, typer.Argument(metavar="DIR", help="A sweep's directory.")],
    reps: Annotated[int, typer.Option("--reps", help="Bootstrap resamples (rliable).")] = 2000,
    seed: Annotated[int, typer.Option("--seed", help="The bootstrap's seed.")] = 0,
) -> None:
    """Write a sweep's report: rliable's statistics over seeds, tables and figures."""
    from mitlc.learn.bounds import check_option

    check_option("report", "--reps", reps)
    check_option("report", "--seed", seed)
    _require("rliable")
    from mitlc.inputs import MAX_RECORD_BYTES, read_capped
    from mitlc.sweep.report import REPORT_MD, report

    written = report(directory, reps=reps, seed=seed)
    text = read_capped(directory / REPORT_MD, MAX_RECORD_BYTES, "a sweep's report")
    sys.stdout.write(text.decode("utf-8"))
    for path in written.files:
        typer.echo(str(path))


def register(app: typer.Typer, reports_errors: Callable[[Any], Any]) -> None:
    """Add the sweep commands to ``app``."""
    os.environ.setdefault("PYTHONWARNINGS", "ignore::FutureWarning")
    app.command(name="sweep")(reports_errors(sweep_command))
    app.command(name="report")(reports_errors(report_command))
