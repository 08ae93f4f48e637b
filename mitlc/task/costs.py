"""What one step of an episode costs, by a world's costs (:class:`mitlc.worlds.costs.Costs`).

A step leaves position ``s`` (whose letter ``L(s)`` the automaton reads, moving from ``q`` to
``q'``) by world action ``a`` and arrives in ``s'``. It pays

    step + actions[a] + sum of hold[p] over the p in L(s')
                      + sum of start[p] over the p in L(s') but not in L(s)
                      + sum of the costs of the transition rules that (q, L(s), q') matches

(docs/costs.md). An epsilon jump pays nothing; nothing is paid once the task is decided (the
episode is over). The world part is :func:`world_cost`, written with ``+``, ``*``, ``&``,
``~`` and ``>>`` only, so that it runs on one step's ints and on arrays of steps alike (as
:mod:`mitlc.task.rules` does); the automaton part is :meth:`TransitionCosts.cost`, memoised
per (automaton state, letter). :func:`mitlc.product.costs.product_costs` applies both to
every transition of a product.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np

from mitlc.automata.patterns import ObligationPattern, letter_formula, letter_holds
from mitlc.errors import MitlcError
from mitlc.worlds.model import FloatArray, World

if TYPE_CHECKING:
    from mitlc.task.monitor import TaskAutomaton
    from mitlc.worlds.costs import TransitionCost


class CostError(MitlcError, ValueError):
    """A world's costs that cannot apply to its task: a transition rule that no transition
    the world can take matches."""


T = TypeVar("T", int, Any)
"""An int (one step) or a numpy integer array (many)."""


@dataclass(frozen=True, slots=True)
class StepTable:
    """A world's costs per step, per action and per proposition (bit ``i`` of a world letter:
    ``world.propositions[i]``), as arrays."""

    step: float
    action: FloatArray
    hold: FloatArray
    start: FloatArray

    @staticmethod
    def of(world: World) -> StepTable:
        """The table of ``world``'s costs (all zero for a world without costs)."""
        costs = world.costs
        action = np.zeros(world.num_actions)
        hold = np.zeros(len(world.propositions))
        start = np.zeros(len(world.propositions))
        if costs is None:
            return StepTable(0.0, action, hold, start)
        for name, value in costs.actions:
            action[world.actions.index(name)] += value
        for entry in costs.propositions:
            i = world.propositions.index(entry.proposition)
            hold[i] += entry.hold
            start[i] += entry.start
        return StepTable(costs.step, action, hold, start)


def world_cost(table: StepTable, action: T, left: T, arrived: T) -> Any:
    """The world part of the cost of steps taking ``action`` from a position of letter
    ``left`` to one of letter ``arrived`` (see the module docstring)."""
    cost = table.step + table.action[action]
    started = arrived & ~left
    for i in np.flatnonzero(table.hold).tolist():
        cost = cost + table.hold[i] * ((arrived >> i) & 1)
    for i in np.flatnonzero(table.start).tolist():
        cost = cost + table.start[i] * ((started >> i) & 1)
    return cost


class TransitionCosts:
    """The transition rules of ``world``'s costs over ``automaton``: :meth:`cost` of a
    transition, and which rules have matched one so far (:attr:`matched`)."""

    def __init__(self, world: World, automaton: TaskAutomaton) -> None:
        self.automaton = automaton
        self.rules: tuple[TransitionCost, ...] = ()
        if world.costs is not None:
            self.rules = world.costs.transitions
        self._sources = [_pattern(r.source) for r in self.rules]
        self._targets = [_pattern(r.target) for r in self.rules]
        self._whens = [letter_formula(r.when) for r in self.rules]
        self._names = world.propositions
        index = {p: i for i, p in enumerate(world.propositions)}
        self._bits = [(index[p], j) for j, p in enumerate(automaton.propositions) if p in index]
        self.matched = [False] * len(self.rules)
        self._memo: dict[tuple[int, int], float] = {}
        self._states: dict[tuple[int, int, bool], bool] = {}

    def automaton_letter(self, letter: int) -> int:
        """The letter over the automaton's propositions of a world ``letter``."""
        return sum(((letter >> i) & 1) << j for i, j in self._bits)

    def cost(self, state: int, letter: int) -> float:
        """The cost of the transition of automaton ``state`` on the world ``letter``: the sum
        of the costs of the rules it matches."""
        key = (state, letter)
        found = self._memo.get(key)
        if found is None:
            true = {p for i, p in enumerate(self._names) if letter >> i & 1}
            target: int | None = None
            found = 0.0
            for k, rule in enumerate(self.rules):
                if not letter_holds(self._whens[k], true) or not self._state(k, state, False):
                    continue
                if self._targets[k] is not None:
                    if target is None:
                        target = self.automaton.successor(state, self.automaton_letter(letter))[0]
                    if not self._state(k, target, True):
                        continue
                found += rule.cost
                self.matched[k] = True
            self._memo[key] = found
        return found

    def _state(self, k: int, state: int, target: bool) -> bool:
        """Whether ``state`` is an instance of rule ``k``'s ``from`` (its ``to``, when
        ``target``); a rule without one matches every state."""
        key = (k, state, target)
        found = self._states.get(key)
        if found is None:
            pattern = (self._targets if target else self._sources)[k]
            found = pattern is None or pattern.matches(self.automaton.obligation(state))
            self._states[key] = found
        return found

    def unmatched_error(self, obligations: list[str]) -> CostError | None:
        """The error for the rules that matched nothing, given the obligations of the states
        that were asked about; ``None`` when every rule matched a transition."""
        missed = [r for r, m in zip(self.rules, self.matched, strict=True) if not m]
        if not missed:
            return None
        shown = ", ".join(repr(o) for o in obligations[:6])
        more = f" and {len(obligations) - 6} more" if len(obligations) > 6 else ""
        lines = [
            f"{rule.where or 'a transition cost'}: matches no transition the world can take "
            f"(from {rule.source or 'any state'!r}, when {rule.when!r}"
            + (f", to {rule.target!r}" if rule.target is not None else "")
            + f"); the task's states it reaches owe {shown}{more} (mitlc compile prints the "
            "task's locations)"
            for rule in missed
        ]
        return CostError("\n".join(lines))


def _pattern(text: str | None) -> ObligationPattern | None:
    return None if text is None else ObligationPattern.parse(text)
