"""The learning commands of ``mitlc``: ``train``, ``eval`` and ``plot`` (registered on the
app by :mod:`mitlc.cli`, which owns error reporting)."""

# No `from __future__ import annotations` here: typer reads every command's annotations at each
# start (all commands, for any one), and evaluating them once at import spares it compiling and
# evaluating them as strings (about 10 ms of the start-up; bench/startup_bench.py).

import json
import signal
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING, Annotated, Any

import typer

from mitlc.cli_common import (
    TaskExprOpt,
    TaskSpecOpt,
    TrustWorldOpt,
    command_deadline,
    task_formula,
    time_limit_option,
)
from mitlc.learn.names import ALGORITHMS, DEVICES
from mitlc.learn.names import MAX_EVAL_EPISODES as MAX_EVAL
from mitlc.limits import DEFAULT_TIME_LIMIT, Deadline

if TYPE_CHECKING:
    from mitlc.learn.config import TrainConfig

RunArg = Annotated[Path, typer.Argument(metavar="RUN", help="A run directory (mitlc train).")]


def _overrides(
    pairs: list[str],
    algo: str | None,
    seed: int | None,
    episodes: int | None,
    device: str | None = None,
) -> dict[str, Any]:
    from mitlc.learn.rundir.files import RunError

    values: dict[str, Any] = {}
    for pair in pairs:
        key, sep, value = pair.partition("=")
        if not sep or not key:
            raise RunError(f"--set {pair!r}: expected KEY=VALUE, e.g. --set q.alpha=0.2")
        values[key.strip()] = value.strip()
    given: dict[str, object] = {"algo": algo, "seed": seed, "episodes": episodes}
    given["device"] = device
    values.update({name: v for name, v in given.items() if v is not None})
    return values


class _StopFlag:
    """Ctrl-C asks the run to stop (it checkpoints first); a second Ctrl-C stops at once."""

    def __init__(self) -> None:
        self.raised = False
        self._previous: Any = None

    def __enter__(self) -> "_StopFlag":
        self._previous = signal.signal(signal.SIGINT, self._handle)
        return self

    def __exit__(self, *_: object) -> None:
        signal.signal(signal.SIGINT, self._previous)

    def _handle(self, signum: int, frame: FrameType | None) -> None:
        if self.raised:
            raise KeyboardInterrupt
        self.raised = True

    def __call__(self) -> bool:
        return self.raised


def _progress_display(quiet: bool) -> Any:
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    return Progress(
        TextColumn("[bold]{task.description}"),
        BarColumn(bar_width=12),
        MofNCompleteColumn(),
        TextColumn(
            "success {task.fields[success]:.3f} return {task.fields[ret]:.1f} "
            "ε {task.fields[epsilon]:.2f}"
        ),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
        console=Console(stderr=True),
        disable=quiet,
        transient=False,
    )


@contextmanager
def _evaluation_bar() -> Iterator[Callable[[int, int], None] | None]:
    """A bar of the evaluation's episodes on stderr, where stderr is a terminal (else none:
    a log or a pipe, and ``--json`` read from stdout, get no bar)."""
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
    )

    console = Console(stderr=True)
    if not console.is_terminal:
        yield None
        return
    columns = (TextColumn("[bold]eval"), BarColumn(bar_width=12), MofNCompleteColumn(),
               TimeElapsedColumn())  # fmt: skip
    with Progress(*columns, console=console, transient=True) as bar:
        task = bar.add_task("eval", total=None)

        def show(ended: int, total: int) -> None:
            bar.update(task, completed=ended, total=total)

        yield show


def train_command(
    world_file: Annotated[Path, typer.Argument(metavar="WORLD", help="A world file (YAML).")],
    algo: Annotated[
        str | None, typer.Option("--algo", help=f"One of {', '.join(ALGORITHMS)}.")
    ] = None,
    seed: Annotated[int | None, typer.Option("--seed", help="The run's seed.")] = None,
    episodes: Annotated[
        int | None,
        typer.Option(
            "--episodes",
            help="The run's total number of episodes, also with --resume (where it must be more "
            "than the run has). The run stops at the first step at which at least this many "
            "episodes have ended, so it may end up to num_envs - 1 above it.",
        ),
    ] = None,
    out: Annotated[
        Path | None,
        typer.Option("--out", help="The run directory (default: runs/WORLD-ALGO-sSEED)."),
    ] = None,
    resume: Annotated[
        bool,
        typer.Option(
            "--resume",
            help="Continue the run in --out from its latest checkpoint (one run at a time holds "
            "a run directory).",
        ),
    ] = False,
    spec: TaskSpecOpt = None,
    expr: TaskExprOpt = None,
    settings: Annotated[
        list[str] | None,
        typer.Option("--set", metavar="KEY=VALUE", help="A training setting, e.g. q.alpha=0.2."),
    ] = None,
    device: Annotated[
        str | None,
        typer.Option(
            "--device",
            help=f"Where torch trains: {', '.join(DEVICES)} (default: the world file's, else "
            "auto: CUDA where torch sees it, else the CPU). A resumed run may change it.",
        ),
    ] = None,
    shield: Annotated[
        float | None,
        typer.Option(
            "--shield",
            metavar="THETA",
            help="Keep to the shield of the exact product (finite MDPs): only actions that "
            "keep every shielded policy at THETA x the optimum within the horizon (1: optimal "
            "actions only). Sets training.shield.",
        ),
    ] = None,
    shield_violation: Annotated[
        float | None,
        typer.Option(
            "--shield-violation",
            metavar="DELTA",
            help="Only actions whose violation probability within the horizon exceeds the "
            "least possible by at most DELTA (0: least violation only). Sets "
            "training.shield_violation.",
        ),
    ] = None,
    evaluate_after: Annotated[
        bool, typer.Option("--eval/--no-eval", help="Evaluate the policy at the end.")
    ] = True,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No progress bar.")] = False,
    time_limit: Annotated[
        float,
        time_limit_option(
            "Stop the set-up (compiling the task, building the product) after this many "
            "seconds (0: no limit); the training itself runs its episodes (Ctrl-C stops it).",
        ),
    ] = DEFAULT_TIME_LIMIT,
    trust_world: TrustWorldOpt = False,
) -> None:
    """Learn a policy for a world's task; report it beside the exact optimum."""
    from mitlc.learn.bounds import check_option

    check_option("train", "--episodes", episodes)  # before the learners are imported
    check_option("train", "--seed", seed)
    from mitlc.learn.config import config_for
    from mitlc.learn.run import train
    from mitlc.learn.rundir.files import RunError
    from mitlc.learn.setting import CONFIG, read_config
    from mitlc.worlds.door import open_world

    overrides = _overrides(settings or [], algo, seed, episodes, device)
    for key, value in (("shield", shield), ("shield_violation", shield_violation)):
        if value is not None:
            overrides[key] = value
    formula = None
    override = task_formula(spec, expr)
    if override is not None:
        from mitlc.syntax import to_text

        formula = to_text(override)
    if resume and out is not None and (out / CONFIG).is_file():
        _, saved = read_config(out)
        overrides = {**_flatten(saved), **overrides}
    world = open_world(world_file, formula)  # the one read and build of the world file
    config, name = config_for(world, overrides)
    if resume and out is None:
        raise RunError("--resume needs --out: the run directory to continue")
    if config.device == "cuda":  # a machine without CUDA: say so before the set-up
        from mitlc.learn.device import resolve_device

        resolve_device(config.device)
    directory = out or Path("runs") / f"{name}-{config.algo}-s{config.seed}"
    sb3 = config.algo.startswith("sb3-")  # Stable-Baselines3's runs count environment steps
    with _StopFlag() as stop, _progress_display(quiet) as display:
        tasks: list[Any] = []  # the bar appears with the first progress, once the run is set up

        def show(p: Any) -> None:
            if not tasks:
                total = config.sb3.steps if sb3 else config.episodes
                tasks.append(
                    display.add_task(config.algo, total=total, success=0.0, ret=0.0, epsilon=1.0)
                )
            display.update(
                tasks[0],
                completed=min(p.steps if sb3 else p.episodes, p.total),
                success=p.success_rate,
                ret=p.mean_return,
                epsilon=p.epsilon,
            )

        result = train(
            world_file,
            config,
            directory,
            spec=formula,
            resume=resume,
            progress=show,
            should_stop=stop,
            deadline=command_deadline(time_limit, "train"),
            notes=lambda note: typer.echo(note, err=True),
            world=world,
        )
    if result.stopped:
        typer.echo(
            f"stopped at episode {result.episodes:,}; checkpoint saved. Continue with:\n"
            f"  mitlc train {world_file} --out {directory} --resume",
            err=True,
        )
        raise typer.Exit(130)
    typer.echo(
        f"trained {result.episodes:,} episodes ({result.steps:,} steps) in "
        f"{result.seconds:.1f} s -> {directory}"
    )
    if result.never_held:
        from mitlc.learn.held import never_held_note

        note = never_held_note(result.never_held, result.episodes, result.steps)
        typer.echo(f"note: {note}", err=True)
    if evaluate_after:
        _print_evaluation(directory, None, 12345, as_json=False, bounds=False)


def _flatten(config: "TrainConfig") -> dict[str, Any]:
    """A saved run's settings as dotted overrides (what ``--resume`` starts from)."""
    from mitlc.learn.config import to_data

    flat: dict[str, Any] = {}

    def walk(prefix: str, data: dict[str, Any]) -> None:
        for key, value in data.items():
            if isinstance(value, dict):
                walk(f"{prefix}{key}.", value)
            else:
                flat[f"{prefix}{key}"] = value

    walk("", to_data(config))
    return flat


def _print_evaluation(
    directory: Path,
    episodes: int | None,
    seed: int,
    *,
    as_json: bool,
    bounds: bool,
    deadline: Deadline | None = None,
) -> None:
    from mitlc.learn.evaluation.evaluate import evaluate

    with _evaluation_bar() as show:
        report = evaluate(
            directory, episodes=episodes, seed=seed, pomdp_bounds=bounds, deadline=deadline,
            progress=show,
        )  # fmt: skip
    data = report.summary()
    if as_json:
        typer.echo(json.dumps(data, indent=2, sort_keys=True))
        return
    low, high = report.interval
    rows = [
        (
            "learned success",
            f"{report.success_rate:.4f}  95% [{low:.4f}, {high:.4f}]  "
            f"({report.successes:,}/{report.episodes:,} episodes)",
        ),
    ]
    if report.exact is not None:
        rows.append(("learned, exact", f"{report.exact:.6f}"))
    kind = "fully observable upper bound" if report.pomdp else "optimum"
    if report.optimum is None:
        rows.append(("optimum", "none: this world is not finite (no exact optimum)"))
    else:
        rows.append((kind, f"{report.optimum:.6f}"))
    if report.lower is not None:
        rows.append(("observation-based lower bound", f"{report.lower:.6f}"))
    if report.optimum is not None and report.optimum > 0:
        shown = report.exact if report.exact is not None else report.success_rate
        rows.append(("ratio", f"{shown / report.optimum:.4f}"))
    if report.lower is not None and report.lower > 0:
        rows.append(("ratio to the lower bound", f"{report.success_rate / report.lower:.4f}"))
    if report.bounds is not None:
        rows.append(
            ("Storm bounds", f"[{report.bounds['lower']:.6f}, {report.bounds['upper']:.6f}]")
        )
    rows.append(("mean return", f"{report.mean_return:.2f}"))
    if report.mean_rounds > 0:
        rows.append(("mean rounds completed", f"{report.mean_rounds:.2f}"))
    if report.mean_cost is not None:
        rows.append(("mean cost", f"{report.mean_cost:.2f}"))
    if report.min_cost is not None:
        rows.append(("least cost, best success", f"{report.min_cost:.2f}"))
    width = max(len(k) for k, _ in rows)
    for key, value in rows:
        typer.echo(f"{key:<{width}}  {value}")
    if report.never_held:
        from mitlc.learn.held import never_held_note

        typer.echo(f"note: {never_held_note(report.never_held, report.episodes)}", err=True)


def eval_command(
    run: RunArg,
    episodes: Annotated[
        int | None,
        typer.Option(
            "--episodes",
            help=f"Episodes (default: the run's setting), all run at once: 1 to {MAX_EVAL:,}.",
        ),
    ] = None,
    seed: Annotated[int, typer.Option("--seed", help="The evaluation's seed.")] = 12345,
    as_json: Annotated[bool, typer.Option("--json", help="Print the report as JSON.")] = False,
    pomdp_bounds: Annotated[
        bool,
        typer.Option("--pomdp-bounds", help="For a POMDP, add Storm's belief bounds (slow)."),
    ] = False,
    time_limit: Annotated[
        float,
        time_limit_option(
            "Stop the set-up and the exact figures after this many seconds (0: no limit); "
            "POMDP bounds that run out of time are left out.",
        ),
    ] = DEFAULT_TIME_LIMIT,
    trust_world: TrustWorldOpt = False,
) -> None:
    """Measure a run's policy (success with a 95% interval) beside the exact optimum."""
    from mitlc.learn.bounds import check_option

    check_option("eval", "--episodes", episodes)
    check_option("eval", "--seed", seed)
    deadline = command_deadline(time_limit, "eval")
    _print_evaluation(run, episodes, seed, as_json=as_json, bounds=pomdp_bounds, deadline=deadline)


def plot_command(
    run: RunArg,
    out: Annotated[
        Path | None, typer.Option("--out", help="Where to write the figures (default: RUN).")
    ] = None,
    trajectories: Annotated[
        int, typer.Option("--trajectories", help="Greedy trajectories to draw.")
    ] = 5,
    seed: Annotated[int, typer.Option("--seed", help="The trajectories' seed.")] = 0,
    time_limit: Annotated[
        float,
        time_limit_option(
            "Stop setting the run up (its task, its product) after this many seconds (0: no limit)."
        ),
    ] = DEFAULT_TIME_LIMIT,
    trust_world: TrustWorldOpt = False,
) -> None:
    """Draw a run: learning curve, trajectories on the map, the automaton (PNG); for a team,
    every robot's path in its colour and an animated greedy episode (GIF)."""
    from mitlc.learn.bounds import check_option

    check_option("plot", "--trajectories", trajectories)  # before matplotlib is imported
    check_option("plot", "--seed", seed)
    from mitlc.learn.plots import plot_run
    from mitlc.learn.setting import read_config

    read_config(run)
    deadline = command_deadline(time_limit, "plot")
    for path in plot_run(run, out, trajectories=trajectories, seed=seed, deadline=deadline):
        typer.echo(str(path))


def register(app: typer.Typer, reports_errors: Callable[[Any], Any]) -> None:
    """Add the learning commands to ``app``."""
    app.command(name="train")(reports_errors(train_command))
    app.command(name="eval")(reports_errors(eval_command))
    app.command(name="plot")(reports_errors(plot_command))
