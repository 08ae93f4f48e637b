"""The digital automaton: the explicit, discrete-time ground truth of a compiled formula.

A transition-based generalized Büchi automaton over letters (sets of propositions), given as an
explicit table: ``delta[s][letter]`` is the successor of state ``s`` on the letter whose index is
``sum(1 << i for each true propositions[i])``, and ``marks[s][letter]`` is the bit mask of the
acceptance sets that transition belongs to. The automaton is deterministic and complete on
letters; its only other choice is an epsilon jump ``(source, target)``, which reads no letter and
goes from the initial to the accepting component (a limit-deterministic automaton, LDGBA).

A run is accepting iff it takes, infinitely often, a transition of every acceptance set; with
zero sets, iff it never enters a violated state.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, TypeAlias

Component: TypeAlias = Literal["initial", "accepting"]
Verdict: TypeAlias = Literal["satisfied", "violated", "pending"]


@dataclass(frozen=True, slots=True)
class DigitalState:
    """One state: the obligation still owed (a formula), its component and its verdict.

    ``verdict`` is ``satisfied`` when every continuation is accepted, ``violated`` when none is
    (the one rejecting sink), ``pending`` otherwise.
    """

    obligation: str
    component: Component
    verdict: Verdict


@dataclass(frozen=True, slots=True)
class DigitalAutomaton:
    """An explicit LDGBA with transition-based generalized Büchi acceptance (see module doc)."""

    source: str
    """The formula as written."""
    formula: str
    """The formula in canonical text."""
    propositions: tuple[str, ...]
    states: tuple[DigitalState, ...]
    initial: int
    delta: tuple[tuple[int, ...], ...]
    """``delta[s][letter]``: the successor of ``s`` on ``letter``."""
    marks: tuple[tuple[int, ...], ...]
    """``marks[s][letter]``: bit ``k`` set iff that transition is in acceptance set ``k``."""
    num_sets: int
    epsilon: tuple[tuple[int, int], ...] = ()
    """Epsilon jumps ``(source, target)``, sorted, from the initial to the accepting component."""

    @property
    def num_letters(self) -> int:
        """``2 ** len(propositions)``."""
        return 1 << len(self.propositions)

    @property
    def is_deterministic(self) -> bool:
        """True when there are no epsilon jumps."""
        return not self.epsilon

    @property
    def all_sets(self) -> int:
        """The mask with every acceptance set."""
        return (1 << self.num_sets) - 1

    def letter_index(self, true_props: frozenset[str] | set[str]) -> int:
        """The index of the letter in which exactly ``true_props`` hold (others are ignored)."""
        return sum(1 << i for i, p in enumerate(self.propositions) if p in true_props)

    def letter_props(self, letter: int) -> frozenset[str]:
        """The propositions true in letter ``letter``."""
        return frozenset(p for i, p in enumerate(self.propositions) if letter >> i & 1)

    def jumps_from(self, state: int) -> tuple[int, ...]:
        """The targets of the epsilon jumps leaving ``state``."""
        return tuple(t for s, t in self.epsilon if s == state)

    # The interface of mitlc.task.monitor.TaskAutomaton (shared with the lazy automaton).

    def successor(self, state: int, letter: int) -> tuple[int, int]:
        """``(target, marks)`` of the transition of ``state`` on ``letter``."""
        return self.delta[state][letter], self.marks[state][letter]

    def verdict(self, state: int) -> Verdict:
        """The verdict of ``state``."""
        return self.states[state].verdict

    def jumps(self, state: int) -> tuple[int, ...]:
        """The targets of the epsilon jumps leaving ``state``, by target."""
        return self.jumps_from(state)

    def obligation(self, state: int) -> str:
        """What ``state`` still owes."""
        return self.states[state].obligation

    @property
    def num_transitions(self) -> int:
        """Letter transitions plus epsilon jumps."""
        return len(self.states) * self.num_letters + len(self.epsilon)
