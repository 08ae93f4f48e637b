"""MITL to a digital limit-deterministic generalized Büchi automaton: ``translate(formula)``.

The construction is that of Esparza, Křetínský and Sickert (EKS20: "A unified translation of
linear temporal logic to ω-automata", JACM 67(6), 2020; first as SEJK16: Sickert, Esparza, Jaax,
Křetínský, "Limit-deterministic Büchi automata for linear temporal logic", CAV 2016), on the
discrete-time MITL of DESIGN.md, whose bounded operators progression resolves in finite time.

* The *initial component* is the progression automaton: its states are the obligations still
  owed (:mod:`mitlc.automata.progress`), deterministic and complete.
* By the Master Theorem (EKS20, Thm. 5.7), a word satisfies φ iff for some set ``X`` of its
  unbounded F/U subformulas and ``Y`` of its unbounded G/R subformulas: (1) from some position
  ``i`` on the residual obligation ``ψ`` satisfies ``ψ[X]ν``; (2) each ``χ ∈ X`` satisfies
  ``G F χ[Y]μ``; (3) each ``χ ∈ Y`` satisfies ``F G χ[X]ν``. An epsilon jump guesses ``i``,
  ``X`` and ``Y``; the *accepting component* checks the safety formula ``ψ[X]ν & G χ[X]ν``
  (``χ ∈ Y``) by progression and each ``G F χ[Y]μ`` with a breakpoint: a disjunction of tokens,
  one started at every position, whose progression reaching ``true`` marks acceptance set ``χ``
  and restarts empty (:mod:`mitlc.automata.accepting`).
* A formula without unbounded F/U is a safety formula: the progression automaton alone with zero
  acceptance sets. One without unbounded G/R is a co-safety formula: the progression automaton
  with one set, on ``true``. A conjunction of safety, co-safety and ``G χ`` (``χ`` co-safety)
  parts has a deterministic breakpoint construction (:mod:`mitlc.automata.recurrence`).
  All three are deterministic; only the rest (persistence,
  as in ``F G p``, and mixtures) get epsilon jumps.
* States with no accepting continuation merge into one rejecting sink; ``true`` is the
  accepting sink; states are numbered in breadth-first order, so output is canonical. Then
  bisimilar states (the same verdicts, ends, marks and successors) are merged
  (:mod:`mitlc.automata.minimize`); the lazy automaton keeps the states progression reaches
  (``minimal=False`` here).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from types import EllipsisType
from typing import Any

from mitlc.automata.digital import DigitalAutomaton, DigitalState, Row
from mitlc.automata.ends import END_FAILS
from mitlc.automata.graph import live_states
from mitlc.automata.keys import SINK, Key, Rules
from mitlc.automata.keys import StateKind as StateKind
from mitlc.automata.minimize import bisimulation, is_minimal, quotient
from mitlc.automata.terms import TermStore
from mitlc.errors import MitlcError
from mitlc.limits import DEFAULT_TIME_LIMIT, Deadline, LimitError, collector_paused
from mitlc.syntax import ast, to_text

MAX_PROPOSITIONS = 62
"""Letters are 64-bit words in worlds and products (one bit per proposition)."""


class TranslationError(MitlcError):
    """A formula the translation refuses: too many propositions or states."""


class StateLimitError(TranslationError, LimitError):
    """The translation stopped at its state limit (``max_states``, ``--max-states``)."""


def state_limit_error(limit: int) -> StateLimitError:
    """The error of a translation (eager or lazy) growing past ``limit`` states."""
    return StateLimitError(
        f"the automaton grows past --max-states {limit}; raise the state limit "
        "with a larger --max-states (max_states from Python) or simplify the "
        "formula (smaller bounds, fewer nested operators)"
    )


@dataclass(slots=True)
class _Explored:
    """The states found so far, in discovery order, with their rows."""

    keys: list[Key] = field(default_factory=list)
    index: dict[Key, int] = field(default_factory=dict)
    rows: list[Row] = field(default_factory=list)
    """Per state: its :meth:`Rules.transitions` as a row over discovery ids (its targets: the
    states it leads to, by least letter)."""
    epsilon: list[tuple[int, int]] = field(default_factory=list)

    def id(self, key: Key, limit: int) -> int:
        found = self.index.get(key)
        if found is None:
            if len(self.keys) >= limit:
                raise state_limit_error(limit)
            found = len(self.keys)
            self.keys.append(key)
            self.index[key] = found
        return found


@dataclass(frozen=True, slots=True)
class Translation:
    """The digital automaton with the normal forms behind its states, for folding."""

    automaton: DigitalAutomaton
    store: TermStore
    keys: tuple[Key, ...]
    """``keys[s]``: the normal forms behind digital state ``s``."""
    components: tuple[int, ...] = ()
    """``components[s]``: the strongly connected component of ``s``, numbered in reverse
    topological order (successors' first), as the liveness analysis found them (the sink's:
    0); empty when not known (:func:`mitlc.automata.minimize.bisimulation` finds them)."""


def translate(
    formula: ast.Formula,
    *,
    max_states: int = 1_000_000,
    time_limit: float | None = DEFAULT_TIME_LIMIT,
    memory_limit: float | EllipsisType | None = ...,
    deadline: Deadline | None = None,
    minimal: bool = True,
) -> DigitalAutomaton:
    """The digital LDGBA of ``formula`` (see the module docstring), its bisimilar states
    merged unless ``minimal`` is false (:func:`translate_terms`).

    Stops with :class:`StateLimitError` past ``max_states`` states and with
    :class:`mitlc.limits.LimitError` after ``time_limit`` seconds
    or past ``memory_limit`` GB held (``None``: no limit), or at
    ``deadline`` when one is given (a clock shared with the caller's other stages)."""
    clock = Deadline.of(deadline, time_limit, "compile", memory_limit)
    return translate_terms(
        formula, max_states=max_states, deadline=clock, minimal=minimal
    ).automaton


def translate_terms(
    formula: ast.Formula,
    *,
    max_states: int = 1_000_000,
    time_limit: float | None = DEFAULT_TIME_LIMIT,
    memory_limit: float | EllipsisType | None = ...,
    deadline: Deadline | None = None,
    minimal: bool = True,
) -> Translation:
    """:func:`translate`, keeping the term store and each state's normal form. With
    ``minimal`` (the default), bisimilar states are merged (:mod:`mitlc.automata.minimize`);
    without, the states are those progression reaches, as the lazy automaton's."""
    clock = Deadline.of(deadline, time_limit, "compile", memory_limit).at("translation")
    with collector_paused():
        translation = _translate_terms(formula, max_states, clock)
        if not minimal:
            return translation
        block = bisimulation(translation.automaton, clock, translation.components)
        if is_minimal(block):
            return translation
        automaton, keys = quotient(translation.automaton, translation.keys, block)
        return Translation(automaton, translation.store, keys)


def _translate_terms(formula: ast.Formula, max_states: int, deadline: Deadline) -> Translation:
    propositions = ast.atoms(formula)
    if len(propositions) > MAX_PROPOSITIONS:
        raise TranslationError(
            f"{len(propositions)} propositions; a letter is a 64-bit word, which allows at "
            f"most {MAX_PROPOSITIONS}"
        )
    rules = Rules.of(formula)
    rules.progression.diagrams.deadline = deadline
    builder = _Builder(rules, max_states, deadline)
    explored = builder.explore()
    return builder.finish(explored, to_text(formula))


@dataclass(slots=True)
class _Builder:
    rules: Rules
    max_states: int
    deadline: Deadline

    def explore(self) -> _Explored:
        """Breadth-first exploration from the initial obligation, jumps included.

        A state's successors are made once per class of letters it tells apart (the terminals
        of :meth:`Rules.transitions`), by least letter (:meth:`Row.export` meets them so): the
        order in which a table over every letter first meets them, so states are numbered as
        there, at a cost that grows with the classes, not with ``2^n``."""
        explored = _Explored()
        start = self.rules.start()
        limit, deadline = self.max_states, self.deadline
        keys, index = explored.keys, explored.index
        diagrams = self.rules.progression.diagrams
        explored.id(start, limit)
        position = 0
        while position < len(keys):
            deadline.check_now()
            key = keys[position]
            transitions = self.rules.transitions(key)

            def discover(
                value: Any, outcome: Callable[[Any], tuple[Key, int]] = transitions.outcome
            ) -> tuple[int, int]:
                target, mark = outcome(value)
                found = index.get(target)
                return (explored.id(target, limit) if found is None else found), mark

            explored.rows.append(Row.export(diagrams, transitions.diagram, discover))
            for jump in self.rules.jumps(key, deadline):
                explored.epsilon.append((position, explored.id(jump, limit)))
            position += 1
        return explored

    def finish(self, explored: _Explored, formula_text: str) -> Translation:
        """Merge dead states into the sink, renumber breadth-first, attach the obligations."""
        keys, rules = explored.keys, self.rules
        sink_ids = {i for i, k in enumerate(keys) if k == SINK}
        delta = [row.targets for row in explored.rows]
        stops = {i for i, k in enumerate(keys) if rules.end(k) != END_FAILS}
        live, component = live_states(
            delta,
            [row.marks for row in explored.rows],
            explored.epsilon,
            rules.num_sets,
            sink_ids,
            stops,
        )
        order = _bfs_order(delta, explored.epsilon, live)
        new_id = {old: new for new, old in enumerate(order)}
        sink: int | None = None
        if len(order) < len(keys) or not live:
            sink = len(order)

        # remap[old]: the new id of a live state, the sink's of any other
        remap = [-1 if sink is None else sink] * len(keys)
        for old, new in new_id.items():
            remap[old] = new
        found = [explored.rows[old] for old in order]
        if len(set(remap)) == len(remap):  # most often: no dead state but the sink
            get = remap.__getitem__
            rows = [Row(r.root, r.tests, tuple(map(get, r.targets)), r.marks) for r in found]
        else:
            rows = [row.renumbered(remap) for row in found]
        states = []
        for old in order:
            self.deadline.check()
            states.append(rules.state(keys[old]))
        new_keys = [keys[old] for old in order]
        if sink is not None:
            new_keys.append(SINK)
            rows.append(Row.constant(sink))
            states.append(DigitalState("false", "initial", "violated"))
        epsilon = sorted(
            (new_id[s], new_id[t]) for s, t in explored.epsilon if s in live and t in live
        )
        initial = 0 if 0 in live else (sink if sink is not None else 0)
        automaton = DigitalAutomaton(
            source=formula_text,
            formula=formula_text,
            propositions=rules.store.propositions,
            states=tuple(states),
            initial=initial,
            rows=tuple(rows),
            num_sets=rules.num_sets,
            epsilon=tuple(epsilon),
            jump_order=_jump_order(explored.epsilon, order, new_id, len(states)) if epsilon else (),
        )
        components = [component[old] + 1 for old in order] + ([0] if sink is not None else [])
        return Translation(automaton, rules.store, tuple(new_keys), tuple(components))


def _jump_order(
    epsilon: Sequence[tuple[int, int]], order: Sequence[int], new_id: dict[int, int], size: int
) -> tuple[tuple[int, ...], ...]:
    """Per state of the automaton (``size`` of them: the live ones in ``order``, then the
    sink), the new ids of its live jump targets in the order they were explored: that of
    :meth:`Rules.jumps` (the guesses), which the lazy automaton keeps too."""
    found: dict[int, list[int]] = {}
    for s, t in epsilon:
        if s in new_id and t in new_id:
            found.setdefault(s, []).append(new_id[t])
    listed = [tuple(found.get(old, ())) for old in order]
    return tuple(listed + [()] * (size - len(listed)))


def _bfs_order(
    delta: Sequence[Sequence[int]], epsilon: Sequence[tuple[int, int]], live: set[int]
) -> list[int]:
    """Live states in breadth-first order from the initial state: letters, then jumps."""
    if 0 not in live:
        return []
    jumps: dict[int, list[int]] = {}
    for s, t in epsilon:
        jumps.setdefault(s, []).append(t)
    order, seen = [0], {0}
    position = 0
    while position < len(order):
        state = order[position]
        for t in [*delta[state], *jumps.get(state, ())]:
            if t in live and t not in seen:
                seen.add(t)
                order.append(t)
        position += 1
    return order
