"""The timed LDGBA: locations, clocks, guarded edges with resets (DESIGN.md, "The automaton").

Clock semantics: all clocks are 0 at position 0. Reading position ``i`` with valuation ``v``
takes the unique edge of the current location whose label holds the letter and whose guard
holds for ``v``; then every clock the edge resets becomes 0 and every other clock becomes
``min(v + 1, bound)``. Guards are closed integer intervals per clock; a clock absent from a guard
is unconstrained. An epsilon jump reads no letter and
keeps the clocks but those it resets.
"""

from __future__ import annotations

from dataclasses import dataclass

from mitlc.automata.digital import Component, Verdict
from mitlc.automata.labels import Letters

Guard = tuple[tuple[int, int, int], ...]
"""``((clock, lo, hi), ...)`` sorted by clock: closed intervals (clocks stop at their bound)."""


@dataclass(frozen=True, slots=True)
class Location:
    """A location: the obligation it stands for, written with its clocks' names."""

    id: int
    name: str
    obligation: str
    component: Component
    verdict: Verdict
    clocks: tuple[int, ...]
    """The clocks the obligation depends on."""


@dataclass(frozen=True, slots=True)
class Edge:
    """A guarded edge: its letters (a Boolean label), a clock guard, resets, marks."""

    source: int
    target: int
    label: Letters
    guard: Guard
    reset: tuple[int, ...]
    acc: tuple[int, ...]


@dataclass(frozen=True, slots=True)
class Jump:
    """An epsilon jump from the initial to the accepting component."""

    source: int
    target: int
    reset: tuple[int, ...]


@dataclass(frozen=True, slots=True)
class Tldgba:
    """A timed limit-deterministic generalized Büchi automaton (see the module docstring)."""

    source: str
    formula: str
    propositions: tuple[str, ...]
    clock_bounds: tuple[int, ...]
    """``clock_bounds[c]``: the value at which clock ``c`` stops counting."""
    num_sets: int
    initial: int
    locations: tuple[Location, ...]
    edges: tuple[Edge, ...]
    epsilon: tuple[Jump, ...]

    @property
    def clock_names(self) -> tuple[str, ...]:
        """``x0``, ``x1``, ..."""
        return tuple(f"x{c}" for c in range(len(self.clock_bounds)))

    def enabled(self, location: int, letter: int, valuation: tuple[int, ...]) -> list[Edge]:
        """The edges of ``location`` enabled by ``letter`` under ``valuation``."""
        return [
            e
            for e in self.edges
            if e.source == location and letter in e.label and guard_holds(e.guard, valuation)
        ]

    def advance(self, edge: Edge | Jump, valuation: tuple[int, ...]) -> tuple[int, ...]:
        """The valuation after taking ``edge`` (a jump keeps non-reset clocks as they are)."""
        tick = 1 if isinstance(edge, Edge) else 0
        return tuple(
            0 if c in edge.reset else min(v + tick, self.clock_bounds[c])
            for c, v in enumerate(valuation)
        )


def guard_holds(guard: Guard, valuation: tuple[int, ...]) -> bool:
    """Whether ``valuation`` satisfies every clock constraint of ``guard``."""
    return all(lo <= valuation[c] <= hi for c, lo, hi in guard)
