"""The ``mitlc`` command: the only module that prints or exits.

Every command turns mitlc's typed errors into a message on standard error and exit status 1;
usage errors exit with status 2, as Click does.
"""

from __future__ import annotations

import functools
import json
import sys
from collections.abc import Callable
from enum import StrEnum
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, ParamSpec, TypeVar

import typer

from mitlc import __version__
from mitlc.automata import DEFAULT_MAX_STATES, DigitalAutomaton, compile_formula
from mitlc.automata.artifact import from_data, to_json
from mitlc.automata.dot import render, to_dot, write_atomically
from mitlc.automata.hoa import to_hoa, to_hoa_stream
from mitlc.automata.runs import run_states
from mitlc.cli_learn import register as register_learning
from mitlc.errors import MitlcError
from mitlc.limits import CLI_HOW, DEFAULT_TIME_LIMIT, Deadline, LimitError
from mitlc.product.explicit import DEFAULT_MAX_PRODUCT_STATES
from mitlc.syntax import Formula, ast_to_data, atoms, parse, parse_batch_file, read_spec, to_text
from mitlc.syntax.tree import tree_text
from mitlc.traces import TraceError, read_trace, read_trace_text, trace_columns
from mitlc.worlds.model import World

if TYPE_CHECKING:
    from mitlc.check.observed import ObservedBound
    from mitlc.product.explicit import Product

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
            name = f"{err.filename}: " if err.filename is not None else ""
            typer.echo(f"mitlc: {name}{err.strerror or err}", err=True)
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
        return parse(read_spec(sys.stdin.buffer, "<stdin>"), "<stdin>")
    return parse(read_spec(spec), spec)


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


class Format(StrEnum):
    """Output formats of ``mitlc compile``."""

    json = "json"
    dot = "dot"
    hoa = "hoa"


MaxStatesOpt = Annotated[
    int,
    typer.Option(
        "--max-states", min=1, help="Stop a translation that grows past this many states."
    ),
]
TimeLimitOpt = Annotated[
    float,
    typer.Option(
        "--time-limit",
        min=0,
        metavar="SECONDS",
        help="Stop the command after this many seconds (0: no limit).",
    ),
]


def _deadline(seconds: float, command: str) -> Deadline:
    """The time limit of one command (``--time-limit``)."""
    return Deadline(seconds, f"mitlc {command}", CLI_HOW)


OutOpt = Annotated[
    Path | None, typer.Option("--output", "-o", help="Write here (atomically) instead of stdout.")
]


def _emit(text: str, output: Path | None) -> None:
    if output is None:
        typer.echo(text, nl=False)
    else:
        write_atomically(output, text.encode("utf-8"))


@app.command(name="compile")
@_reports_errors
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
    deadline = _deadline(time_limit, "compile")
    if batch is not None:
        if spec is not None or expr is not None:
            raise UsageError("mitlc: --batch reads its formulas from FILE; give no SPEC or -e")
        _emit(_compile_batch(batch, fmt, max_states, deadline), output)
        return
    compiled = compile_formula(load_formula(spec, expr), max_states=max_states, deadline=deadline)
    if fmt is Format.hoa:
        text = to_hoa(compiled.digital)
    elif fmt is Format.dot:
        text = to_dot(compiled.timed)
    else:
        text = to_json(compiled.timed)
    _emit(text, output)


def _compile_batch(path: Path, fmt: Format, max_states: int, deadline: Deadline) -> str:
    compiled = [
        compile_formula(f, max_states=max_states, deadline=deadline)
        for f in parse_batch_file(path)
    ]
    if fmt is Format.hoa:
        return to_hoa_stream(c.digital for c in compiled)
    if fmt is Format.dot:
        raise UsageError("mitlc: --batch writes json (JSON Lines) or hoa")
    return "".join(to_json(c.timed, indent=None) for c in compiled)


@app.command(name="render")
@_reports_errors
def render_command(
    source: Annotated[
        str | None,
        typer.Argument(help="A spec file, '-' for standard input, or an AUTOMATON.json artifact."),
    ] = None,
    expr: ExprOpt = None,
    output: Annotated[
        Path, typer.Option("--output", "-o", help="FILE.png, FILE.svg or FILE.dot.")
    ] = Path("automaton.png"),
    max_states: MaxStatesOpt = DEFAULT_MAX_STATES,
    time_limit: TimeLimitOpt = DEFAULT_TIME_LIMIT,
) -> None:
    """Draw the timed LDGBA of a formula or of a compiled artifact."""
    if source is not None and source.endswith(".json"):
        try:
            data = json.loads(Path(source).read_bytes())
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
            max_states=max_states,
            deadline=_deadline(time_limit, "render"),
        ).timed
    render(to_dot(timed), output)
    typer.echo(f"wrote {output}", err=True)


@app.command()
@_reports_errors
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
    formula = load_formula(spec, None)
    text = read_trace_text(trace)
    columns = trace_columns(trace, text)
    missing = sorted(set(atoms(formula)) - columns) if columns is not None else []
    if missing:
        raise TraceError(f"{trace}: no column for the spec's proposition(s) {', '.join(missing)}")
    letters = read_trace(trace, text)
    deadline = _deadline(time_limit, "monitor")
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


@app.command(name="check")
@_reports_errors
def check_command(
    world_file: Annotated[Path, typer.Argument(metavar="WORLD", help="A world file (YAML).")],
    spec: Annotated[
        str | None, typer.Option("--spec", help="A spec file instead of the world's own task.")
    ] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print the report as JSON.")] = False,
    policy: Annotated[
        Path | None, typer.Option(
            "--policy",
            help="Write the optimal policy (JSON) here; for a POMDP, the observation-based one.",
        )
    ] = None,
    export_drn: Annotated[
        Path | None, typer.Option("--export-drn", help="Write the product in Storm's DRN format.")
    ] = None,
    export_dot: Annotated[
        Path | None,
        typer.Option("--export-dot", help="Draw a small product (at most 2,000 states) as DOT."),
    ] = None,
    pomdp_bounds: Annotated[
        bool,
        typer.Option(
            "--pomdp-bounds/--no-pomdp-bounds",
            help="For a POMDP world, add Storm's belief-exploration bounds (needs stormpy).",
        ),
    ] = True,
    max_states: MaxStatesOpt = DEFAULT_MAX_STATES,
    max_product_states: Annotated[
        int,
        typer.Option(
            "--max-product-states",
            min=1,
            help="Refuse a product that may have more states than this (world x automaton).",
        ),
    ] = DEFAULT_MAX_PRODUCT_STATES,
    time_limit: TimeLimitOpt = DEFAULT_TIME_LIMIT,
) -> None:
    """Check a world exactly: the best probability of doing its task, and a policy for it."""
    from mitlc.check import check
    from mitlc.check.drn import to_drn
    from mitlc.worlds import load_world

    world = load_world(world_file)
    if spec is not None:
        from mitlc.product import relabel
        from mitlc.worlds import read_world_file

        formula = load_formula(spec, None)
        try:
            labels = read_world_file(world_file).labels
            world = relabel(world, labels, to_text(formula))
        except ValueError as err:
            raise UsageError(f"{world_file}: the spec {spec}: {err}") from None
    else:
        formula = parse(world.spec, world.spec_source)
    deadline = _deadline(time_limit, "check")
    digital = compile_formula(formula, max_states=max_states, deadline=deadline).digital
    if world.is_pomdp:
        typer.echo(
            "note: a POMDP world; pmax and pmax_horizon are the fully observable upper bounds, "
            "pmax_horizon_observed the exact success of an observation-based policy (a lower "
            "bound)",
            err=True,
        )
    report = check(world, digital, max_product_states=max_product_states, deadline=deadline)
    if export_drn is not None:
        write_atomically(export_drn, to_drn(report.product).encode("utf-8"))
    if export_dot is not None:
        from mitlc.check.drn import to_product_dot

        try:
            dot = to_product_dot(report.product, list(world.cells), world.actions)
        except ValueError as err:
            raise UsageError(f"mitlc: --export-dot: {err}") from None
        write_atomically(export_dot, dot.encode("utf-8"))
    summary = report.summary()
    observed, why = _observed(world, report.product, deadline) if world.is_pomdp else (None, "")
    if world.is_pomdp:
        summary["pmax_horizon_observed"] = observed.value if observed is not None else why
    if policy is not None:
        if observed is not None:
            data: object = _observed_policy(world, observed)
        elif world.is_pomdp:
            raise UsageError(f"mitlc: --policy: no observation-based policy ({why})")
        else:
            data = report.policy_data(world)
        write_atomically(policy, (_json_dumps(data) + "\n").encode("utf-8"))
    if world.is_pomdp and pomdp_bounds:
        summary["bounds"] = _pomdp_bounds(world, digital, max_product_states, deadline)
    if as_json:
        typer.echo(_json_dumps(summary))
        return
    width = max(len(k) for k in summary)
    for key, value in summary.items():
        shown = f"{value:.6f}" if isinstance(value, float) else str(value)
        if isinstance(value, dict) and "lower" in value:
            shown = f"[{value['lower']:.6f}, {value['upper']:.6f}] ({value['method']})"
        typer.echo(f"{key:<{width}}  {shown}")


def _observed(
    world: World, product: Product, deadline: Deadline
) -> tuple[ObservedBound | None, str]:
    """The best observation-based policy found and its exact success, or why there is none
    (its time limit included: the exact results above it stand)."""
    from mitlc.check.observed import ObservedBoundError, observed_bound

    try:
        stage = deadline.at("the observation-based bound")
        return observed_bound(world, product, deadline=stage), ""
    except (ObservedBoundError, LimitError) as err:
        return None, f"unavailable: {err}"


def _observed_policy(world: World, found: ObservedBound) -> dict[str, object]:
    """The observation-based policy as data: an action per step, observation and automaton
    state that it meets."""
    assert world.observations is not None
    names = world.observations.names
    return {
        "kind": "observation-based",
        "pmax_horizon_observed": found.value,
        "rows": [
            {
                "step": t,
                "observation": names[o],
                "automaton_state": q,
                "action": world.actions[a],
            }
            for t, o, q, a in found.rows()
        ],
    }


def _pomdp_bounds(
    world: World, digital: DigitalAutomaton, max_product_states: int, deadline: Deadline
) -> dict[str, object]:
    """Storm's lower and upper bounds of the POMDP's optimum, or why there are none (its time
    limit included)."""
    from mitlc.check.pomdp import pomdp_bounds, unavailable_reason

    try:
        found = pomdp_bounds(
            world, digital, max_product_states=max_product_states, deadline=deadline
        )
    except (ValueError, LimitError) as err:
        return {"unavailable": str(err)}
    if found is None:
        return {"unavailable": unavailable_reason() or "stormpy.pomdp is not installed"}
    keys = ("lower", "upper", "lower_complete", "upper_complete", "method")
    return {k: found[k] for k in keys if k in found}


@app.command(name="schema")
@_reports_errors
def schema_command(
    kind: Annotated[str, typer.Argument(help="Which schema: 'world'.")] = "world",
) -> None:
    """Print the JSON schema of world files, for editors."""
    if kind != "world":
        raise UsageError(f"mitlc: unknown schema {kind!r}; the one schema is 'world'")
    from mitlc.worlds import world_json_schema

    typer.echo(_json_dumps(world_json_schema()))


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


register_learning(app, _reports_errors)


def main() -> None:
    """The console script's entry point."""
    app()
