"""The states of the digital LDGBA and their one successor function, shared by the eager
translation (:mod:`mitlc.automata.ldba`) and the lazy automaton (:mod:`mitlc.automata.lazy`).

A state is a :class:`Key`: its kind and the normal forms behind it. :class:`Rules` holds what
one formula's translation needs (the term store, its progression, the Master Theorem's μ- and
ν-atoms, the recurrence split) and defines, once, the start state, the successor of a key on a
letter with its acceptance marks, the epsilon jumps of a key, the propositions a key reads
(:meth:`Rules.reads`: the successor and marks of a key depend on the letter only through
``letter & reads(key)``), and the :class:`~mitlc.automata.digital.DigitalState` of a key.
The store's normal forms do not depend on the order they were made in (its subsumption,
:meth:`mitlc.automata.terms.TermStore.implies`), so the keys reached do not depend on
the order in which states were discovered: both automata reach the same ones.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal, NamedTuple, TypeAlias

from mitlc.automata.accepting import Guess, Substitution, guesses, unbounded_atoms
from mitlc.automata.digital import DigitalState, Verdict
from mitlc.automata.ends import END_FAILS, END_HOLDS, holds_after
from mitlc.automata.normalize import normalize
from mitlc.automata.progress import Progression
from mitlc.automata.recurrence import Recurrence, split_recurrence
from mitlc.automata.terms import TermStore
from mitlc.automata.text import form_text
from mitlc.limits import Deadline
from mitlc.syntax import ast

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


class Transitions(NamedTuple):
    """A key's transitions (:meth:`Rules.transitions`): a diagram and the meaning of its
    terminals."""

    diagram: int
    outcome: Callable[[Any], tuple[Key, int]]


SINK = Key("sink")
TRUE = Key("true")


@dataclass(slots=True)
class Rules:
    """One formula's states and transitions (see the module docstring)."""

    store: TermStore
    progression: Progression
    root: int
    mu: tuple[int, ...]
    """The μ-atoms a jump guesses over (empty when the automaton needs no jumps)."""
    nu: tuple[int, ...]
    num_sets: int
    recurrence: Recurrence | None = None
    substitution: Substitution = field(init=False)

    def __post_init__(self) -> None:
        self.substitution = Substitution(self.store)

    @staticmethod
    def of(formula: ast.Formula, store: TermStore | None = None) -> Rules:
        """The rules of ``formula``: its normal form, μ/ν-atoms, acceptance sets, recurrence
        (in ``store`` when given: one that already holds the formula's forms, so that keys of
        two rules over it compare)."""
        store = TermStore(ast.atoms(formula)) if store is None else store
        root = normalize(formula, store)
        mu, nu = unbounded_atoms(store, root)
        num_sets = 0 if not mu else 1 if not nu else len(mu)
        recurrence = split_recurrence(store, root) if mu and nu else None
        if recurrence is not None:
            mu, num_sets = (), recurrence.num_sets
        return Rules(store, Progression(store), root, mu if nu else (), nu, num_sets, recurrence)

    def start(self) -> Key:
        """The initial state."""
        if self.recurrence is not None:
            return Key("recurrence", self.recurrence.start(self.store))
        return self.initial_key(self.root)

    def initial_key(self, after: int) -> Key:
        """The initial-component state of obligation ``after`` (``false``, ``true``: the sinks)."""
        if after == self.store.false:
            return SINK
        if after == self.store.true:
            return TRUE
        return Key("initial", (after,))

    def successor(self, key: Key, letter: int) -> tuple[Key, int]:
        """The successor of ``key`` on ``letter`` and the acceptance marks of that step."""
        if key.kind == "initial":
            return self.initial_key(self.progression.step(key.forms[0], letter)), 0
        step = self.progression.step
        return self.advance(key, [step(form, letter) for form in self.read_forms(key)])

    def advance(self, key: Key, progressed: Sequence[int]) -> tuple[Key, int]:
        """The successor of a key other than an initial one, and its marks, given the
        progressions of :meth:`read_forms` through a letter (in their order)."""
        if key == SINK:
            return SINK, 0
        if key == TRUE:
            return TRUE, (1 << self.num_sets) - 1
        if key.kind == "recurrence":
            assert self.recurrence is not None
            stepped = self.recurrence.advance(self.store, progressed)
            if stepped is None:
                return SINK, 0
            return Key("recurrence", stepped[0]), stepped[1]
        moved = key.guess().advance(self.store, progressed, self.num_sets)
        if moved is None:
            return SINK, 0
        next_guess, marks = moved
        return Key.of_guess(next_guess), marks

    def read_forms(self, key: Key) -> list[int]:
        """The forms whose progressions determine :meth:`successor` of ``key`` (those that
        :meth:`advance` reads; for an initial key, its obligation)."""
        if key.kind == "initial":
            return [key.forms[0]]
        if key.kind == "recurrence":
            assert self.recurrence is not None
            return self.recurrence.read_forms(self.store, key.forms)
        if key.kind == "accepting":
            return key.guess().read_forms(self.store)
        return []

    def reads(self, key: Key) -> int:
        """The mask of the propositions whose value can change :meth:`successor` of ``key``.

        :meth:`Progression.step` reads ``letter & reads(form)`` only, and the successor and the
        marks of a key are functions of the progressions of :meth:`read_forms`, so
        ``successor(key, letter) == successor(key, letter & reads(key))``."""
        mask = 0
        for form in self.read_forms(key):
            mask |= self.progression.reads(form)
        return mask

    def transitions(self, key: Key) -> Transitions:
        """The successor of ``key`` and the marks on every letter: a decision diagram (in
        ``progression.diagrams``) with one terminal per class of letters the key tells apart,
        and what each terminal means, ``(successor key, marks)``. The diagram is that of the
        progressions of :meth:`read_forms`, taken together, and a terminal means what
        :meth:`advance` makes of them: what :meth:`successor` gives on each letter of its class
        (for an initial state, the diagram is its obligation's progression itself)."""
        d = self.progression.diagrams
        if key.kind == "initial":
            initial_key = self.initial_key
            return Transitions(
                self.progression.split(key.forms[0]), lambda after: (initial_key(after), 0)
            )
        together = d.leaf(())
        for form in self.read_forms(key):
            split = self.progression.split(form)
            together = d.apply("tuple", lambda t, v: (*t, v), together, split)
        advance = self.advance
        outcomes: dict[tuple[int, ...], tuple[Key, int]] = {}

        def outcome(progressed: tuple[int, ...]) -> tuple[Key, int]:
            found = outcomes.get(progressed)  # a caller may ask for a terminal again (lazy)
            if found is None:
                found = outcomes[progressed] = advance(key, progressed)
            return found

        return Transitions(together, outcome)

    def jumps(self, key: Key, deadline: Deadline | None = None) -> Iterator[Key]:
        """The targets of the epsilon jumps of ``key``, in the order of :func:`guesses`, each
        once (two guesses may have one key). This order is the one both automata
        list a state's jumps in (:meth:`DigitalAutomaton.jumps
        <mitlc.automata.digital.DigitalAutomaton.jumps>`, :meth:`LazyAutomaton.jumps
        <mitlc.automata.lazy.LazyAutomaton.jumps>`): it depends on the key alone, not on how
        the states were numbered."""
        if key.kind == "initial" and self.mu:
            seen: set[Key] = set()
            for guess in guesses(self.substitution, key.forms[0], self.mu, self.nu, deadline):
                found = Key.of_guess(guess)
                if found not in seen:
                    seen.add(found)
                    yield found

    def state(self, key: Key) -> DigitalState:
        """The obligation, component, verdict and end code of a live state ``key``."""
        if key == SINK:
            return DigitalState("false", "initial", "violated")
        if key == TRUE:
            return DigitalState("true", "initial", "satisfied", END_HOLDS)
        if key.kind == "accepting":  # a guess: proved by completed rounds (mitlc.automata.ends)
            guess = key.guess()
            satisfied = guess.is_trivially_true(self.store)
            verdict: Verdict = "satisfied" if satisfied else "pending"
            return DigitalState(guess.text(self.store), "accepting", verdict, self.end(key))
        owed = form_text(self.store, self.owed(key))
        return DigitalState(owed, "initial", "pending", self.end(key))

    def owed(self, key: Key) -> int:
        """The obligation of an initial or recurrence state ``key``."""
        if key.kind == "recurrence":
            assert self.recurrence is not None
            return self.recurrence.obligation(self.store, key.forms)
        return key.forms[0]

    def end(self, key: Key) -> int:
        """What a stop in ``key`` is worth: an end code of :mod:`mitlc.automata.ends`."""
        if key == SINK:
            return END_FAILS
        if key == TRUE:
            return END_HOLDS
        if key.kind == "accepting":
            guess = key.guess()
            if guess.is_trivially_true(self.store):
                return END_HOLDS
            all_sets = (1 << self.num_sets) - 1
            return holds_after(all_sets) if self.store.end_value(guess.safety) else END_FAILS
        if key.kind == "recurrence":
            assert self.recurrence is not None
            owed = self.recurrence.owed_at_end(self.store, key.forms)
            if not self.store.end_value(owed):
                return END_FAILS
            return holds_after(self.recurrence.round_sets)
        return END_HOLDS if self.store.end_value(self.owed(key)) else END_FAILS

    def surely_live(self, key: Key) -> bool:
        """True for the states :meth:`state` calls satisfied: each loops on itself with every
        acceptance set on every letter, so an accepting run exists from it."""
        if key.kind == "accepting":
            return key.guess().is_trivially_true(self.store)
        return key == TRUE
