"""The least expected cost within the horizon among the policies of best success:
``least_cost(product, costs, horizon)``.

Lexicographic optimisation over a finite horizon: success first, then cost. Among the
policies whose probability of success within ``H`` steps is ``pmax_horizon`` (the best), the
least expected total cost of the steps taken (:func:`mitlc.product.costs.product_costs`), by
the standard backward induction for lexicographic objectives on a finite-horizon MDP: restrict
each state's choices to those optimal for the first objective, then optimise the second over
what remains (Puterman, *Markov Decision Processes*, 1994, ch. 4; as the lexicographic
reachability-safety games of Chatterjee, Katoen, Weininger and Winkler, "Stochastic games
with lexicographic reachability-safety objectives", CAV 2020, restrict to the optimal
actions of each objective in turn). A time-dependent policy with a choice per step left,
frontier and product state is optimal for both (no randomisation is needed: the restriction is
made exactly, not with a threshold).

With ``V[r][mask, x]`` the best success within ``r`` steps (:func:`mitlc.check.solve.pmax_horizon`'s
history) and ``C[0] = 0``, a step more left gives, for a world choice ``c`` of ``x`` (``mask'``
the frontier after its marks)

    q_V(c) = sum_y P(c, y) V[r-1][mask', y]      q_C(c) = cost(c) + sum_y P(c, y) C[r-1][mask', y]

and ``C[r][mask, x]`` is the least cost among the choices of ``x`` whose success value is
optimal, world actions and epsilon jumps alike: a world choice ``c`` with ``q_V(c) >=
V[r][mask, x]`` offers ``q_C(c)``, and a jump to ``t`` (no step, no cost) with ``V[r][mask, t] >=
V[r][mask, x]`` offers ``C[r][mask, t]`` (both within :data:`TOLERANCE`, relative; the jumps in
``pmax_horizon``'s order). A choice that is not optimal is never taken, however cheap: where
the optimum needs a jump (no world choice reaches ``V[r][mask, x]``), the jump is taken
whatever it costs. Nothing is paid once the task is decided: the absorbing states cost 0. The
value reported is ``C[H][0]`` averaged over the start distribution.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from typing import Any

import numpy as np

from mitlc.check.solve import jumps_in_order, mask_matrices, pmax_horizon
from mitlc.limits import Deadline
from mitlc.product.explicit import SATISFIED, VIOLATED, Product, start_average
from mitlc.task.monitor import TaskAutomaton
from mitlc.worlds.model import FloatArray, IntArray, World

TOLERANCE = 1e-12
"""A choice is optimal for success when its value is within this share of the best."""


@dataclass(frozen=True, slots=True)
class LeastCost:
    """The least expected cost among the policies of best success, and the policy."""

    value: float
    """``C[H][0]`` averaged over the start distribution."""
    horizon: int
    costs: list[FloatArray]
    """``costs[r][mask, x]``: the least expected cost with ``r`` steps left."""
    choices: list[IntArray]
    """``choices[r][mask, x]``: the product choice taken with ``r >= 1`` steps left
    (``choices[0]`` is empty: with no step left nothing is taken)."""
    values: list[FloatArray]
    """``values[r][mask, x]``: the best success within ``r`` steps (``pmax_horizon``'s)."""
    immediate: FloatArray
    """``immediate[c]``: the expected immediate cost of choice ``c`` (the input)."""


def least_cost(
    product: Product,
    costs: FloatArray,
    horizon: int,
    *,
    values: list[FloatArray] | None = None,
    deadline: Deadline | None = None,
) -> LeastCost:
    """The least expected total cost within ``horizon`` steps among the policies of best
    success, with ``costs[c]`` the expected immediate cost of choice ``c``
    (:attr:`mitlc.product.costs.ProductCosts.choice`); see the module docstring. ``values``:
    ``pmax_horizon(product, horizon)``'s history when the caller has it. Reads ``deadline`` at
    every step (:class:`mitlc.limits.LimitError` at its time limit) and reserves the tables
    (a cost and a choice per step, frontier and state) before making them."""
    clock = Deadline.none() if deadline is None else deadline
    if values is None:
        _, values = pmax_horizon(product, horizon, deadline=clock)
    masks, n = 1 << product.num_sets, product.num_states
    clock.reserve((horizon + 1) * masks * n * 16, "the cost tables")
    step = _Step(product, costs)
    tables = [np.zeros((masks, n))]
    choices = [np.zeros((0, 0), dtype=np.int64)]
    for r in range(1, horizon + 1):
        clock.check_now()
        cost, choice = step.back(values[r - 1], values[r], tables[-1])
        tables.append(cost)
        choices.append(choice)
    value = start_average(product, tables[horizon][0])
    return LeastCost(value, horizon, tables, choices, values[: horizon + 1], costs)


class _Step:
    """One step of the backward induction (see the module docstring)."""

    def __init__(self, product: Product, costs: FloatArray) -> None:
        self.product, self.costs = product, costs
        self.matrices = mask_matrices(product)
        self.ptr = product.choice_ptr[:-1]
        self.owner = np.repeat(np.arange(product.num_states), np.diff(product.choice_ptr))
        self.is_jump = product.action < 0
        self.jumps = jumps_in_order(product)
        self.index = np.arange(product.num_choices)
        sources = np.array([s for s, _, _ in self.jumps], dtype=np.int64)
        targets = np.array([t for _, t, _ in self.jumps], dtype=np.int64)
        self.jump_sources, self.jump_targets = sources, targets
        # Some jump leads to a state with jumps of its own (none in a limit-deterministic
        # automaton's product, whose jumps all leave the initial component): then the jumps
        # are relaxed until nothing changes, not once.
        self.chained = bool(np.isin(targets, sources).any())

    def back(
        self, before: FloatArray, best: FloatArray, later: FloatArray
    ) -> tuple[FloatArray, IntArray]:
        """``C[r]`` and the choices taken, from ``V[r-1]`` (``before``), ``V[r]`` (``best``)
        and ``C[r-1]`` (``later``).

        Only the choices whose success value is optimal are candidates, world actions and
        jumps alike: a world action by its ``q_V``, a jump by its target's ``V[r]``. Where
        no world action is optimal (the optimum needs a jump) the state's world cost is
        infinite and an optimal jump replaces it whatever it costs."""
        owner, ptr, world = self.owner, self.ptr, ~self.is_jump
        q_v = np.stack([m @ before.ravel() for m in self.matrices])
        q_c = np.stack([self.costs + m @ later.ravel() for m in self.matrices])
        goal = self._goal(q_v, best)
        masked = np.where(world & (q_v >= goal[:, owner]), q_c, np.inf)
        cost = np.minimum.reduceat(masked, ptr, axis=1)
        first = np.where(masked <= cost[:, owner], self.index, self.product.num_choices)
        choice = np.minimum.reduceat(first, ptr, axis=1)
        changed = True
        while changed:  # one pass, in pmax_horizon's order (_settle), unless jumps chain
            changed = False
            for source, target, c in self.jumps:
                better = (best[:, target] >= goal[:, source]) & (cost[:, target] < cost[:, source])
                if better.any():
                    cost[:, source] = np.where(better, cost[:, target], cost[:, source])
                    choice[:, source] = np.where(better, c, choice[:, source])
                    changed = self.chained
        cost[:, SATISFIED] = cost[:, VIOLATED] = 0.0
        return cost, choice

    def _goal(self, q_v: FloatArray, best: FloatArray) -> FloatArray:
        """Per mask and state, the success value a choice must reach to be a candidate:
        ``V[r]`` less :data:`TOLERANCE` (relative), or, where rounding left every choice a
        hair below it, the best the choices reach (their ``q_V``, a jump's target's ``V[r]``)
        less the same tolerance, so that some choice always qualifies."""
        top = np.maximum.reduceat(np.where(self.is_jump, -1.0, q_v), self.ptr, axis=1)
        if len(self.jumps):
            np.maximum.at(top.T, self.jump_sources, best[:, self.jump_targets].T)
        goal: FloatArray = np.minimum(best, top) * (1.0 - TOLERANCE)
        return goal


def policy_data(
    found: LeastCost,
    product: Product,
    world: World,
    automaton: TaskAutomaton | None = None,
) -> dict[str, Any]:
    """The lexicographic policy as data: for each step ``t`` (``H - t`` steps left), each
    (frontier, product state) the policy reaches then with positive probability from the
    start, the world cell, automaton state (and its obligation when ``automaton`` is given),
    the action taken (a world action's name, or ``jump:q`` for an epsilon jump), and the best
    success and least expected cost from there. Decided states (the task satisfied or
    violated) have no row: the episode is over."""
    horizon, t = found.horizon, product.transitions
    rows = []
    layer = {(0, x) for x, _ in product.starts}
    for step in range(horizon):
        r = horizon - step
        queue, seen = deque(sorted(layer)), set(layer)
        after: set[tuple[int, int]] = set()
        while queue:
            mask, x = queue.popleft()
            if x in (SATISFIED, VIOLATED):
                continue
            c = int(found.choices[r][mask, x])
            action = int(product.action[c])
            rows.append(_row(found, product, world, automaton, (step, r, mask, x), action))
            targets = t.targets[int(t.indptr[c]) : int(t.indptr[c + 1])].tolist()
            if action < 0:
                if (mask, targets[0]) not in seen:
                    seen.add((mask, targets[0]))
                    queue.append((mask, targets[0]))
                continue
            moved = mask | int(product.marks[c])
            after.update((moved, y) for y in targets)
        layer = after
    return {
        "kind": "lexicographic",
        "horizon": horizon,
        "pmax_horizon": start_average(product, found.values[horizon][0]),
        "min_cost_horizon": found.value,
        "rows": rows,
    }


def _row(
    found: LeastCost,
    product: Product,
    world: World,
    automaton: TaskAutomaton | None,
    where: tuple[int, int, int, int],
    action: int,
) -> dict[str, Any]:
    step, r, mask, x = where
    q = int(product.automaton_state[x])
    return {
        "step": step,
        "cell": list(world.cells[int(product.world_state[x])]),
        "automaton_state": q,
        **({"obligation": automaton.obligation(q)} if automaton is not None else {}),
        **({"frontier": mask} if product.num_sets else {}),
        "action": world.actions[action] if action >= 0 else f"jump:{-1 - action}",
        "success": float(found.values[r][mask, x]),
        "cost": float(found.costs[r][mask, x]),
    }
