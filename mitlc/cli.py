"""The ``mitlc`` command: the only module that prints or exits.

Every command turns mitlc's typed errors into a message on standard error and exit status 1;
usage errors exit with status 2, as Click does.
"""

from __future__ import annotations

import functools
import json
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any, ParamSpec, TypeVar

import typer

from mitlc import __version__
from mitlc.errors import MitlcError
from mitlc.syntax import Formula, ast_to_data, parse, parse_bytes, to_text
from mitlc.syntax.tree import tree_text

app = typer.Typer(
    name="mitlc",
    help="Compile, check and learn time-bounded robot tasks written in MITL.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
)

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


class UsageError(MitlcError):
    """The command line names no spec, or two."""


def _reports_errors(command: Callable[P, R]) -> Callable[P, R]:
    """Print mitlc's errors (and unreadable files) as a message, exit 1, never a traceback."""

    @functools.wraps(command)
    def wrapper(*args: P.args, **kwargs: P.kwargs) -> R:
        try:
            return command(*args, **kwargs)
        except MitlcError as err:
            typer.echo(err.render(), err=True)
            raise typer.Exit(1) from None
        except OSError as err:
            name = err.filename if err.filename is not None else ""
            typer.echo(f"mitlc: cannot read {name}: {err.strerror}", err=True)
            raise typer.Exit(1) from None

    return wrapper


def load_formula(spec: str | None, expr: str | None) -> Formula:
    """The formula named on the command line: a file, standard input ('-'), or ``-e``."""
    if (spec is None) == (expr is None):
        raise UsageError("mitlc: give one formula: a SPEC file (or '-'), or -e FORMULA")
    if expr is not None:
        return parse(expr, "<expr>")
    assert spec is not None
    if spec == "-":
        return parse_bytes(sys.stdin.buffer.read(), "<stdin>")
    return parse_bytes(Path(spec).read_bytes(), spec)


def _json_dumps(data: Any) -> str:
    return json.dumps(data, indent=2, sort_keys=True, ensure_ascii=False)


@app.command()
@_reports_errors
def fmt(spec: SpecArg = None, expr: ExprOpt = None) -> None:
    """Print the canonical text of a formula (it parses back to the same formula)."""
    typer.echo(to_text(load_formula(spec, expr)))


@app.command(name="parse")
@_reports_errors
def parse_command(
    spec: SpecArg = None,
    expr: ExprOpt = None,
    as_json: Annotated[
        bool, typer.Option("--json", help="Print the AST as JSON, with source spans.")
    ] = False,
) -> None:
    """Print the abstract syntax tree of a formula."""
    formula = load_formula(spec, expr)
    typer.echo(_json_dumps(ast_to_data(formula)) if as_json else tree_text(formula))


def _version(value: bool) -> None:
    if value:
        typer.echo(f"mitlc {__version__}")
        raise typer.Exit()


@app.callback()
def _main(
    version: Annotated[
        bool,
        typer.Option("--version", callback=_version, is_eager=True, help="Print the version."),
    ] = False,
) -> None:
    """Compile, check and learn time-bounded robot tasks written in MITL."""


def main() -> None:
    """The console script's entry point."""
    app()
