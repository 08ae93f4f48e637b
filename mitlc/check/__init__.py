"""Exact checking of a world against its task: ``check(world, automaton) -> CheckReport``."""

from __future__ import annotations

import time
from dataclasses import dataclass
from types import EllipsisType
from typing import Any

from mitlc.check.costs import LeastCost, least_cost
from mitlc.check.solve import Solution, pmax, pmax_horizon
from mitlc.limits import DEFAULT_MAX_PRODUCT_STATES, DEFAULT_TIME_LIMIT, Deadline
from mitlc.product.costs import product_costs
from mitlc.product.explicit import Product, build_product, start_average, start_distribution
from mitlc.task import TaskAutomaton
from mitlc.worlds.model import FloatArray, World


@dataclass(frozen=True, slots=True)
class CheckReport:
    """What ``mitlc check`` reports, and the optimal memoryless policy for ``pmax``."""

    world: str
    spec: str
    product: Product
    pmax: float
    pmax_horizon: float
    horizon: int
    seconds: float
    solution: Solution
    cost: LeastCost | None = None
    """For a world with costs: the least expected cost within the horizon among the policies
    of best success (:mod:`mitlc.check.costs`), and that policy."""
    horizon_values: FloatArray | None = None
    """Per product state, the best success within the whole horizon from it (the first
    round's values: no acceptance set seen yet); ``pmax_horizon`` is their start average."""

    @property
    def product_states(self) -> int:
        """Reachable product states (the absorbing violated and satisfied ones included)."""
        return self.product.num_states

    @property
    def product_transitions(self) -> int:
        """Non-zero transition probabilities of the product."""
        return self.product.num_transitions

    def summary(self) -> dict[str, Any]:
        """The report as JSON-ready data."""
        return {
            "world": self.world,
            "spec": self.spec,
            "product_states": self.product_states,
            "product_choices": self.product.num_choices,
            "product_transitions": self.product_transitions,
            "acceptance_sets": self.product.num_sets,
            "pmax": self.pmax,
            "pmax_horizon": self.pmax_horizon,
            **({"min_cost_horizon": self.cost.value} if self.cost is not None else {}),
            "horizon": self.horizon,
            "seconds": round(self.seconds, 6),
            **self._starts(),
        }

    def _starts(self) -> dict[str, Any]:
        """For a drawn start: how many start states the probabilities are averaged over."""
        starts = self.product.initial_distribution
        if len(starts) <= 1:
            return {}
        return {"start_states": len(starts)}

    def start_cells(self, world: World) -> list[dict[str, Any]]:
        """For a drawn start, per start cell (in cell order): its probability, and ``pmax``
        and ``pmax_horizon`` from it (averaged over the states of the cell, the outcomes of
        its uncertain labels: :mod:`mitlc.worlds.uncertain`)."""
        product, horizon = self.product, self.horizon_values
        starts = start_distribution(world)
        pairs = list(zip(starts, product.starts, strict=False))
        if len(product.starts) != len(starts):  # decided at the start: one absorbing state
            pairs = [(sp, product.starts[0]) for sp in starts]
        cells: dict[tuple[int, ...], list[float]] = {}
        for (s, p), (x, _) in pairs:
            found = cells.setdefault(tuple(world.cells[s]), [0.0, 0.0, 0.0])
            found[0] += p
            found[1] += p * float(self.solution.values[x])
            found[2] += p * (float(horizon[x]) if horizon is not None else float("nan"))
        return [
            {"cell": list(cell), "probability": p, "pmax": a / p, "pmax_horizon": b / p}
            for cell, (p, a, b) in sorted(cells.items())
        ]

    def policy_data(
        self, world: World, automaton: TaskAutomaton | None = None
    ) -> list[dict[str, Any]]:
        """The optimal policy: for each product state, the world cell, automaton state (with
        its obligation when ``automaton`` is given: a lazy automaton numbers its states in the
        order the product reached them) and the action (a world action's name, or ``jump:q``
        for an epsilon jump)."""
        rows = []
        product = self.product
        for x in range(product.num_states):
            s = int(product.world_state[x])
            if s < 0:
                continue
            choice = int(self.solution.policy[x])
            action = int(product.action[choice])
            rows.append(
                {
                    "cell": list(world.cells[s]),
                    "automaton_state": int(product.automaton_state[x]),
                    **(
                        {"obligation": automaton.obligation(int(product.automaton_state[x]))}
                        if automaton is not None
                        else {}
                    ),
                    "action": world.actions[action] if action >= 0 else f"jump:{-1 - action}",
                    "value": float(self.solution.values[x]),
                }
            )
        return rows


def check(
    world: World,
    automaton: TaskAutomaton,
    *,
    max_product_states: int | None = DEFAULT_MAX_PRODUCT_STATES,
    time_limit: float | None = DEFAULT_TIME_LIMIT,
    memory_limit: float | EllipsisType | None = ...,
    deadline: Deadline | None = None,
) -> CheckReport:
    """Build the product and compute ``pmax`` and ``pmax_horizon`` with an optimal policy,
    and, for a world with costs, the least expected cost among the policies of best success
    within the horizon (:func:`mitlc.check.costs.least_cost`).

    Refuses a product past ``max_product_states``
    (:class:`mitlc.product.explicit.ProductSizeError`); stops with
    :class:`mitlc.limits.LimitError` after ``time_limit`` seconds
    or past ``memory_limit`` GB held for all three stages together
    (``None``: no limit), or at ``deadline`` when one is given."""
    start = time.perf_counter()
    clock = Deadline.of(deadline, time_limit, "check", memory_limit)
    product = build_product(world, automaton, max_product_states=max_product_states, deadline=clock)
    costs = None if world.costs is None else product_costs(world, automaton, product)
    solution = pmax(product, deadline=clock.at("pmax"))
    within, history = pmax_horizon(
        product,
        world.horizon,
        keep_history=costs is not None,
        deadline=clock.at("pmax_horizon"),
        layered=solution.layers,
    )
    cost = None
    if costs is not None:
        stage = clock.at("the least cost")
        cost = least_cost(product, costs.choice, world.horizon, values=history, deadline=stage)
    return CheckReport(
        world=world.name,
        spec=automaton.formula,
        product=product,
        pmax=start_average(product, solution.values),
        pmax_horizon=within,
        horizon=world.horizon,
        seconds=time.perf_counter() - start,
        solution=solution,
        cost=cost,
        horizon_values=history[-1][0],
    )
