"""Storm's belief-exploration bounds on the maximal probability of the task in a POMDP world.

The agent observes the world's observation and the automaton state (the automaton is the
agent's own memory, so it knows it). Storm wants the observation to be a function of the
state, so the product POMDP splits each product state ``(s, q)`` by the observation ``o``
emitted on entering it: its states are ``(s, q, o)`` with ``o ~ observations.model.row(s)``,
the observation probabilities multiplied into the transitions, and the observation id is the
pair ``(o, q)``. A fresh initial state (its own observation, one choice) samples the
start state (the world's start distribution) and its observation. The absorbing
``violated`` and ``satisfied`` states get observations of their own.

The property is reachability, which is what Storm's POMDP checkers take: ``Pmax=? [F
"satisfied"]``. This equals the task's probability under *every* policy when the product MDP
has no way to meet the acceptance condition without reaching ``satisfied`` (checked with
Storm on the fully observable product: ``Pmax=? [(G !"satisfied") & acceptance] = 0``; for
zero acceptance sets, the acceptance is ``G !"violated"``, so the check says that no policy
can stay pending forever with positive probability). This holds for the bounded co-safety
tasks of the paper; otherwise :func:`pomdp_bounds` raises :class:`PomdpBoundsError` (a
``ValueError``). Every Storm call goes through :func:`mitlc.check.storm.storm_guard`: Storm's
failures raise :class:`mitlc.check.storm.StormError` (a ``ValueError`` too).

Bounds: ``lower`` from ``stormpy.pomdp.verify_with_belief_unfolding`` (the value of a
finite part of the belief MDP, under-approximating the maximum), ``upper`` from
``stormpy.pomdp.verify_with_belief_discretization`` (a Freudenthal triangulation of the
belief space, over-approximating it). The fully observable ``pmax`` is an upper bound too
(reported beside them; ``upper`` is ``pmax`` when the discretization is skipped).

With ``horizon_success`` a step counter ``t`` (world actions count, epsilon jumps do not)
joins the state and the observation (the agent can count steps), and the probability is of
reaching ``satisfied`` within ``world.horizon`` steps, where a run still pending at the horizon
reaches it when the trace it read satisfies the formula (the end value of its state,
:func:`mitlc.task.rules.success`; a completed round is not tracked here, so for a task with
acceptance sets the bound counts only satisfied and end values).

Time: the product, ``pmax`` and the POMDP's text read a :class:`mitlc.limits.Deadline`; Storm's
unfolding gets the time left as its ``max_exploration_time`` (when that is shorter than the
one asked for); Storm's discretization has no time limit of its own, so it starts only while
time is left and then runs to its end (its size is bounded by ``resolution``).
"""

from __future__ import annotations

import math
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from types import EllipsisType
from typing import Any

from mitlc.automata.ends import END_HOLDS
from mitlc.check.drn import labels_present, reachable, storm_property, to_drn
from mitlc.check.solve import pmax
from mitlc.check.storm import storm_guard
from mitlc.errors import MitlcError
from mitlc.limits import DEFAULT_MAX_PRODUCT_STATES, DEFAULT_TIME_LIMIT, Deadline
from mitlc.product.explicit import (
    SATISFIED,
    VIOLATED,
    Product,
    build_product,
    product_ends,
    start_average,
)
from mitlc.task import TaskAutomaton
from mitlc.worlds.model import World

TARGET_PROPERTY = 'Pmax=? [F "satisfied"]'
"""The reachability property the POMDP checkers are given."""


class PomdpBoundsError(MitlcError, ValueError):
    """The task is not reachability of ``satisfied`` on the product, so Storm's POMDP
    checkers cannot bound it."""


def unavailable_reason() -> str | None:
    """Why Storm's POMDP analysis cannot be used here, or ``None`` when it can."""
    try:
        import stormpy.pomdp
    except ImportError as error:
        return f"stormpy.pomdp is not importable: {error}"
    for name in ("verify_with_belief_unfolding", "verify_with_belief_discretization"):
        if not hasattr(stormpy.pomdp, name):
            return f"stormpy.pomdp has no {name}"
    return None


def to_pomdp_drn(
    world: World, product: Product, horizon: int | None = None, *, deadline: Deadline | None = None
) -> str:
    """The DRN text of the product POMDP (see the module docstring), with labels ``init``,
    ``satisfied`` and ``violated``. With ``horizon``, states carry a step counter up to it;
    pending states at the horizon move to ``satisfied`` where the trace read so far satisfies
    the formula (:func:`mitlc.product.explicit.product_ends`, the success rule of
    :func:`mitlc.task.rules.success` without rounds) or to an absorbing ``timeout`` state.
    ``deadline`` (none by default) is read at every state written."""
    clock = Deadline.none() if deadline is None else deadline
    if world.observations is None:
        raise ValueError(f"world {world.name!r} is not a POMDP")
    obs = world.observations.model
    states: dict[tuple[int, int, int], int] = {}
    """``(product state, observation, step) -> POMDP state``; absorbing: observation -1."""
    observation_ids: dict[tuple[int, int, int], int] = {}
    """``(world observation, automaton state, step) -> observation id``."""
    # reserved: 0 fresh initial, 1 violated, 2 satisfied, 3 timeout
    observation_ids[(-1, -1, -1)] = 0
    observation_ids[(-2, -2, -2)] = 1
    observation_ids[(-3, -3, -3)] = 2
    fixed = {VIOLATED: 1, SATISFIED: 2}
    lines_of: dict[int, list[str]] = {}
    order: list[tuple[int, int, int]] = []
    sink_timeout = horizon is not None
    ends = product_ends(product)
    # POMDP ids: 0 init, 1 violated, 2 satisfied, (3 timeout), then split states
    next_id = 4 if sink_timeout else 3
    if sink_timeout:
        observation_ids[(-4, -4, -4)] = 3

    def successors(y: int, step: int) -> list[tuple[int, float]]:
        """The POMDP states entering product state ``y`` at ``step`` leads to, with the
        observation probabilities."""
        nonlocal next_id
        if y in fixed:
            return [(fixed[y], 1.0)]
        s = int(product.world_state[y])
        out = []
        targets, probs = obs.row(s)
        for o, p in zip(targets.tolist(), probs.tolist(), strict=True):
            key = (y, int(o), step)
            if key not in states:
                states[key] = next_id
                next_id += 1
                order.append(key)
            out.append((states[key], float(p)))
        return out

    t = product.transitions
    drawn: dict[int, float] = {}  # the start states drawn, then their observations
    for x0, p0 in product.starts:
        for z, p in successors(x0, 0):
            drawn[z] = drawn.get(z, 0.0) + p0 * p
    init_choice = list(drawn.items())
    index = 0
    while index < len(order):
        clock.check()
        key = order[index]
        index += 1
        x, o, step = key
        q = int(product.automaton_state[x])
        observation = observation_ids.setdefault(
            (o, q, step if horizon is not None else 0), len(observation_ids)
        )
        body = [f"state {states[key]} {{{observation}}}"]
        at_horizon = horizon is not None and step >= horizon
        for c in range(int(product.choice_ptr[x]), int(product.choice_ptr[x + 1])):
            a = int(product.action[c])
            body.append(f"\taction {world.actions[a] if a >= 0 else f'jump{-1 - a}'}")
            if at_horizon:
                body.append(f"\t\t{2 if ends[x] == END_HOLDS else 3} : 1")
                continue
            after = step + 1 if (a >= 0 and horizon is not None) else step
            merged: dict[int, float] = {}
            for j in range(int(t.indptr[c]), int(t.indptr[c + 1])):
                for z, p in successors(int(t.targets[j]), after):
                    merged[z] = merged.get(z, 0.0) + float(t.probs[j]) * p
            body += [f"\t\t{z} : {p!r}" for z, p in sorted(merged.items())]
        lines_of[states[key]] = body
    nr_states = next_id
    lines_of[0] = ["state 0 {0} init", "\taction sample"] + [
        f"\t\t{z} : {p!r}" for z, p in sorted(init_choice)
    ]
    lines_of[1] = ["state 1 {1} violated", "\taction stay", "\t\t1 : 1"]
    lines_of[2] = ["state 2 {2} satisfied", "\taction stay", "\t\t2 : 1"]
    if sink_timeout:
        lines_of[3] = ["state 3 {3} timeout", "\taction stay", "\t\t3 : 1"]
    choices = sum(
        sum(1 for line in body if line.startswith("\taction")) for body in lines_of.values()
    )
    head = [
        "// mitlc product POMDP",
        "@type: POMDP",
        "@parameters",
        "",
        "@reward_models",
        "",
        "@nr_states",
        str(nr_states),
        "@nr_choices",
        str(choices),
        "@model",
    ]
    body_lines = [line for i in range(nr_states) for line in lines_of[i]]
    return "\n".join(head + body_lines) + "\n"


def _reduction_residual(product: Product, directory: Path) -> float:
    """The maximal probability, on the fully observable product, of meeting the acceptance
    condition without ever reaching ``satisfied`` (0 when reachability of ``satisfied`` is
    the task under every policy), the largest over the start states."""
    import stormpy

    present = labels_present(product)
    inner = storm_property(product)[len("Pmax=? [") : -1]
    never = '(G !"satisfied")' if "satisfied" in present else "(G true)"
    path = directory / "product.drn"
    path.write_text(to_drn(product), encoding="utf-8")
    with storm_guard("the fully observable product"):
        model = stormpy.build_model_from_drn(str(path))
        prop = stormpy.parse_properties(f"Pmax=? [{never} & ({inner})]")[0]
        result = stormpy.model_checking(model, prop, only_initial_states=True)
        values = result.get_value_vector()
        return max(float(values[int(s)]) for s in model.initial_states)


def _environment(precision: str) -> Any:
    """Storm's sound environment, its solvers stopping at the absolute ``precision``."""
    import stormpy
    import stormpy.environments

    with storm_guard(f"its sound environment (precision {precision})"):
        environment = stormpy.environments.sound()
        for solver in (environment.solver().min_max(), environment.solver().native()):
            solver.precision = stormpy.Rational(precision)
            solver.relative_termination_criterion = False
    return environment


def pomdp_bounds(
    world: World,
    automaton: TaskAutomaton,
    *,
    horizon_success: bool = False,
    max_exploration_size: int | None = 100_000,
    max_exploration_time: int | None = 30,
    resolution: int = 2,
    discretize: bool = True,
    precision: str = "1/10000000000",
    max_product_states: int | None = DEFAULT_MAX_PRODUCT_STATES,
    time_limit: float | None = DEFAULT_TIME_LIMIT,
    memory_limit: float | EllipsisType | None = ...,
    deadline: Deadline | None = None,
) -> dict[str, Any] | None:
    """Lower and upper bounds on the maximal probability, over observation-based policies, of
    the task (see the module docstring), or ``None`` when Storm's POMDP analysis is
    unavailable (:func:`unavailable_reason` says why).

    The result: ``lower``, ``upper``, ``upper_discretized`` (Storm's upper bound, or
    ``None`` when skipped), ``pmax`` (fully observable), whether each exploration
    completed, the POMDP's size, the seconds spent, and ``method``. Exploration limits:
    ``max_exploration_size`` beliefs and ``max_exploration_time`` seconds for the unfolding;
    ``resolution`` for the discretization (skipped when not ``discretize``). Storm solves the
    belief MDPs soundly to the absolute ``precision`` (a rational's text). Stops with
    :class:`mitlc.limits.LimitError` after ``time_limit`` seconds
    or past ``memory_limit`` GB held (``None``: no limit), or at
    ``deadline`` when one is given (see the module docstring for Storm's part).
    """
    if unavailable_reason() is not None:
        return None
    start = time.perf_counter()
    clock = Deadline.of(deadline, time_limit, "the POMDP bounds", memory_limit)
    product = build_product(world, automaton, max_product_states=max_product_states, deadline=clock)
    full = start_average(product, pmax(product, deadline=clock.at("pmax")).values)
    model = _pomdp_model(world, product, world.horizon if horizon_success else None, clock)
    built = time.perf_counter()
    time_left = _exploration_time(max_exploration_time, clock.at("Storm's unfolding"))
    lower = _unfolding(model, max_exploration_size, time_left, precision)
    unfolded = time.perf_counter()
    upper: Explored | None = None
    if discretize:
        clock.at("Storm's discretization").check_now()
        upper = _discretization(model, resolution, precision)
    done = time.perf_counter()
    return {
        "lower": lower.value,
        "upper": upper.value if upper is not None else full,
        "upper_discretized": upper.value if upper is not None else None,
        "pmax": full,
        "lower_complete": lower.complete,
        "upper_complete": upper.complete if upper is not None else False,
        "explored_beliefs": lower.beliefs,
        "product_states": len(reachable(product)),
        "pomdp_states": model.nr_states,
        "pomdp_observations": model.nr_observations,
        "seconds_build": built - start,
        "seconds_unfolding": unfolded - built,
        "seconds_discretization": done - unfolded,
        "method": "stormpy.pomdp.verify_with_belief_unfolding (lower), "
        f"verify_with_belief_discretization resolution {resolution} (upper)",
    }


@dataclass(frozen=True, slots=True)
class Explored:
    """What one of Storm's belief explorations found: its bound, whether it explored every
    belief it met, and how many it explored."""

    value: float
    complete: bool
    beliefs: int


def _pomdp_model(world: World, product: Product, horizon: int | None, clock: Deadline) -> Any:
    """Storm's model of the product POMDP (:func:`to_pomdp_drn`, with ``horizon``), once the
    task is known to be reachability of ``satisfied`` on ``product``
    (:class:`PomdpBoundsError` where it is not)."""
    import stormpy
    import stormpy.io

    with tempfile.TemporaryDirectory() as tmp:
        directory = Path(tmp)
        residual = _reduction_residual(product, directory)
        if residual > 1e-9:
            raise PomdpBoundsError(
                "the task is not reachability of 'satisfied' on this product: a policy meets "
                f"the acceptance condition without reaching it w.p. {residual}"
            )
        text = to_pomdp_drn(world, product, horizon, deadline=clock.at("the POMDP's text"))
        path = directory / "pomdp.drn"
        path.write_text(text, encoding="utf-8")
        with storm_guard("the product POMDP"):
            options = stormpy.io.DirectEncodingParserOptions()
            options.build_choice_labeling = True
            return stormpy.build_model_from_drn(str(path), options=options)


def _unfolding(model: Any, max_size: int | None, max_time: int | None, precision: str) -> Explored:
    """Storm's lower bound: the belief unfolding of ``model``, within ``max_size`` beliefs and
    ``max_time`` seconds."""
    import stormpy
    import stormpy.pomdp

    environment = _environment(precision)
    with storm_guard("the belief unfolding of the product POMDP"):
        prop = stormpy.parse_properties(TARGET_PROPERTY)[0]
        result = stormpy.pomdp.verify_with_belief_unfolding(
            model,
            prop,
            max_exploration_size=max_size,
            max_exploration_time=max_time,
            environment=environment,
        )
        return _explored(result)


def _discretization(model: Any, resolution: int, precision: str) -> Explored:
    """Storm's upper bound: the belief discretization of ``model`` at ``resolution``."""
    import stormpy
    import stormpy.pomdp

    environment = _environment(precision)
    with storm_guard(f"the belief discretization (resolution {resolution}) of the product POMDP"):
        prop = stormpy.parse_properties(TARGET_PROPERTY)[0]
        result = stormpy.pomdp.verify_with_belief_discretization(
            model, prop, resolution, environment=environment
        )
        return _explored(result)


def _explored(result: Any) -> Explored:
    """The figures of one of Storm's belief-exploration results."""
    stats = result.statistics
    return Explored(
        float(result.value), bool(stats.completed_exploration), int(stats.explored_beliefs)
    )


def _exploration_time(asked: int | None, deadline: Deadline) -> int | None:
    """Storm's ``max_exploration_time``: the seconds ``asked`` for, or the whole seconds left
    before ``deadline`` when fewer (at least 1; the deadline has passed when none is left)."""
    deadline.check_now()
    left = deadline.remaining()
    if left is None:
        return asked
    seconds = max(1, math.floor(left))
    return seconds if asked is None else min(asked, seconds)
