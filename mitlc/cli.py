"""The ``mitlc`` command: the only module that prints or exits.

Every command turns mitlc's typed errors into a message on standard error and exit status 1;
usage errors exit with status 2, as Click does.
"""

# No `from __future__ import annotations` here: typer reads every command's annotations at each
# start (all commands, for any one), and evaluating them once at import spares it compiling and
# evaluating them as strings (about 10 ms of the start-up; bench/startup_bench.py).

import json
from enum import StrEnum
from pathlib import Path
from typing import Annotated

import typer

from mitlc import __version__
from mitlc.cli_check import register as register_checking
from mitlc.cli_coercion import install as install_plain_coercion
from mitlc.cli_common import (
    ExprOpt,
    MaxStatesOpt,
    SpecArg,
    TimeLimitOpt,
    UsageError,
    command_deadline,
    json_dumps,
    load_formula,
    one_command_per_process,
    reports_errors,
)
from mitlc.cli_learn import register as register_learning
from mitlc.cli_memory import exit_now
from mitlc.cli_sweep import register as register_sweeps
from mitlc.errors import MitlcError
from mitlc.limits import (
    DEFAULT_MAX_DRAWN_STATES,
    DEFAULT_MAX_STATES,
    DEFAULT_TIME_LIMIT,
    Deadline,
)
from mitlc.syntax import ast_to_data, atoms, parse_batch_file, to_text
from mitlc.syntax.tree import tree_text

# Each command imports what it needs when it runs (the automata, traces, worlds, learners), and
# typer coerces plain option values without pydantic, so that `mitlc fmt` starts without them:
# the start-up is measured by bench/startup_bench.py, what it imports checked by
# tests/test_startup.py.
install_plain_coercion()

app = typer.Typer(
    name="mitlc",
    help="Compile, check and learn time-bounded robot tasks written in MITL.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
)


@app.command()
@reports_errors
def fmt(spec: SpecArg = None, expr: ExprOpt = None) -> None:
    """Print the canonical text of a formula (it parses back to the same formula)."""
    typer.echo(to_text(load_formula(spec, expr)))


@app.command(name="parse")
@reports_errors
def parse_command(
    spec: SpecArg = None,
    expr: ExprOpt = None,
    as_json: Annotated[
        bool, typer.Option("--json", help="Print the AST as JSON, with source spans.")
    ] = False,
) -> None:
    """Print the abstract syntax tree of a formula."""
    formula = load_formula(spec, expr)
    typer.echo(json_dumps(ast_to_data(formula)) if as_json else tree_text(formula))


class Format(StrEnum):
    """Output formats of ``mitlc compile``."""

    json = "json"
    dot = "dot"
    hoa = "hoa"


OutOpt = Annotated[
    Path | None, typer.Option("--output", "-o", help="Write here (atomically) instead of stdout.")
]


def _emit(text: str, output: Path | None) -> None:
    if output is None:
        typer.echo(text, nl=False)
    else:
        from mitlc.files import write_atomically

        write_atomically(output, text.encode("utf-8"))


@app.command(name="compile")
@reports_errors
def compile_command(
    spec: SpecArg = None,
    expr: ExprOpt = None,
    fmt: Annotated[Format, typer.Option("--format", "-f", help="json, dot or hoa.")] = Format.json,
    output: OutOpt = None,
    batch: Annotated[
        Path | None,
        typer.Option(
            "--batch", help="Compile one formula per line of FILE (JSON Lines, or a HOA stream)."
        ),
    ] = None,
    max_states: MaxStatesOpt = DEFAULT_MAX_STATES,
    time_limit: TimeLimitOpt = DEFAULT_TIME_LIMIT,
) -> None:
    """Compile a formula into its timed LDGBA (JSON artifact, DOT drawing or HOA)."""
    from mitlc.automata import compile_formula

    deadline = command_deadline(time_limit, "compile")
    if batch is not None:
        if spec is not None or expr is not None:
            raise UsageError("mitlc: --batch reads its formulas from FILE; give no SPEC or -e")
        _emit(_compile_batch(batch, fmt, max_states, deadline), output)
        return
    compiled = compile_formula(load_formula(spec, expr), max_states=max_states, deadline=deadline)
    if fmt is Format.hoa:
        from mitlc.automata.hoa import to_hoa

        text = to_hoa(compiled.digital)
    elif fmt is Format.dot:
        from mitlc.automata.dot import to_dot

        text = to_dot(compiled.timed)
    else:
        from mitlc.automata.artifact import to_json

        text = to_json(compiled.timed)
    _emit(text, output)


def _compile_batch(path: Path, fmt: Format, max_states: int, deadline: Deadline) -> str:
    from mitlc.automata import compile_formula
    from mitlc.automata.artifact import to_json
    from mitlc.automata.hoa import to_hoa_stream

    compiled = [
        compile_formula(f, max_states=max_states, deadline=deadline) for f in parse_batch_file(path)
    ]
    if fmt is Format.hoa:
        return to_hoa_stream(c.digital for c in compiled)
    if fmt is Format.dot:
        raise UsageError("mitlc: --batch writes json (JSON Lines) or hoa")
    return "".join(to_json(c.timed, indent=None) for c in compiled)


@app.command(name="render")
@reports_errors
def render_command(
    source: Annotated[
        str | None,
        typer.Argument(help="A spec file, '-' for standard input, or an AUTOMATON.json artifact."),
    ] = None,
    expr: ExprOpt = None,
    output: Annotated[
        Path, typer.Option("--output", "-o", help="FILE.png, FILE.svg or FILE.dot.")
    ] = Path("automaton.png"),
    max_states: Annotated[
        int,
        typer.Option(
            "--max-states",
            min=1,
            help="Refuse to draw an automaton of more states than this (a .dot file is "
            "written at any size).",
        ),
    ] = DEFAULT_MAX_DRAWN_STATES,
    time_limit: TimeLimitOpt = DEFAULT_TIME_LIMIT,
) -> None:
    """Draw the timed LDGBA of a formula or of a compiled artifact."""
    from mitlc.automata import compile_formula
    from mitlc.automata.artifact import from_data
    from mitlc.automata.dot import draw, output_format
    from mitlc.inputs import MAX_ARTIFACT_BYTES, read_capped

    output_format(output)  # an unknown format is refused before any work
    deadline = command_deadline(time_limit, "render")  # Graphviz's layout included
    if source is not None and source.endswith(".json"):
        text = read_capped(source, MAX_ARTIFACT_BYTES, "an automaton artifact")  # or OSError
        try:
            data = json.loads(text)
        except json.JSONDecodeError as err:
            raise UsageError(f"{source}:{err.lineno}:{err.colno}: not JSON: {err.msg}") from None
        except RecursionError:
            raise UsageError(f"{source}: not a JSON artifact: nested too deeply") from None
        except ValueError as err:  # not UTF-8, a number of thousands of digits
            raise UsageError(f"{source}: not a JSON artifact: {err}") from None
        try:
            timed = from_data(data)
        except MitlcError as err:
            raise UsageError(f"{source}: {err}") from None
    else:
        timed = compile_formula(
            load_formula(source, expr),
            max_states=max(DEFAULT_MAX_STATES, max_states),  # the translation's own limit
            deadline=deadline,
        ).timed
    draw(timed, output, max_states=max_states, deadline=deadline)
    typer.echo(f"wrote {output}", err=True)


@app.command()
@reports_errors
def monitor(
    spec: Annotated[str, typer.Argument(help="A spec file, or '-' for standard input.")],
    trace: Annotated[
        Path, typer.Argument(help="The trace: CSV (header of propositions) or JSONL.")
    ],
    as_json: Annotated[bool, typer.Option("--json", help="One JSON object per step.")] = False,
    max_states: MaxStatesOpt = DEFAULT_MAX_STATES,
    time_limit: TimeLimitOpt = DEFAULT_TIME_LIMIT,
) -> None:
    """Print the three-valued verdict (satisfied, violated, pending) after each step of a trace."""
    from mitlc.automata import compile_formula
    from mitlc.automata.runs import run_states
    from mitlc.traces import read_trace

    formula = load_formula(spec, None)
    letters = read_trace(trace, propositions=atoms(formula))
    deadline = command_deadline(time_limit, "monitor")
    digital = compile_formula(formula, max_states=max_states, deadline=deadline).digital
    states = run_states(digital, letters)
    for step, (letter, state) in enumerate(zip(letters, states[1:], strict=True)):
        verdict = digital.states[state].verdict
        true = sorted(letter & set(digital.propositions))
        if as_json:
            row = {"step": step, "true": true, "verdict": verdict}
            typer.echo(json.dumps(row, sort_keys=True))
        else:
            typer.echo(f"{step:>5}  {verdict:<9}  {'{' + ', '.join(true) + '}'}")


@app.command(name="schema")
@reports_errors
def schema_command(
    kind: Annotated[
        str,
        typer.Argument(
            help="Which schema: 'world' (a grid), 'env-world' (a gymnasium env), "
            "'plane-world' (a continuous room) or 'team-world' (robots on a grid)."
        ),
    ] = "world",
) -> None:
    """Print the JSON schema of world files, for editors."""
    from mitlc.worlds.schemas import SCHEMA_KINDS, world_json_schema

    if kind not in SCHEMA_KINDS:
        raise UsageError(f"mitlc: unknown schema {kind!r}; one of {', '.join(SCHEMA_KINDS)}")
    typer.echo(json_dumps(world_json_schema(kind)))


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


register_checking(app, reports_errors)
register_learning(app, reports_errors)
register_sweeps(app, reports_errors)


def main() -> None:
    """The console script's entry point."""
    one_command_per_process()
    try:
        app()
    except SystemExit as done:
        exit_now(done.code if isinstance(done.code, int) else 1)
        raise
