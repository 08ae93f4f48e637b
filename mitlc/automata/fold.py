"""Folding the digital automaton into a T-LDGBA: ``fold(translation) -> Tldgba``.

Digital states that differ only in the time elapsed since their bounded obligations were
spawned become one *location* with *clocks*. Each bounded atom of a state is written as a
*timed atom*: its operator and operands, the interval it had when spawned (its base) and the
clock started then; at clock value ``x`` its interval is ``[max(lo - x, 0), hi - x]``. Atoms
spawned together share a clock. Reading a letter, an atom that is its predecessor shifted by one
step keeps its clock (its lineage); any other bounded atom is fresh and takes the lowest free
clock, which the edge resets. Unbounded operators and literals are untimed.

A location's edges are read off the digital transitions of the (state, valuation) pairs it
covers: for each letter and valuation, the target location, the resets and the acceptance
marks. Guards partition each clock's range ``[0, bound]`` into intervals, clock by clock;
valuations no run reaches take the behaviour of the nearest reachable one below (or above), so
the edges stay deterministic and complete. Epsilon jumps carry no guard, so a location whose
covered states disagree on their jumps is unfolded into one location per state.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

from mitlc.automata.classes import LetterClasses, Shapes
from mitlc.automata.digital import Row, Verdict
from mitlc.automata.guards import partition
from mitlc.automata.labels import Letters
from mitlc.automata.ldba import Translation
from mitlc.automata.templates import (
    LocKey,
    Matcher,
    Outcome,
    TAtom,
    Template,
    TimedAtom,
    Valuation,
    key_text,
    timed_atoms,
    valuation_of,
)
from mitlc.automata.terms import INF, LIT, TermStore
from mitlc.automata.tldgba import Edge, Guard, Jump, Location, Tldgba
from mitlc.limits import Deadline


@dataclass(slots=True)
class _Folder:
    translation: Translation
    unfold: set[LocKey]
    deadline: Deadline
    untimed: bool = False
    locations: dict[LocKey, int] = field(default_factory=dict)
    covered: list[dict[Valuation, int]] = field(default_factory=list)
    behaviour: dict[tuple[int, Valuation], tuple[Row, tuple[Outcome, ...]]] = field(
        default_factory=dict
    )
    """Per (location, valuation): its state's row and the outcome of each of its transitions."""
    shapes: Shapes = field(default_factory=Shapes)
    """The rows' shapes, for the classes of letters of each location."""
    labels: dict[tuple[tuple[int, int], ...], Letters] = field(default_factory=dict)
    """The letters of a union of cubes, made once."""
    jumps: dict[tuple[int, Valuation], frozenset[tuple[LocKey, tuple[int, ...]]]] = field(
        default_factory=dict
    )
    timed_atoms: dict[LocKey, tuple[TimedAtom, ...]] = field(default_factory=dict)
    """:meth:`timed_of` each location key met."""
    timed_ids: frozenset[int] = frozenset()
    """The bounded atoms of the store (:func:`_timed_ids`)."""
    acceptance: dict[int, tuple[int, ...]] = field(default_factory=dict)
    """The acceptance sets of a mask of marks."""
    unclocked: dict[tuple[int, int], tuple[LocKey, dict[int, int], tuple[int, ...]]] = field(
        default_factory=dict
    )
    """:meth:`retemplate` from a source whose clocks are all stopped, per (state, step)."""

    @property
    def store(self) -> TermStore:
        return self.translation.store

    def location_key(self, state: int, templates: tuple[Template, ...]) -> LocKey:
        key = self.translation.keys[state]
        if self.untimed:
            return LocKey(key.kind, (), key.seeds, state)
        loc = LocKey(key.kind, templates, key.seeds)
        if self.unfold and loc in self.unfold:
            return LocKey(key.kind, templates, key.seeds, state)
        return loc

    def retemplate(
        self, state: int, source: LocKey | None, values: dict[int, int], step: int
    ) -> tuple[LocKey, dict[int, int], tuple[int, ...]]:
        """The location and valuation of ``state`` reached from ``source`` (None: the start)."""
        if values and self.translation.keys[state].forms:
            return self._retemplate(state, source, values, step)
        # No clock runs, or no atoms to give one: what the state itself makes, made once.
        found = self.unclocked.get((state, step))
        if found is None:
            if not self.translation.keys[state].forms or self.untimed:
                found = self.location_key(state, ()), {}, ()  # no atoms or no clocks
            else:
                found = self._retemplate(state, None, {}, step)
            self.unclocked[(state, step)] = found
        return found

    def _retemplate(
        self, state: int, source: LocKey | None, values: dict[int, int], step: int
    ) -> tuple[LocKey, dict[int, int], tuple[int, ...]]:
        forms = self.translation.keys[state].forms
        store = self.store
        with_operands = step == 1
        matcher = Matcher(store)
        if source is not None:
            for atom in self.timed_of(source):
                matcher.add(atom, values, step, with_operands)
        timed = self.timed_ids
        raw: list[list[list[TAtom]]] = []
        for form in forms:
            raw.append(
                [
                    [matcher.timed(a, with_operands)[0] if a in timed else a for a in cube]
                    for cube in store.forms[form]
                ]
            )
        if source is None:
            matcher.kept.clear()
        new_values = dict(matcher.kept)
        if not matcher.fresh_used:  # every timed atom keeps its clock
            templates = tuple(frozenset(frozenset(cube) for cube in form) for form in raw)
            return self.location_key(state, templates), new_values, ()
        fresh = 0
        while fresh in matcher.kept:  # the lowest free clock
            fresh += 1
        templates = tuple(
            frozenset(
                frozenset(
                    (*a[:5], fresh) if isinstance(a, tuple) and a[5] == -1 else a for a in cube
                )
                for cube in form
            )
            for form in raw
        )
        new_values[fresh] = 0
        return self.location_key(state, templates), new_values, (fresh,)

    def timed_of(self, key: LocKey) -> tuple[TimedAtom, ...]:
        """The timed atoms of a location's templates."""
        found = self.timed_atoms.get(key)
        if found is None:
            found = self.timed_atoms[key] = tuple(a for t in key.templates for a in timed_atoms(t))
        return found

    def explore(self) -> None:
        automaton = self.translation.automaton
        start_key, start_values, _ = self.retemplate(automaton.initial, None, {}, 0)
        start_valuation = valuation_of(start_values)
        queue = deque([(automaton.initial, start_key, start_values, start_valuation)])
        # A symmetric template (two atoms alike but for their clocks) covers a state under
        # several valuations, so a visit is a (state, location, valuation) triple.
        seen = {(automaton.initial, start_key, start_valuation)}
        jumps: dict[int, list[int]] = {}
        for s, t in automaton.epsilon:
            jumps.setdefault(s, []).append(t)
        deadline = self.deadline
        while queue:
            deadline.check_now()
            state, key, values, valuation = queue.popleft()
            loc = self._location(key)
            self.covered[loc][valuation] = state
            row = automaton.rows[state]
            outcomes: list[Outcome] = []
            reached: dict[int, tuple[LocKey, tuple[int, ...]]] = {}
            for target, marks in zip(row.targets, row.marks, strict=True):  # by least letter
                found = reached.get(target)
                if found is None:
                    t_key, t_values, resets = self.retemplate(target, key, values, 1)
                    found = reached[target] = (t_key, resets)
                    visit = (target, t_key, valuation_of(t_values))
                    if visit not in seen:
                        seen.add(visit)
                        queue.append((target, t_key, t_values, visit[2]))
                outcomes.append((found[0], found[1], marks))
            self.behaviour[(loc, valuation)] = (row, tuple(outcomes))
            jumped = set()
            for target in jumps.get(state, ()):
                t_key, t_values, resets = self.retemplate(target, key, values, 0)
                jumped.add((t_key, resets))
                visit = (target, t_key, valuation_of(t_values))
                if visit not in seen:
                    seen.add(visit)
                    queue.append((target, t_key, t_values, visit[2]))
            self.jumps[(loc, valuation)] = frozenset(jumped)

    def _location(self, key: LocKey) -> int:
        found = self.locations.get(key)
        if found is None:
            if not self.untimed and self._too_big(key):
                raise _NotWorthFolding

            found = len(self.locations)
            self.locations[key] = found
            self.covered.append({})
        return found

    def _too_big(self, key: LocKey) -> bool:
        """Folding stops paying once a new location would make as many locations as states,
        or with too many clocks."""
        if len(self.locations) + 1 >= len(self.translation.automaton.states):
            return True
        return any(a[5] >= MAX_CLOCKS for a in self.timed_of(key))

    def conflicts(self) -> set[LocKey]:
        """Locations whose covered states disagree on their epsilon jumps."""
        bad: set[LocKey] = set()
        for key, loc in self.locations.items():
            seen = {self.jumps[(loc, v)] for v in self.covered[loc]}
            if len(seen) > 1:
                bad.add(key.folded())
        return bad


class _NotWorthFolding(Exception):
    """Raised while exploring once the folding is known to be no better than no folding."""


MAX_REFINEMENTS = 8
MAX_CLOCKS = 3
"""More clocks than this and the digital automaton reads better than its folding."""


def fold(translation: Translation, *, deadline: Deadline | None = None) -> Tldgba:
    """The T-LDGBA of a translation (see the module docstring).

    When folding does not pay (no fewer locations than the digital automaton has states, which
    happens when clocks get permuted, or more than ``MAX_CLOCKS`` clocks), or the jumps cannot
    be made guard-free, the result is the digital automaton itself: one location per state and
    no clocks. ``deadline`` (none by default) stops a folding that runs past its time limit
    with :class:`mitlc.limits.LimitError`.
    """
    return fold_points(translation, deadline=deadline)[0]


Point = tuple[int, Valuation]
"""A digital state as a location of the T-LDGBA and the values of that location's clocks."""


def fold_points(
    translation: Translation, *, deadline: Deadline | None = None
) -> tuple[Tldgba, tuple[Point, ...]]:
    """:func:`fold`, with the point of each digital state: ``points[s]`` is the least
    ``(location, valuation)`` that covers state ``s`` (a symmetric template covers a state
    under several valuations; they behave alike)."""
    deadline = Deadline.none() if deadline is None else deadline
    timed = _timed_ids(translation)
    if not timed:
        # Without clocks a location is its forms, which name one state each: no fewer
        # locations than states, so folding cannot pay.
        return _unfolded(_Folder(translation, set(), deadline, untimed=True))
    unfold: set[LocKey] = set()
    shapes = Shapes()  # with the labels, made once for every try
    labels: dict[tuple[tuple[int, int], ...], Letters] = {}
    for _ in range(MAX_REFINEMENTS):
        folder = _Folder(
            translation, unfold, deadline, shapes=shapes, labels=labels, timed_ids=timed
        )
        try:
            folder.explore()
        except _NotWorthFolding:
            break
        conflicts = folder.conflicts()
        if not conflicts:
            folded = _build(folder)
            states = len(translation.automaton.states)
            if len(folded.locations) < states and len(folded.clock_bounds) <= MAX_CLOCKS:
                return folded, _points(folder)
            break
        unfold |= conflicts
    return _unfolded(_Folder(translation, set(), deadline, True, shapes=shapes, labels=labels))


def _points(folder: _Folder) -> tuple[Point, ...]:
    found: dict[int, Point] = {}
    for loc, covered in enumerate(folder.covered):
        for valuation, state in covered.items():
            point = (loc, valuation)
            if state not in found or point < found[state]:
                found[state] = point
    count = len(folder.translation.automaton.states)
    missing = [s for s in range(count) if s not in found]
    assert not missing, f"the folding covers every digital state (not {missing[:5]})"
    return tuple(found[s] for s in range(count))


def _timed_ids(translation: Translation) -> frozenset[int]:
    """The bounded atoms of the store: those that take a clock in a state that holds them."""
    atoms = translation.store.atoms
    return frozenset(i for i, (kind, _, hi, _, _) in enumerate(atoms) if kind != LIT and hi != INF)


def unfolded(translation: Translation, *, deadline: Deadline | None = None) -> Tldgba:
    """The digital automaton as a T-LDGBA: one location per state, no clocks."""
    deadline = Deadline.none() if deadline is None else deadline
    return _unfolded(_Folder(translation, set(), deadline, untimed=True))[0]


def _unfolded(folder: _Folder) -> tuple[Tldgba, tuple[Point, ...]]:
    folder.explore()
    return _build(folder), _points(folder)


def _build(folder: _Folder) -> Tldgba:
    automaton = folder.translation.automaton
    store = folder.store
    timed = [atom for key in folder.locations for atom in folder.timed_of(key)]
    bound = max((atom[4] for atom in timed), default=1)
    num_clocks = 1 + max((atom[5] for atom in timed), default=-1)
    locations, edges, jumps = [], [], []
    sink_key = next((k for k in folder.locations if k.kind == "sink"), None)
    sink: Outcome | None = None if sink_key is None else (sink_key, (), 0)
    for key, loc in folder.locations.items():
        folder.deadline.check()
        clocks = sorted({a[5] for a in folder.timed_of(key)})
        states = set(folder.covered[loc].values())
        verdicts: set[Verdict] = {automaton.states[s].verdict for s in states}
        verdict: Verdict = verdicts.pop() if len(verdicts) == 1 else "pending"
        component = automaton.states[min(states)].component
        text = (
            automaton.states[key.state].obligation
            if key.state is not None and not key.templates
            else key_text(store, key)
        )
        locations.append(Location(loc, f"q{loc}", text, component, verdict, tuple(clocks)))
        edges.extend(_edges(folder, loc, clocks, bound, sink))
        some = next(iter(folder.covered[loc]))
        for t_key, resets in sorted(
            folder.jumps[(loc, some)], key=lambda j: folder.locations[j[0]]
        ):
            jumps.append(Jump(loc, folder.locations[t_key], resets))
    return Tldgba(
        source=automaton.source,
        formula=automaton.formula,
        propositions=automaton.propositions,
        clock_bounds=tuple(bound for _ in range(num_clocks)),
        num_sets=automaton.num_sets,
        initial=0,
        locations=tuple(locations),
        edges=tuple(sorted(edges, key=_edge_order)),
        epsilon=tuple(jumps),
    )


def _edges(
    folder: _Folder, loc: int, clocks: list[int], bound: int, sink: Outcome | None
) -> list[Edge]:
    """The edges of one location: per class of letters its states tell apart together
    (:meth:`Shapes.classes`), a partition of its valuations into guards (``sink``: the
    behaviour past every deadline); then the classes with the same guard and outcome share an
    edge, labelled with the union of their letters."""
    num_sets = folder.translation.automaton.num_sets
    points = [tuple(value for _, value in v) for v in folder.covered[loc]]
    behaviours = [folder.behaviour[(loc, v)] for v in folder.covered[loc]]
    found = folder.shapes.classes([row for row, _ in behaviours])
    grouped: dict[tuple[Guard, Outcome], list[int]] = {}
    for c, each in enumerate(found.transitions):
        folder.deadline.check()
        behaviour = {
            point: outcomes[each[index]]
            for point, index, (_, outcomes) in zip(points, found.position, behaviours, strict=True)
        }
        for box, outcome in partition(behaviour, len(clocks), bound, sink):
            guard: Guard = tuple(
                (clocks[d], lo, hi) for d, (lo, hi) in enumerate(box) if (lo, hi) != (0, bound)
            )
            grouped.setdefault((guard, outcome), []).append(c)
    edges = []
    for (guard, (t_key, resets, marks)), members in grouped.items():
        acc = folder.acceptance.get(marks)
        if acc is None:
            acc = folder.acceptance[marks] = tuple(k for k in range(num_sets) if marks >> k & 1)
        label = found.letters[members[0]] if len(members) == 1 else _union(folder, found, members)
        edges.append(Edge(loc, folder.locations[t_key], label, guard, resets, acc))
    return edges


def _union(folder: _Folder, found: LetterClasses, members: list[int]) -> Letters:
    """The letters of several classes (locations of one automaton share most such unions)."""
    cubes = tuple(cube for c in members for cube in found.cubes[c])
    label = folder.labels.get(cubes)
    if label is None:
        label = folder.labels[cubes] = Letters.of_cubes(cubes)
    return label


def _edge_order(edge: Edge) -> tuple[object, ...]:
    return (edge.source, edge.guard, edge.label.least, edge.target)
