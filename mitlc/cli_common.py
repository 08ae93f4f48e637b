"""What every ``mitlc`` command shares: the spec arguments, the limit options, and the wrapper
that turns mitlc's typed errors into one message and exit status 1 (never a traceback)."""

from __future__ import annotations

import functools
import json
import os
import sys
from collections.abc import Callable
from typing import Annotated, Any, ParamSpec, TypeVar

import typer

from mitlc.cli_memory import stopped_at_a_limit, with_memory_limit
from mitlc.errors import MitlcError
from mitlc.limits import CLI_HOW, CLI_MEMORY_HOW, Deadline, LimitError
from mitlc.syntax import Formula, parse, read_spec

P = ParamSpec("P")
R = TypeVar("R")

SpecArg = Annotated[
    str | None,
    typer.Argument(
        help="A spec file holding one MITL formula, or '-' for standard input.",
        show_default=False,
    ),
]
ExprOpt = Annotated[
    str | None,
    typer.Option("--expr", "-e", help="A formula given on the command line instead of SPEC."),
]
TaskSpecOpt = Annotated[
    str | None,
    typer.Option(
        "--spec",
        metavar="SPEC",
        help="A spec file ('-': standard input) instead of the world's own task.",
    ),
]
TaskExprOpt = Annotated[
    str | None,
    typer.Option(
        "--expr",
        "-e",
        metavar="FORMULA",
        help="A formula given on the command line instead of the world's own task.",
    ),
]


TrustWorldOpt = Annotated[
    bool,
    typer.Option(
        "--trust-world",
        help="Trust the world file as your own code: allow wrappers from any installed "
        "package and arguments that name files (docs/envs.md, 'Trust model').",
    ),
]


class UsageError(MitlcError):
    """The command line names no spec, or two."""


def reports_errors(command: Callable[P, R]) -> Callable[P, R]:
    """Print mitlc's errors (and unreadable files, and memory that could not be had) as a
    message, exit 1, never a traceback; give the command its ``--memory-limit``
    (:func:`mitlc.cli_memory.with_memory_limit`); and run a command given ``--trust-world``
    (a ``trust_world`` parameter: :data:`TrustWorldOpt`) with world files trusted
    (:func:`mitlc.worlds.trust.trusting`)."""

    @functools.wraps(command)
    def wrapper(*args: P.args, **kwargs: P.kwargs) -> R:
        try:
            if kwargs.get("trust_world"):  # --trust-world, for this command only
                from mitlc.worlds.trust import trusting

                with trusting():
                    return command(*args, **kwargs)
            return command(*args, **kwargs)
        except MitlcError as err:
            typer.echo(err.render(), err=True)
            if isinstance(err, LimitError):
                stopped_at_a_limit()
            raise typer.Exit(1) from None
        except OSError as err:
            name = f"{err.filename}: " if err.filename is not None else ""
            typer.echo(f"mitlc: {name}{err.strerror or err}", err=True)
            raise typer.Exit(1) from None
        except MemoryError:
            typer.echo(
                f"mitlc: out of memory (an allocation failed); lower the sizes asked for, or "
                f"give the command more with {CLI_MEMORY_HOW}",
                err=True,
            )
            raise typer.Exit(1) from None

    return with_memory_limit(wrapper)


def load_formula(spec: str | None, expr: str | None) -> Formula:
    """The formula named on the command line: a file, standard input ('-'), or ``-e``."""
    if (spec is None) == (expr is None):
        raise UsageError("mitlc: give one formula: a SPEC file (or '-'), or -e FORMULA")
    if expr is not None:
        return parse(expr, "<expr>")
    assert spec is not None
    if spec == "-":
        return parse(read_spec(sys.stdin.buffer, "<stdin>"), "<stdin>")
    return parse(read_spec(spec), spec)


def task_formula(spec: str | None, expr: str | None) -> Formula | None:
    """The formula that replaces a world's own task (``--spec SPEC`` or ``-e FORMULA``, read as
    :func:`load_formula` reads a command's formula), or None where neither is given."""
    if spec is not None and expr is not None:
        raise UsageError("mitlc: give the task once: --spec SPEC or -e FORMULA, not both")
    if spec is None and expr is None:
        return None
    return load_formula(spec, expr)


def json_dumps(data: Any) -> str:
    """Canonical, readable JSON (sorted keys, Unicode kept)."""
    return json.dumps(data, indent=2, sort_keys=True, ensure_ascii=False)


MaxStatesOpt = Annotated[
    int,
    typer.Option(
        "--max-states", min=1, help="Stop a translation that grows past this many states."
    ),
]


def time_limit_option(
    help: str = "Stop the command after this many seconds (0: no limit).",
) -> Any:
    """The ``--time-limit SECONDS`` option of a command, with what it bounds as ``help``."""
    return typer.Option("--time-limit", min=0, metavar="SECONDS", help=help)


TimeLimitOpt = Annotated[float, time_limit_option()]


_whole_process: list[bool] = [False]
"""Whether this process runs one command (the console script): its time limit then counts
from the start of the process (not where commands run in a longer-lived process: tests)."""


def one_command_per_process() -> None:
    """Say that this process runs one command (:func:`mitlc.cli.main` does)."""
    _whole_process[0] = True


def command_deadline(seconds: float, command: str) -> Deadline:
    """The time limit of one command (``--time-limit``); run as the console script, counted
    from the start of the process: the seconds Python and the imports took are the command's
    too."""
    deadline = Deadline(seconds, f"mitlc {command}", CLI_HOW)
    return deadline.counted_from(_seconds_since_start()) if _whole_process[0] else deadline


def _seconds_since_start() -> float:
    """Seconds since this process started (Linux's ``/proc``; 0 where it cannot be read)."""
    try:
        with open("/proc/uptime", "rb") as uptime, open("/proc/self/stat", "rb") as stat:
            now = float(uptime.read().split()[0])
            fields = stat.read().rsplit(b")", 1)[1].split()
        return max(0.0, now - int(fields[19]) / os.sysconf("SC_CLK_TCK"))
    except (OSError, ValueError, IndexError):
        return 0.0
