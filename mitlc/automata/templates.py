"""Templates: a state's forms with each bounded atom timed, the keys of locations, and their text.

A *timed atom* ``(kind, left, right, base_lo, base_hi, clock)`` is a bounded atom written with
the interval it had when spawned (its base) and the clock started then: at clock value ``x`` its
interval is ``[max(lo - x, 0), hi - x]`` (:func:`shift`). A *template* is a form (a set of
cubes) whose bounded atoms are timed; a location (:class:`LocKey`) is the kind of its states,
their templates and their tokens' seeds. :class:`Matcher` finds, for the atoms of a state
reached from a location, the timed atoms of that location they descend from (their lineage,
which keeps its clock). Used by :mod:`mitlc.automata.fold`.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import NamedTuple, TypeAlias

from mitlc.automata.ldba import StateKind
from mitlc.automata.terms import TermStore
from mitlc.automata.text import atom_text, form_text, timed_atom_text

TimedAtom: TypeAlias = tuple[str, int, int, int, int, int]
"""``(kind, left, right, base_lo, base_hi, clock)``."""
TAtom: TypeAlias = int | TimedAtom
"""An untimed atom (its id) or a timed atom."""
Template: TypeAlias = frozenset[frozenset[TAtom]]
Valuation: TypeAlias = tuple[tuple[int, int], ...]
"""``((clock, value), ...)`` for the clocks a location uses, sorted by clock."""


class LocKey(NamedTuple):
    """A location: the kind of its states, their forms as templates, and the tokens' seeds;
    ``state`` names the one digital state of an unfolded location (a named tuple: hashed and
    compared in C)."""

    kind: StateKind
    templates: tuple[Template, ...] = ()
    seeds: tuple[tuple[int, int], ...] = ()
    state: int | None = None

    def folded(self) -> LocKey:
        """This location before any unfolding."""
        return LocKey(self.kind, self.templates, self.seeds)


Outcome: TypeAlias = tuple[LocKey, tuple[int, ...], int]
"""``(target location, reset clocks, marks)``."""


def shift(base_lo: int, base_hi: int, age: int) -> tuple[int, int]:
    """The interval of an atom spawned with ``[base_lo, base_hi]``, ``age`` steps later."""
    return max(base_lo - age, 0), base_hi - age


class Matcher:
    """Timed atoms of the source location, keyed by what their successor must look like."""

    __slots__ = ("by_signature", "fresh_used", "kept", "store")

    def __init__(self, store: TermStore) -> None:
        self.store = store
        self.by_signature: dict[tuple[object, ...], tuple[int, int, int, int]] = {}
        self.kept: dict[int, int] = {}
        self.fresh_used = False

    def add(self, atom: TimedAtom, values: dict[int, int], step: int, with_operands: bool) -> None:
        kind, left, right, lo, hi, clock = atom
        age = values[clock] + step
        now_lo, now_hi = shift(lo, hi, age)
        signature = (kind, left, right, now_lo, now_hi) if with_operands else (kind, now_lo, now_hi)
        found = self.by_signature.get(signature)
        if found is None or clock < found[2]:
            self.by_signature[signature] = (lo, hi, clock, age)

    def timed(self, atom_id: int, with_operands: bool) -> tuple[TAtom, int | None]:
        """The timed atom for digital atom ``atom_id`` and its clock's value (None: fresh)."""
        kind, lo, hi, left, right = self.store.atoms[atom_id]
        signature = (kind, left, right, lo, hi) if with_operands else (kind, lo, hi)
        found = self.by_signature.get(signature)
        if found is None:
            self.fresh_used = True
            return (kind, left, right, lo, hi, -1), None
        base_lo, base_hi, clock, value = found
        self.kept[clock] = value
        return (kind, left, right, base_lo, base_hi, clock), value


def timed_atoms(template: Template) -> Iterable[TimedAtom]:
    """The timed atoms of a template."""
    for cube in template:
        for atom in cube:
            if isinstance(atom, tuple):
                yield atom


def valuation_of(values: dict[int, int]) -> Valuation:
    """Clock values as a sorted tuple (hashable)."""
    return tuple(sorted(values.items()))


def key_text(store: TermStore, key: LocKey) -> str:
    """The obligation of a location, in the spec syntax with timed atoms."""
    if key.kind in ("sink", "true"):
        return "false" if key.kind == "sink" else "true"
    parts = [template_text(store, key.templates[0])]
    parts += [f"G F ({form_text(store, seed)})" for _, seed in key.seeds]
    return " & ".join(p for p in parts if p != "true") or "true"


def template_text(store: TermStore, template: Template) -> str:
    """A template in the spec syntax with timed atoms."""
    cubes = sorted(template, key=lambda c: (len(c), sorted(map(str, c))))
    if not cubes:
        return "false"
    texts = []
    for cube in cubes:
        atoms = sorted(
            timed_atom_text(store, *a) if isinstance(a, tuple) else atom_text(store, a)
            for a in cube
        )
        texts.append(" & ".join(atoms) if atoms else "true")
    if len(texts) == 1:
        return texts[0]
    return " | ".join(f"({t})" if " & " in t else t for t in texts)
