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
  accepting sink; states are numbered in breadth-first order, so output is canonical.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal, NamedTuple, TypeAlias

from mitlc.automata.accepting import Guess, Substitution, guesses, unbounded_atoms
from mitlc.automata.digital import DigitalAutomaton, DigitalState, Verdict
from mitlc.automata.graph import live_states
from mitlc.automata.normalize import normalize
from mitlc.automata.progress import Progression
from mitlc.automata.recurrence import Recurrence, split_recurrence
from mitlc.automata.terms import TermStore
from mitlc.automata.text import form_text
from mitlc.errors import MitlcError
from mitlc.limits import DEFAULT_TIME_LIMIT, Deadline, LimitError, collector_paused
from mitlc.syntax import ast, to_text

MAX_PROPOSITIONS = 16

StateKind: TypeAlias = Literal["initial", "accepting", "recurrence", "sink", "true"]


class Key(NamedTuple):
    """What a digital state stands for: its kind and its normal forms (a named tuple: hashed
    and compared in C, as the exploration does for every transition).

    ``initial``: ``forms == (obligation,)``. ``accepting``: ``forms == (safety, pending...)``
    with one pending token per ``(k, seed)`` in ``seeds``. ``recurrence``: ``forms == (S, C,
    B_1, N_1, ...)`` (:mod:`mitlc.automata.recurrence`). ``sink`` and ``true``: no forms.
    """

    kind: StateKind
    forms: tuple[int, ...] = ()
    seeds: tuple[tuple[int, int], ...] = ()

    @staticmethod
    def of_guess(guess: Guess) -> Key:
        """The key of an accepting state."""
        pending = tuple(p for _, _, p in guess.tokens)
        seeds = tuple((k, seed) for k, seed, _ in guess.tokens)
        return Key("accepting", (guess.safety, *pending), seeds)

    def guess(self) -> Guess:
        """The accepting state this key stands for."""
        tokens = tuple(
            (k, seed, p) for (k, seed), p in zip(self.seeds, self.forms[1:], strict=True)
        )
        return Guess(self.forms[0], tokens)


SINK = Key("sink")
TRUE = Key("true")


class TranslationError(MitlcError):
    """A formula the translation refuses: too many propositions or states."""


class StateLimitError(TranslationError, LimitError):
    """The translation stopped at its state limit (``max_states``, ``--max-states``)."""


@dataclass(slots=True)
class _Explored:
    """The states found so far and their transitions, in discovery order."""

    keys: list[Key] = field(default_factory=list)
    index: dict[Key, int] = field(default_factory=dict)
    delta: list[list[int]] = field(default_factory=list)
    marks: list[list[int]] = field(default_factory=list)
    epsilon: list[tuple[int, int]] = field(default_factory=list)

    def id(self, key: Key, limit: int) -> int:
        found = self.index.get(key)
        if found is None:
            if len(self.keys) >= limit:
                raise StateLimitError(
                    f"the automaton grows past --max-states {limit}; raise the state limit "
                    "with a larger --max-states (max_states from Python) or simplify the "
                    "formula (smaller bounds, fewer nested operators)"
                )
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


def translate(
    formula: ast.Formula,
    *,
    max_states: int = 1_000_000,
    time_limit: float | None = DEFAULT_TIME_LIMIT,
    deadline: Deadline | None = None,
) -> DigitalAutomaton:
    """The digital LDGBA of ``formula`` (see the module docstring).

    Stops with :class:`StateLimitError` past ``max_states`` states and with
    :class:`mitlc.limits.LimitError` after ``time_limit`` seconds (``None``: no limit), or at
    ``deadline`` when one is given (a clock shared with the caller's other stages)."""
    clock = Deadline.of(deadline, time_limit, "compile")
    return translate_terms(formula, max_states=max_states, deadline=clock).automaton


def translate_terms(
    formula: ast.Formula,
    *,
    max_states: int = 1_000_000,
    time_limit: float | None = DEFAULT_TIME_LIMIT,
    deadline: Deadline | None = None,
) -> Translation:
    """:func:`translate`, keeping the term store and each state's normal form."""
    clock = Deadline.of(deadline, time_limit, "compile").at("translation")
    with collector_paused():
        return _translate_terms(formula, max_states, clock)


def _translate_terms(formula: ast.Formula, max_states: int, deadline: Deadline) -> Translation:
    propositions = ast.atoms(formula)
    if len(propositions) > MAX_PROPOSITIONS:
        raise TranslationError(
            f"{len(propositions)} propositions; the explicit letter table allows at most "
            f"{MAX_PROPOSITIONS}"
        )
    store = TermStore(propositions)
    root = normalize(formula, store)
    mu, nu = unbounded_atoms(store, root)
    num_sets = 0 if not mu else 1 if not nu else len(mu)
    recurrence = split_recurrence(store, root) if mu and nu else None
    if recurrence is not None:
        mu, num_sets = (), recurrence.num_sets
    builder = _Builder(
        store, Progression(store), mu if nu else (), nu, num_sets, max_states, deadline
    )
    builder.recurrence = recurrence
    explored = builder.explore(root)
    return builder.finish(explored, to_text(formula))


@dataclass(slots=True)
class _Builder:
    store: TermStore
    progression: Progression
    mu: tuple[int, ...]
    nu: tuple[int, ...]
    num_sets: int
    max_states: int
    deadline: Deadline
    substitution: Substitution = field(init=False)
    recurrence: Recurrence | None = None

    def __post_init__(self) -> None:
        self.substitution = Substitution(self.store)

    @property
    def letters(self) -> range:
        return range(1 << len(self.store.propositions))

    def explore(self, root: int) -> _Explored:
        """Breadth-first exploration from the initial obligation, jumps included."""
        explored = _Explored()
        start = Key("initial", (root,))
        if self.recurrence is not None:
            start = Key("recurrence", self.recurrence.start(self.store))
        elif root == self.store.true:
            start = TRUE
        elif root == self.store.false:
            start = SINK
        limit, deadline, letters = self.max_states, self.deadline, self.letters
        keys, index = explored.keys, explored.index
        explored.id(start, limit)
        position = 0
        while position < len(keys):
            deadline.check_now()
            key = keys[position]
            targets, marks = [], []
            if key.kind == "initial":  # the common case: no marks, one target per obligation
                targets = self._initial_row(explored, key.forms[0])
                marks = [0] * len(letters)
            else:
                for letter in letters:
                    successor, mark = self._successor(key, letter)
                    found = index.get(successor)
                    targets.append(explored.id(successor, limit) if found is None else found)
                    marks.append(mark)
            explored.delta.append(targets)
            explored.marks.append(marks)
            if key.kind == "initial" and self.mu:
                for guess in guesses(self.substitution, key.forms[0], self.mu, self.nu, deadline):
                    target = explored.id(Key.of_guess(guess), limit)
                    explored.epsilon.append((position, target))
            position += 1
        return explored

    def _initial_row(self, explored: _Explored, form: int) -> list[int]:
        """The successors of the initial-component state of ``form``, letter by letter: what
        :meth:`_successor` gives, each obligation looked up once."""
        step, false, true = self.progression.step, self.store.false, self.store.true
        index, row = explored.index, []
        made: dict[int, int] = {}
        for letter in self.letters:
            after = step(form, letter)
            found = made.get(after)
            if found is None:
                if after == false:
                    successor = SINK
                elif after == true:
                    successor = TRUE
                else:
                    successor = Key("initial", (after,))
                found = index.get(successor)
                if found is None:
                    found = explored.id(successor, self.max_states)
                made[after] = found
            row.append(found)
        return row

    def _successor(self, key: Key, letter: int) -> tuple[Key, int]:
        store, all_sets = self.store, (1 << self.num_sets) - 1
        if key == SINK:
            return SINK, 0
        if key == TRUE:
            return TRUE, all_sets
        if key.kind == "initial":
            after = self.progression.step(key.forms[0], letter)
            if after == store.false:
                return SINK, 0
            if after == store.true:
                return TRUE, 0
            return Key("initial", (after,)), 0
        if key.kind == "recurrence":
            assert self.recurrence is not None
            stepped = self.recurrence.step(self.progression, key.forms, letter)
            if stepped is None:
                return SINK, 0
            return Key("recurrence", stepped[0]), stepped[1]
        moved = key.guess().step(self.progression, letter, self.num_sets)
        if moved is None:
            return SINK, 0
        next_guess, marks = moved
        return Key.of_guess(next_guess), marks

    def finish(self, explored: _Explored, formula_text: str) -> Translation:
        """Merge dead states into the sink, renumber breadth-first, attach the obligations."""
        keys = explored.keys
        sink_ids = {i for i, k in enumerate(keys) if k == SINK}
        live = live_states(
            explored.delta, explored.marks, explored.epsilon, self.num_sets, sink_ids
        )
        order = _bfs_order(explored, live)
        new_id = {old: new for new, old in enumerate(order)}
        sink: int | None = None
        if len(order) < len(keys) or not live:
            sink = len(order)

        # remap[old]: the new id of a live state, the sink's of any other
        remap = [-1 if sink is None else sink] * len(keys)
        for old, new in new_id.items():
            remap[old] = new
        delta = [tuple([remap[t] for t in explored.delta[old]]) for old in order]
        marks = [tuple(explored.marks[old]) for old in order]
        states = []
        for old in order:
            self.deadline.check()
            states.append(self._state(keys[old]))
        new_keys = [keys[old] for old in order]
        if sink is not None:
            new_keys.append(SINK)
            delta.append(tuple(sink for _ in self.letters))
            marks.append(tuple(0 for _ in self.letters))
            states.append(DigitalState("false", "initial", "violated"))
        epsilon = sorted(
            (new_id[s], new_id[t]) for s, t in explored.epsilon if s in live and t in live
        )
        initial = 0 if 0 in live else (sink if sink is not None else 0)
        automaton = DigitalAutomaton(
            source=formula_text,
            formula=formula_text,
            propositions=self.store.propositions,
            states=tuple(states),
            initial=initial,
            delta=tuple(delta),
            marks=tuple(marks),
            num_sets=self.num_sets,
            epsilon=tuple(epsilon),
        )
        return Translation(automaton, self.store, tuple(new_keys))

    def _state(self, key: Key) -> DigitalState:
        if key == SINK:
            return DigitalState("false", "initial", "violated")
        if key == TRUE:
            return DigitalState("true", "initial", "satisfied")
        if key.kind == "initial":
            return DigitalState(form_text(self.store, key.forms[0]), "initial", "pending")
        if key.kind == "recurrence":
            assert self.recurrence is not None
            owed = self.recurrence.obligation(self.store, key.forms)
            return DigitalState(form_text(self.store, owed), "initial", "pending")
        guess = key.guess()
        verdict: Verdict = "satisfied" if guess.is_trivially_true(self.store) else "pending"
        return DigitalState(guess.text(self.store), "accepting", verdict)


def _bfs_order(explored: _Explored, live: set[int]) -> list[int]:
    """Live states in breadth-first order from the initial state: letters, then jumps."""
    if 0 not in live:
        return []
    jumps: dict[int, list[int]] = {}
    for s, t in explored.epsilon:
        jumps.setdefault(s, []).append(t)
    order, seen = [0], {0}
    position = 0
    while position < len(order):
        state = order[position]
        for t in [*explored.delta[state], *jumps.get(state, ())]:
            if t in live and t not in seen:
                seen.add(t)
                order.append(t)
        position += 1
    return order
