"""The accepting component of the LDGBA: guesses, the Master Theorem's substitutions, and steps.

EKS20 (Esparza, Křetínský, Sickert, JACM 2020), Section 5. For a set ``X`` of unbounded
F/U subformulas (the μ-formulas that hold infinitely often) and ``Y`` of unbounded G/R
subformulas (the ν-formulas that eventually always hold):

* ``φ[X]ν`` replaces each μ-subformula: ``F p`` by ``true`` if it is in ``X`` else ``false``,
  ``p U q`` by ``p' W q'`` (written ``q' R (p' | q')``) if in ``X`` else ``false``;
* ``φ[Y]μ`` replaces each ν-subformula: ``G p`` by ``true`` if in ``Y`` else ``false``,
  ``p R q`` by ``true`` if in ``Y`` else ``p' M q'`` (written ``q' U (p' & q')``);

everything else maps homomorphically (bounded operators included). The accepting state holds
the safety obligation ``S`` and, for each ``χ ∈ X`` (its index ``k`` among the μ-formulas), the
seed ``χ[Y]μ`` and the pending token ``R``: reading a letter, ``R' = af(R | seed)``; when
``R'`` is ``true`` the step is in acceptance set ``k`` and ``R'`` restarts as ``false``. Sets of
μ-formulas not in ``X`` are marked on every step.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from functools import cache
from itertools import combinations

from mitlc.automata.terms import ALWAYS, EVENTUALLY, INF, LIT, RELEASE, UNTIL, TermStore
from mitlc.automata.text import form_text
from mitlc.limits import Deadline


def closure(store: TermStore, form: int) -> frozenset[int]:
    """Every atom occurring in ``form``, operands of temporal atoms included."""
    seen: set[int] = set()
    stack = [form]
    visited_forms: set[int] = set()
    while stack:
        f = stack.pop()
        if f in visited_forms:
            continue
        visited_forms.add(f)
        for cube in store.forms[f]:
            for atom in cube:
                if atom not in seen:
                    seen.add(atom)
                    kind, _, _, left, right = store.atoms[atom]
                    if kind != LIT:
                        stack.append(left)
                        if kind in (UNTIL, RELEASE):
                            stack.append(right)
    return frozenset(seen)


def _is_unbounded(store: TermStore, atom: int, kinds: tuple[str, ...]) -> bool:
    kind, lo, hi, _, _ = store.atoms[atom]
    return kind in kinds and lo == 0 and hi == INF


def unbounded_atoms(store: TermStore, form: int) -> tuple[tuple[int, ...], tuple[int, ...]]:
    """The unbounded μ-atoms (F, U) and ν-atoms (G, R) of ``form``, each sorted by id."""
    atoms = closure(store, form)
    mu = tuple(sorted(a for a in atoms if _is_unbounded(store, a, (EVENTUALLY, UNTIL))))
    nu = tuple(sorted(a for a in atoms if _is_unbounded(store, a, (ALWAYS, RELEASE))))
    return mu, nu


class Substitution:
    """``φ[X]ν`` and ``φ[Y]μ`` over one store, memoised."""

    def __init__(self, store: TermStore) -> None:
        self.store = store
        self.nu = cache(self._nu)
        self.mu = cache(self._mu)

    def _nu(self, form: int, xs: frozenset[int]) -> int:
        return self.store.substitute(form, lambda atom: self._nu_atom(atom, xs))

    def _nu_atom(self, atom: int, xs: frozenset[int]) -> int:
        store = self.store
        kind, lo, hi, left, right = store.atoms[atom]
        if kind == LIT:
            return store.atom_form(atom)
        if _is_unbounded(store, atom, (EVENTUALLY,)):
            return store.true if atom in xs else store.false
        if _is_unbounded(store, atom, (UNTIL,)):
            if atom not in xs:
                return store.false
            p, q = self.nu(left, xs), self.nu(right, xs)
            return store.temporal(RELEASE, 0, INF, q, store.or_(p, q))
        if kind in (EVENTUALLY, ALWAYS):
            return store.temporal(kind, lo, hi, self.nu(left, xs))
        return store.temporal(kind, lo, hi, self.nu(left, xs), self.nu(right, xs))

    def _mu(self, form: int, ys: frozenset[int]) -> int:
        return self.store.substitute(form, lambda atom: self._mu_atom(atom, ys))

    def _mu_atom(self, atom: int, ys: frozenset[int]) -> int:
        store = self.store
        kind, lo, hi, left, right = store.atoms[atom]
        if kind == LIT:
            return store.atom_form(atom)
        if _is_unbounded(store, atom, (ALWAYS,)):
            return store.true if atom in ys else store.false
        if _is_unbounded(store, atom, (RELEASE,)):
            if atom in ys:
                return store.true
            p, q = self.mu(left, ys), self.mu(right, ys)
            return store.temporal(UNTIL, 0, INF, q, store.and_(p, q))
        if kind in (EVENTUALLY, ALWAYS):
            return store.temporal(kind, lo, hi, self.mu(left, ys))
        return store.temporal(kind, lo, hi, self.mu(left, ys), self.mu(right, ys))


@dataclass(frozen=True, slots=True)
class Guess:
    """An accepting-component state: the safety obligation and one token per ``χ ∈ X``."""

    safety: int
    tokens: tuple[tuple[int, int, int], ...]
    """``(k, seed, pending)`` for each ``χ_k ∈ X``, by increasing ``k``."""

    def read_forms(self, store: TermStore) -> list[int]:
        """The forms whose progressions :meth:`advance` reads: ``S``, then ``R | seed`` for
        each token."""
        return [self.safety, *(store.or_(pending, seed) for _, seed, pending in self.tokens)]

    def advance(
        self, store: TermStore, progressed: Sequence[int], num_sets: int
    ) -> tuple[Guess, int] | None:
        """The successor and its acceptance marks, given the progressions of
        :meth:`read_forms` through a letter (in their order); ``None`` if ``S`` fails."""
        safety = progressed[0]
        if safety == store.false:
            return None
        marks = (1 << num_sets) - 1
        tokens = []
        for (k, seed, _), after in zip(self.tokens, progressed[1:], strict=True):
            if after == store.true:
                after = store.false
            else:
                marks &= ~(1 << k)
            tokens.append((k, seed, after))
        return Guess(safety, tuple(tokens)), marks

    def is_trivially_true(self, store: TermStore) -> bool:
        """``S`` is true and no recurrence is owed: every continuation is accepted."""
        return self.safety == store.true and all(seed == store.true for _, seed, _ in self.tokens)

    def text(self, store: TermStore) -> str:
        """The obligation of this state: ``S & G F seed`` for each token."""
        parts = [form_text(store, self.safety)] if self.safety != store.true else []
        parts += [_recurrence_text(store, seed) for _, seed, _ in self.tokens]
        return " & ".join(f"({p})" if " " in p and len(parts) > 1 else p for p in parts) or "true"


def _recurrence_text(store: TermStore, seed: int) -> str:
    """``G F seed``, written ``G F b`` (not ``G F F b``) for a seed ``F b``, as the formula was."""
    if store.is_unbounded(seed, EVENTUALLY):
        return f"G {form_text(store, seed)}"
    return f"G F ({form_text(store, seed)})"


def guesses(
    substitution: Substitution,
    form: int,
    mu: tuple[int, ...],
    nu: tuple[int, ...],
    deadline: Deadline | None = None,
) -> Iterator[Guess]:
    """The accepting states an epsilon jump from obligation ``form`` may enter, each once.

    There are up to ``2^|mu| * 2^|nu|`` candidates (most of them empty for most formulas);
    ``deadline`` is read at each, so a formula with many recurrences stops at its time limit."""
    clock = Deadline.none() if deadline is None else deadline
    store = substitution.store
    present = closure(store, form)
    mu_here = [a for a in mu if a in present]
    nu_here = [a for a in nu if a in present]
    index = {a: k for k, a in enumerate(mu)}
    produced: set[Guess] = set()
    for xs in _subsets(mu_here):
        safety_core = substitution.nu(form, xs)
        if safety_core == store.false:
            continue
        always: dict[int, int] = {}  # chi -> G (chi[X]ν), made when first needed
        for ys in _subsets(nu_here):
            clock.check_now()
            safety = safety_core
            for chi in sorted(ys):
                found = always.get(chi)
                if found is None:
                    weak = substitution.nu(store.atom_form(chi), xs)
                    found = always[chi] = store.temporal(ALWAYS, 0, INF, weak)
                safety = store.and_(safety, found)
            if safety == store.false:
                continue
            seeds = [(index[chi], substitution.mu(store.atom_form(chi), ys)) for chi in sorted(xs)]
            if any(seed == store.false for _, seed in seeds):
                continue
            # A recurrence `G F true` holds on every step: like a set outside X, always marked.
            seeds = [(k, seed) for k, seed in seeds if seed != store.true]
            guess = Guess(safety, tuple((k, seed, store.false) for k, seed in sorted(seeds)))
            if guess not in produced:
                produced.add(guess)
                yield guess


def _subsets(items: list[int]) -> Iterator[frozenset[int]]:
    for size in range(len(items) + 1):
        for chosen in combinations(items, size):
            yield frozenset(chosen)
