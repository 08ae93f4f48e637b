"""The digital automaton: the explicit, discrete-time ground truth of a compiled formula.

A transition-based generalized Büchi automaton over letters (sets of propositions; a letter's
index is ``sum(1 << i for each true propositions[i])``), with symbolic letters: each state has a
:class:`Row`, the propositions it reads now and one transition per valuation of those (the
classes of letters the state tells apart), so a state that reads two of twenty propositions has
four transitions, not a million. ``successor(s, letter)`` is the target of state ``s`` on
``letter`` and the bit mask of the acceptance sets that transition belongs to; ``edges(s)``
groups the classes by transition, each with its letters as a :class:`Letters` (a Boolean
label). The explicit per-letter table (``delta``, ``marks``) is a view made on demand, for
small alphabets. The automaton is deterministic and complete on letters; its only other choice
is an epsilon jump ``(source, target)``, which reads no letter and goes from the initial to the
accepting component (a limit-deterministic automaton, LDGBA).

A run is accepting iff it takes, infinitely often, a transition of every acceptance set; with
zero sets, iff it never enters a violated state.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal, NamedTuple, TypeAlias

from mitlc.automata.bdd import LEAF, Diagrams
from mitlc.automata.labels import Letters

Component: TypeAlias = Literal["initial", "accepting"]
Verdict: TypeAlias = Literal["satisfied", "violated", "pending"]


@dataclass(frozen=True, slots=True)
class DigitalState:
    """One state: the obligation still owed (a formula), its component, its verdict and its
    value at the end of a trace.

    ``verdict`` is ``satisfied`` when every continuation is accepted, ``violated`` when none is
    (the one rejecting sink), ``pending`` otherwise. ``end`` is whether a finite trace that
    stops in this state satisfies the formula (:mod:`mitlc.automata.ends`): what an episode
    still pending at its end is judged by (:func:`mitlc.task.rules.success`): an end code of
    :mod:`mitlc.automata.ends`, 0 (fails), or ``1 + sets``: succeeds once the acceptance sets of
    the mask ``sets`` have been seen (1: at once).
    """

    obligation: str
    component: Component
    verdict: Verdict
    end: int = 0


class Row(NamedTuple):
    """The transitions of one state: a reduced decision diagram over the propositions it reads
    (:mod:`mitlc.automata.bdd`). ``tests[i]`` is ``(proposition, low, high)``; a child or
    ``root`` ``c >= 0`` is ``tests[c]`` and ``c < 0`` is transition ``~c``: ``(targets[~c],
    marks[~c])``. Transitions are listed by their least letter, each once. (A named tuple:
    a translation makes one per state, and a tuple is made faster than a frozen dataclass.)"""

    root: int
    tests: tuple[tuple[int, int, int], ...]
    targets: tuple[int, ...]
    marks: tuple[int, ...]

    @property
    def reads(self) -> int:
        """The propositions the state reads (those its diagram tests)."""
        reads = 0
        for prop, _, _ in self.tests:
            reads |= 1 << prop
        return reads

    @staticmethod
    def constant(target: int, marks: int = 0) -> Row:
        """A row that reads nothing: the same transition on every letter."""
        return Row(~0, (), (target,), (marks,))

    @staticmethod
    def export(diagrams: Diagrams, node: int, relabel: Callable[[Any], tuple[int, int]]) -> Row:
        """The row of ``node`` of ``diagrams``, its terminals relabelled ``(target, marks)``
        (terminals relabelled alike are merged, and the diagram kept reduced)."""
        var, values = diagrams.var, diagrams.values
        if var[node] == LEAF:
            return Row.constant(*relabel(values[node]))
        low, high = diagrams.low[node], diagrams.high[node]
        if var[low] == LEAF and var[high] == LEAF:  # one test (most rows): no walk
            (t0, m0), (t1, m1) = relabel(values[low]), relabel(values[high])
            if (t0, m0) == (t1, m1):
                return Row.constant(t0, m0)
            return Row(0, ((var[node], ~0, ~1),), (t0, t1), (m0, m1))
        outcomes: dict[tuple[int, int], int] = {}
        tests: list[tuple[int, int, int]] = []
        root = _export(diagrams, node, relabel, outcomes, tests)
        targets, marks = zip(*outcomes, strict=True)
        return Row(root, tuple(tests), targets, marks)

    def renumbered(self, state: Sequence[int]) -> Row:
        """This row with each target ``t`` renamed ``state[t]`` (transitions that come to
        agree are merged, and the diagram kept reduced)."""
        targets = tuple(map(state.__getitem__, self.targets))
        if len(set(zip(targets, self.marks, strict=True))) == len(targets):
            return Row(self.root, self.tests, targets, self.marks)
        diagrams = Diagrams()  # rare: dead states merged into the sink
        node = self.into(diagrams, lambda k: (targets[k], self.marks[k]))
        return Row.export(diagrams, node, lambda outcome: outcome)

    def into(self, diagrams: Diagrams, value: Callable[[int], Any]) -> int:
        """This row as a node of ``diagrams``, transition ``k`` a terminal ``value(k)``."""
        return self._into(diagrams, value, self.root, {})

    def _into(
        self, diagrams: Diagrams, value: Callable[[int], Any], c: int, made: dict[int, int]
    ) -> int:
        found = made.get(c)
        if found is None:
            if c < 0:
                found = diagrams.leaf(value(~c))
            else:
                prop, low, high = self.tests[c]
                low_node = self._into(diagrams, value, low, made)
                found = diagrams.node(prop, low_node, self._into(diagrams, value, high, made))
            made[c] = found
        return found

    def transition(self, letter: int) -> int:
        """The index of the transition taken on ``letter``."""
        c, tests = self.root, self.tests
        while c >= 0:
            prop, low, high = tests[c]
            c = high if letter >> prop & 1 else low
        return ~c

    def successor(self, letter: int) -> tuple[int, int]:
        """``(target, marks)`` on ``letter``."""
        k = self.transition(letter)
        return self.targets[k], self.marks[k]

    def paths(self) -> list[tuple[int, int, int]]:
        """Every path ``(care, value, transition)``: disjoint cubes covering every letter."""
        out, stack = [], [(self.root, 0, 0)]
        while stack:
            c, care, value = stack.pop()
            if c < 0:
                out.append((care, value, ~c))
                continue
            prop, low, high = self.tests[c]
            bit = 1 << prop
            stack += [(high, care | bit, value | bit), (low, care | bit, value)]
        return out

    def cubes(self) -> list[tuple[tuple[int, int], ...]]:
        """Per transition, its letters as disjoint cubes ``(care, value)`` (its paths)."""
        found: list[list[tuple[int, int]]] = [[] for _ in self.targets]
        for care, value, k in self.paths():
            found[k].append((care, value))
        return [tuple(each) for each in found]

    def edges(self) -> list[tuple[int, int, Letters]]:
        """``(target, marks, letters)`` per transition, by their least letter."""
        return [
            (t, m, Letters.of_cubes(c))
            for t, m, c in zip(self.targets, self.marks, self.cubes(), strict=True)
        ]


def _export(
    diagrams: Diagrams,
    node: int,
    relabel: Callable[[Any], tuple[int, int]],
    outcomes: dict[tuple[int, int], int],
    tests: list[tuple[int, int, int]],
) -> int:
    """:meth:`Row.export` of ``node``: a depth-first walk, low branch first (so transitions
    are numbered by least letter), each test made once its branches are (``~f`` on the stack:
    both branches of ``f`` are done)."""
    var, low, high, values = diagrams.var, diagrams.low, diagrams.high, diagrams.values
    inner: dict[tuple[int, int, int], int] = {}
    memo: dict[int, int] = {}
    stack = [node]
    while stack:
        f = stack.pop()
        if f < 0:
            f = ~f
            lo, hi = memo[low[f]], memo[high[f]]
            if lo == hi:
                memo[f] = lo
                continue
            key = (var[f], lo, hi)
            found = inner.get(key)
            if found is None:
                found = inner[key] = len(tests)
                tests.append(key)
            memo[f] = found
        elif f not in memo:
            if var[f] == LEAF:
                memo[f] = ~outcomes.setdefault(relabel(values[f]), len(outcomes))
            else:
                stack += (~f, high[f], low[f])
    return memo[node]


def _table_row(targets: Sequence[int], marks: Sequence[int], num_props: int) -> Row:
    """The row of one state of an explicit table (``targets[letter]``, ``marks[letter]``)."""
    diagrams = Diagrams()

    def build(var: int, base: int) -> int:
        if var < 0:
            return diagrams.leaf((targets[base], marks[base]))
        return diagrams.node(var, build(var - 1, base), build(var - 1, base | 1 << var))

    return Row.export(diagrams, build(num_props - 1, 0), lambda outcome: outcome)


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
    rows: tuple[Row, ...]
    """``rows[s]``: the transitions of ``s``."""
    num_sets: int
    epsilon: tuple[tuple[int, int], ...] = ()
    """Epsilon jumps ``(source, target)``, sorted, from the initial to the accepting component."""
    jump_order: tuple[tuple[int, ...], ...] = field(default=(), compare=False, repr=False)
    """``jump_order[s]``: the targets of the jumps of ``s`` (those of ``epsilon``) in the order
    :meth:`jumps` gives them, that of :func:`mitlc.automata.accepting.guesses` for a
    translation (:meth:`mitlc.automata.keys.Rules.jumps`); empty: by target. Not part of the
    artifact, which lists ``epsilon``."""
    _table: dict[str, tuple[tuple[tuple[int, ...], ...], ...]] = field(
        default_factory=dict, compare=False, repr=False
    )

    @staticmethod
    def from_table(
        source: str,
        formula: str,
        propositions: tuple[str, ...],
        states: tuple[DigitalState, ...],
        initial: int,
        delta: Sequence[Sequence[int]],
        marks: Sequence[Sequence[int]],
        num_sets: int,
        epsilon: tuple[tuple[int, int], ...] = (),
    ) -> DigitalAutomaton:
        """The automaton of an explicit table (``delta[s][letter]``, ``marks[s][letter]``):
        every state reads every proposition."""
        n = len(propositions)
        rows = [_table_row(d, m, n) for d, m in zip(delta, marks, strict=True)]
        return DigitalAutomaton(
            source, formula, propositions, states, initial, tuple(rows), num_sets, epsilon
        )

    @property
    def num_letters(self) -> int:
        """``2 ** len(propositions)``."""
        return 1 << len(self.propositions)

    @property
    def delta(self) -> tuple[tuple[int, ...], ...]:
        """The explicit view: ``delta[s][letter]``, the successor of ``s`` on ``letter``, for
        all ``2^n`` letters (made on first use; for small alphabets)."""
        return self._explicit()[0]

    @property
    def marks(self) -> tuple[tuple[int, ...], ...]:
        """The explicit view: ``marks[s][letter]``, bit ``k`` set iff that transition is in
        acceptance set ``k``."""
        return self._explicit()[1]

    def _explicit(self) -> tuple[tuple[tuple[int, ...], ...], ...]:
        found = self._table.get("explicit")
        if found is None:
            letters = range(self.num_letters)
            pairs = [[row.successor(letter) for letter in letters] for row in self.rows]
            delta = tuple(tuple(t for t, _ in pair) for pair in pairs)
            marks = tuple(tuple(m for _, m in pair) for pair in pairs)
            found = self._table["explicit"] = (delta, marks)
        return found

    def edges(self, state: int) -> list[tuple[int, int, Letters]]:
        """The transitions of ``state``: ``(target, marks, letters)``, by least letter."""
        return self.rows[state].edges()

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
        return self.rows[state].successor(letter)

    def verdict(self, state: int) -> Verdict:
        """The verdict of ``state``."""
        return self.states[state].verdict

    def jumps(self, state: int) -> tuple[int, ...]:
        """The targets of the epsilon jumps leaving ``state``, in the order of ``jump_order``
        (a translation's: that of the guesses, as the lazy automaton's), else by target. A
        jump's action number in a product or a gym wrapper is its place here."""
        return self.jump_order[state] if self.jump_order else self.jumps_from(state)

    def end(self, state: int) -> int:
        """What a trace that stops in ``state`` is worth: its end code
        (:attr:`DigitalState.end`)."""
        return self.states[state].end

    def obligation(self, state: int) -> str:
        """What ``state`` still owes."""
        return self.states[state].obligation

    @property
    def num_transitions(self) -> int:
        """Letter transitions (one per class of letters a state tells apart) plus jumps."""
        return sum(len(row.targets) for row in self.rows) + len(self.epsilon)
