"""``mitlc check``: a world checked exactly, with the POMDP bounds where the world has them."""

# No `from __future__ import annotations` here: typer reads every command's annotations at each
# start (all commands, for any one), and evaluating them once at import spares it compiling and
# evaluating them as strings (about 10 ms of the start-up; bench/startup_bench.py).

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from mitlc.cli_common import (
    MaxStatesOpt,
    TaskExprOpt,
    TaskSpecOpt,
    TimeLimitOpt,
    TrustWorldOpt,
    UsageError,
    command_deadline,
    json_dumps,
    task_formula,
)
from mitlc.limits import (
    DEFAULT_MAX_PRODUCT_STATES,
    DEFAULT_MAX_STATES,
    DEFAULT_TIME_LIMIT,
    Deadline,
    LimitError,
)
from mitlc.syntax import parse, to_text

if TYPE_CHECKING:
    from mitlc.check.observed import ObservedBound
    from mitlc.product.explicit import Product
    from mitlc.task import TaskAutomaton
    from mitlc.worlds.model import World


def check_command(
    world_file: Annotated[Path, typer.Argument(metavar="WORLD", help="A world file (YAML).")],
    spec: TaskSpecOpt = None,
    expr: TaskExprOpt = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print the report as JSON.")] = False,
    policy: Annotated[
        Path | None,
        typer.Option(
            "--policy",
            help="Write the optimal policy (JSON) here; for a POMDP, the observation-based one; "
            "for a world with costs, the one of least cost among the best (per step).",
        ),
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
    trust_world: TrustWorldOpt = False,
) -> None:
    """Check a world exactly: the best probability of doing its task, and a policy for it."""
    from mitlc.automata import LazyAutomaton
    from mitlc.check import check
    from mitlc.check.drn import to_drn
    from mitlc.files import write_atomically
    from mitlc.task.horizon import short_horizon_note
    from mitlc.worlds import load_world

    formula = task_formula(spec, expr)
    if formula is not None:
        world = load_world(world_file, to_text(formula))
    else:
        world = load_world(world_file)
        formula = parse(world.spec, world.spec_source)
    deadline = command_deadline(time_limit, "check")
    note = short_horizon_note(formula, world.horizon)
    if note is not None:
        typer.echo(note, err=True)
    # The automaton is made lazily: only the states and letters the world reaches (a task over
    # many propositions never builds its 2^n letters, nor its folded form, here).
    digital = LazyAutomaton(formula, max_states=max_states, deadline=deadline)
    if world.is_pomdp:
        typer.echo(
            "note: a POMDP world; pmax and pmax_horizon are the fully observable upper bounds, "
            "pmax_horizon_observed the exact success of an observation-based policy (a lower "
            "bound)",
            err=True,
        )
    report = check(world, digital, max_product_states=max_product_states, deadline=deadline)
    if export_drn is not None:
        costs = None if report.cost is None else report.cost.immediate
        write_atomically(export_drn, to_drn(report.product, costs).encode("utf-8"))
    if export_dot is not None:
        from mitlc.check.drn import to_product_dot

        try:
            dot = to_product_dot(report.product, list(world.cells), world.actions)
        except ValueError as err:
            raise UsageError(f"mitlc: --export-dot: {err}") from None
        write_atomically(export_dot, dot.encode("utf-8"))
    summary = report.summary()
    if "start_states" in summary:
        typer.echo(
            f"note: the start is drawn from {summary['start_states']} states; pmax and "
            "pmax_horizon are averaged over the start distribution (per start cell: --json)",
            err=True,
        )
    if as_json and "start_states" in summary:
        summary["start_cells"] = report.start_cells(world)
    observed, why = _observed(world, report.product, deadline) if world.is_pomdp else (None, "")
    if world.is_pomdp:
        summary["pmax_horizon_observed"] = observed.value if observed is not None else why
    if policy is not None:
        if observed is not None:
            data: object = _observed_policy(world, observed)
        elif world.is_pomdp:
            raise UsageError(f"mitlc: --policy: no observation-based policy ({why})")
        elif report.cost is not None:
            from mitlc.check.costs import policy_data

            data = policy_data(report.cost, report.product, world, digital)
        else:
            data = report.policy_data(world, digital)
        write_atomically(policy, (json_dumps(data) + "\n").encode("utf-8"))
    if world.is_pomdp and pomdp_bounds:
        summary["bounds"] = _pomdp_bounds(world, digital, max_product_states, deadline)
    if as_json:
        typer.echo(json_dumps(summary))
        return
    width = max(len(k) for k in summary)
    for key, value in summary.items():
        shown = f"{value:.6f}" if isinstance(value, float) else str(value)
        if isinstance(value, dict) and "lower" in value:
            shown = f"[{value['lower']:.6f}, {value['upper']:.6f}] ({value['method']})"
        typer.echo(f"{key:<{width}}  {shown}")


def _observed(
    world: "World", product: "Product", deadline: Deadline
) -> "tuple[ObservedBound | None, str]":
    """The best observation-based policy found and its exact success, or why there is none
    (its time limit included: the exact results above it stand)."""
    from mitlc.check.observed import ObservedBoundError, observed_bound

    try:
        stage = deadline.at("the observation-based bound")
        return observed_bound(world, product, deadline=stage), ""
    except (ObservedBoundError, LimitError) as err:
        return None, f"unavailable: {err}"


def _observed_policy(world: "World", found: "ObservedBound") -> dict[str, object]:
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
    world: "World", digital: "TaskAutomaton", max_product_states: int, deadline: Deadline
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


def register(app: typer.Typer, reports_errors: Callable[[Any], Any]) -> None:
    """Add ``check`` to ``app``."""
    app.command(name="check")(reports_errors(check_command))
