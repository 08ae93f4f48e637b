"""Boolean labels for sets of letters: symbolic letter sets and two-level minimisation.

A letter is an integer whose bit ``i`` says whether proposition ``i`` holds (as in
:mod:`mitlc.automata.digital`). A :class:`Letters` is a set of letters given by the few
propositions it depends on (its support) and the valuations of those it holds: its size is that
of its truth table over its support, never ``2^n`` for ``n`` propositions. It is canonical (the
support is the smallest one), so equal sets are equal values. A :class:`Cube` is a conjunction of
literals: the propositions in ``care`` are fixed to their bit in ``value``, the others are free.
:func:`minimal_cover` turns a set of letters into a short disjunction of cubes whose letters are
exactly that set: the prime implicants by Quine–McCluskey, the essential ones first, then the
fewest further primes (an exact branch and bound for small problems, greedy beyond a node
budget). A :class:`Letters` is covered over its support alone.

Everything is deterministic and the cubes come out in a canonical order, so a label is the same
text on every run. :func:`label_text` writes a cover in mitlc's spec syntax (``a & !b | c``) or
with HOA's proposition indices (``0&!1 | 2``).
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Sequence
from typing import Literal, NamedTuple

MAX_EXACT_PROPS = 10
"""Beyond this many propositions the cover comes from a cheap Shannon split (exact, not minimal):
Quine–McCluskey's prime implicants grow too many to enumerate."""

_SEARCH_BUDGET = 2_000
"""Nodes the exact cover search may visit before it settles for the best cover found."""


class Cube(NamedTuple):
    """The conjunction that fixes each proposition of ``care`` to its bit in ``value``."""

    care: int
    value: int

    def contains(self, letter: int) -> bool:
        """True when ``letter`` satisfies the cube."""
        return letter & self.care == self.value

    def letters(self, num_props: int) -> list[int]:
        """The letters over ``num_props`` propositions that satisfy the cube, ascending."""
        free = ((1 << num_props) - 1) & ~self.care
        out, sub = [], free
        while True:  # every subset of the free propositions, largest first
            out.append(self.value | sub)
            if not sub:
                return out[::-1]
            sub = (sub - 1) & free

    @property
    def num_literals(self) -> int:
        """How many propositions the cube fixes."""
        return self.care.bit_count()


def submasks(mask: int) -> Iterator[int]:
    """Every letter whose true propositions lie in ``mask``, ascending: the classes of letters
    that a reader of the propositions ``mask`` tells apart (``letter & mask``)."""
    sub = 0
    while True:
        yield sub
        if sub == mask:
            return
        sub = (sub - mask) & mask


class Letters(NamedTuple):
    """A set of letters: those whose valuation of the propositions ``support`` is in ``members``
    (each member a letter inside ``support``). Canonical: ``support`` holds only propositions the
    set depends on, so two equal sets are equal values (:meth:`of`). A named tuple, made
    quickly: a folding makes one per class of letters."""

    support: int
    members: frozenset[int]

    @staticmethod
    def of(mask: int, members: Iterable[int]) -> Letters:
        """The letters ``l`` with ``l & mask`` in ``members`` (letters inside ``mask``), with the
        propositions that do not matter dropped from the support."""
        kept = frozenset(members)
        if len(kept) <= 1:  # one valuation depends on every proposition (none: on none)
            return Letters(mask if kept else 0, kept)
        bits = mask
        while bits:
            bit = bits & -bits
            bits ^= bit
            if kept == {m ^ bit for m in kept}:  # closed under flipping ``bit``: it is free
                mask &= ~bit
                kept = frozenset(m & ~bit for m in kept)
        return Letters(mask if kept else 0, kept)

    @staticmethod
    def everything() -> Letters:
        """Every letter (the label ``true``)."""
        return Letters(0, frozenset({0}))

    def __contains__(self, letter: object) -> bool:
        return isinstance(letter, int) and letter & self.support in self.members

    @staticmethod
    def of_cubes(cubes: Iterable[tuple[int, int]]) -> Letters:
        """The letters of a union of cubes ``(care, value)`` (e.g. a decision diagram's paths)."""
        listed = list(cubes)
        if len(listed) == 1:  # a cube depends on every proposition it fixes
            ((care, value),) = listed
            return Letters(care, frozenset((value,)))
        support = 0
        for care, _ in listed:
            support |= care
        members = set()
        for care, value in listed:
            if care == support:  # a whole valuation of the support: one member
                members.add(value)
            else:
                members.update(value | free for free in submasks(support & ~care))
        return Letters.of(support, members)

    def __or__(self, other: Letters) -> Letters:
        mask = self.support | other.support
        return Letters.of(mask, (m for m in submasks(mask) if m in self or m in other))

    def __and__(self, other: Letters) -> Letters:
        mask = self.support | other.support
        return Letters.of(mask, (m for m in submasks(mask) if m in self and m in other))

    @property
    def is_empty(self) -> bool:
        """True for the empty set (the label ``false``)."""
        return not self.members

    @property
    def is_everything(self) -> bool:
        """True for the set of all letters (the label ``true``)."""
        return bool(self.members) and self.support == 0

    @property
    def least(self) -> int:
        """The smallest letter of a non-empty set."""
        return min(self.members)

    def letters(self, num_props: int) -> list[int]:
        """Every letter over ``num_props`` propositions in the set, ascending (``2^num_props``
        letters to look at: for small alphabets and tests)."""
        return [m for m in range(1 << num_props) if m & self.support in self.members]

    def cover(self) -> list[Cube]:
        """A minimal cover (:func:`minimal_cover`) made over the support alone: the same cubes
        as the cover of the whole letter set, since no prime implicant of a set fixes a
        proposition the set does not depend on."""
        bits = [i for i in range(self.support.bit_length()) if self.support >> i & 1]
        compressed = [_compress(m, bits) for m in self.members]
        return [
            Cube(_expand(c.care, bits), _expand(c.value, bits))
            for c in minimal_cover(compressed, len(bits))
        ]

    def text(self, propositions: Sequence[str], style: Literal["spec", "hoa"] = "spec") -> str:
        """The label: its cover in mitlc's syntax (``a & !b | c``, ``true``, ``false``), which
        :func:`mitlc.syntax.parse` reads back, or HOA's label syntax with proposition indices
        (``0&!1 | 2``, ``t``, ``f``)."""
        if style not in ("spec", "hoa"):
            raise ValueError(f"unknown label style {style!r}")
        cover = self.cover()
        if not cover:
            return "false" if style == "spec" else "f"
        cover.sort(key=lambda c: cube_key(c, len(propositions)))
        return " | ".join(cube_text(cube, propositions, style) for cube in cover)


def _compress(letter: int, bits: Sequence[int]) -> int:
    """The bits ``bits`` of ``letter``, packed: bit ``k`` of the result is bit ``bits[k]``."""
    return sum(1 << k for k, b in enumerate(bits) if letter >> b & 1)


def _expand(packed: int, bits: Sequence[int]) -> int:
    """The inverse of :func:`_compress`."""
    return sum(1 << b for k, b in enumerate(bits) if packed >> k & 1)


def cube_key(cube: Cube, num_props: int) -> tuple[int, ...]:
    """The canonical sort key: per proposition, 0 positive, 1 negative, 2 free (truth-table
    order, so ``a & !b`` comes before ``c``)."""
    return tuple(
        (0 if cube.value >> i & 1 else 1) if cube.care >> i & 1 else 2 for i in range(num_props)
    )


def prime_implicants(letters: Iterable[int], num_props: int) -> list[Cube]:
    """The prime implicants of the letter set (Quine–McCluskey), in canonical order."""
    full = (1 << num_props) - 1
    level = {Cube(full, m) for m in letters}
    primes: set[Cube] = set()
    while level:
        merged: set[Cube] = set()
        used: set[Cube] = set()
        for cube in level:
            care = cube.care
            while care:
                bit = care & -care
                care ^= bit
                partner = Cube(cube.care, cube.value ^ bit)
                if partner in level:
                    used.add(cube)
                    used.add(partner)
                    merged.add(Cube(cube.care & ~bit, cube.value & ~bit))
        primes |= level - used
        level = merged
    return sorted(primes, key=lambda c: cube_key(c, num_props))


def minimal_cover(letters: Iterable[int], num_props: int) -> list[Cube]:
    """Cubes whose letters are exactly ``letters``, few of them, in canonical order.

    The empty set gives ``[]`` (false), the full set ``[Cube(0, 0)]`` (true). Up to
    :data:`MAX_EXACT_PROPS` propositions the cover is made of prime implicants: minimum in the
    number of cubes (then of literals) when the search fits its budget, greedy otherwise;
    beyond, a Shannon split gives an exact but not necessarily minimal cover.
    """
    wanted = sorted(set(letters))
    full = (1 << num_props) - 1
    if any(m < 0 or m > full for m in wanted):
        raise ValueError(f"a letter is out of range for {num_props} propositions")
    if not wanted:
        return []
    if len(wanted) == 1 << num_props:
        return [Cube(0, 0)]
    if num_props > MAX_EXACT_PROPS:
        return sorted(_split_cover(set(wanted), num_props), key=lambda c: cube_key(c, num_props))
    primes = prime_implicants(wanted, num_props)
    masks = [_mask(prime, num_props) for prime in primes]
    covering: dict[int, list[int]] = {m: [] for m in wanted}
    for index, mask in enumerate(masks):
        for m in _bits(mask):
            covering[m].append(index)
    chosen = {options[0] for options in covering.values() if len(options) == 1}
    left = sum(1 << m for m in wanted)
    for index in chosen:
        left &= ~masks[index]
    cover = [primes[i] for i in chosen | set(_cover_rest(left, primes, masks, covering))]
    return sorted(cover, key=lambda c: cube_key(c, num_props))


def _split_cover(letters: set[int], k: int) -> list[Cube]:
    """Cubes whose letters over the low ``k`` propositions are exactly ``letters``: split on the
    highest proposition, keep what both halves share free of it, recurse."""
    if not letters:
        return []
    if len(letters) == 1 << k:
        return [Cube(0, 0)]
    bit = 1 << (k - 1)
    low = {m for m in letters if not m & bit}
    high = {m ^ bit for m in letters if m & bit}
    both = low & high
    return (
        [Cube(c.care | bit, c.value) for c in _split_cover(low - both, k - 1)]
        + [Cube(c.care | bit, c.value | bit) for c in _split_cover(high - both, k - 1)]
        + _split_cover(both, k - 1)
    )


def _mask(cube: Cube, num_props: int) -> int:
    """The letters of ``cube`` as a bit set (bit ``m`` for letter ``m``)."""
    return sum(1 << m for m in cube.letters(num_props))


def _bits(mask: int) -> list[int]:
    """The positions of the set bits of ``mask``, ascending."""
    out = []
    while mask:
        low = mask & -mask
        out.append(low.bit_length() - 1)
        mask ^= low
    return out


def _cover_rest(
    left: int, primes: Sequence[Cube], masks: Sequence[int], covering: dict[int, list[int]]
) -> list[int]:
    """Few primes that cover the letter bit set ``left``: greedy, then branch and bound."""
    best = _greedy(left, primes, masks, covering)
    if not left:
        return best

    def cost(indices: Sequence[int]) -> tuple[int, int]:
        return len(indices), sum(primes[i].num_literals for i in indices)

    best_cost = cost(best)
    visited = 0

    def search(rest: int, picked: list[int]) -> None:
        nonlocal best, best_cost, visited
        visited += 1
        if visited > _SEARCH_BUDGET:
            return
        if not rest:
            if cost(picked) < best_cost:
                best, best_cost = list(picked), cost(picked)
            return
        if len(picked) + 1 > best_cost[0]:
            return
        # Branch on the letter with the fewest covering primes.
        pivot = min(_bits(rest), key=lambda m: len(covering[m]))
        for index in covering[pivot]:
            picked.append(index)
            search(rest & ~masks[index], picked)
            picked.pop()

    search(left, [])
    return best


def _greedy(
    left: int, primes: Sequence[Cube], masks: Sequence[int], covering: dict[int, list[int]]
) -> list[int]:
    """Repeatedly the prime covering the most letters of ``left`` (fewest literals, then first)."""
    picked: list[int] = []
    while left:
        candidates = sorted({i for m in _bits(left) for i in covering[m]})
        index = max(
            candidates,
            key=lambda i: ((masks[i] & left).bit_count(), -primes[i].num_literals, -i),
        )
        picked.append(index)
        left &= ~masks[index]
    return picked


def cube_text(
    cube: Cube, propositions: Sequence[str], style: Literal["spec", "hoa"] = "spec"
) -> str:
    """One cube: ``a & !b`` (spec) or ``0&!1`` (hoa); the empty cube is ``true`` / ``t``."""
    literals = []
    for i, name in enumerate(propositions):
        if cube.care >> i & 1:
            atom = name if style == "spec" else str(i)
            literals.append(atom if cube.value >> i & 1 else "!" + atom)
    if not literals:
        return "true" if style == "spec" else "t"
    return (" & " if style == "spec" else "&").join(literals)


def label_text(
    letters: Iterable[int], propositions: Sequence[str], style: Literal["spec", "hoa"] = "spec"
) -> str:
    """The label of a letter set given letter by letter over ``propositions``: the text of its
    :class:`Letters` (:meth:`Letters.text`)."""
    full = (1 << len(propositions)) - 1
    wanted = set(letters)
    if any(m < 0 or m > full for m in wanted):
        raise ValueError(f"a letter is out of range for {len(propositions)} propositions")
    return Letters.of(full, wanted).text(propositions, style)
