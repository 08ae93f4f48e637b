"""Decision diagrams over the propositions: the symbolic letters of the translation.

A letter is an integer whose bit ``i`` says whether proposition ``i`` holds. A *diagram* is a
reduced ordered decision diagram whose inner nodes test one proposition and whose terminals hold
any hashable value: a multi-terminal BDD (Bryant, "Graph-based algorithms for Boolean function
manipulation", IEEE ToC 1986; Clarke, McMillan, Zhao, Fujita, Yang, "Spectral transforms for
large Boolean functions with applications to technology mapping", DAC 1993). mitlc's diagrams
map a letter to what a state does on it (a progressed obligation, a successor and its marks), so
the classes of letters a state tells apart are the terminals of its diagram: a state that
avoids three hazards and waits for one room has a handful of classes, not ``2^n``.

Nodes are hash-consed in a :class:`Diagrams` store, so equal functions are equal node ids, and
operations are memoised. The variable order puts the highest proposition at the top: a
depth-first walk that takes the low branch first then meets the terminals in increasing order of
their least letter (:meth:`Diagrams.classes`), the order in which a table over all letters
lists them, so states are numbered as an explicit translation would number them.

No library is used: ``dd`` (the maintained Python BDD package) has Boolean BDDs only, and the
transition function of a state needs terminals that are states; the few operations needed here
(apply, map, evaluate, classes, paths) fit in this module.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable, Iterator
from typing import Any

from mitlc.limits import Deadline

LEAF = -1
"""The variable of a terminal node (below every proposition)."""


class Diagrams:
    """A store of reduced ordered decision diagrams with arbitrary terminal values."""

    def __init__(self) -> None:
        self.var: list[int] = []
        self.low: list[int] = []
        self.high: list[int] = []
        self.values: list[Any] = []
        self._leaves: dict[Hashable, int] = {}
        self._inner: dict[int, int] = {}
        self._memos: dict[Hashable, dict[int, int]] = {}
        self.deadline = Deadline.none()
        """Looked at in every operation's recursion (:meth:`Deadline.check`): one state's
        progression can be a long computation of its own (``F p0 & ... & F p61``)."""

    def leaf(self, value: Hashable) -> int:
        """The terminal holding ``value`` (values are told apart by equality: do not mix
        ``True`` and ``1`` in one store)."""
        found = self._leaves.get(value)
        if found is None:
            found = self._leaves[value] = self._add(LEAF, -1, -1, value)
        return found

    def _memo(self, name: Hashable | None) -> dict[int, int]:
        """The memo of one operation: ``f << 32 | g`` -> result (int keys: nothing for the
        cyclic garbage collector to scan); ``None``: one for this call only."""
        if name is None:
            return {}
        found = self._memos.get(name)
        if found is None:
            found = self._memos[name] = {}
        return found

    def node(self, var: int, low: int, high: int) -> int:
        """The node testing proposition ``var``: ``low`` where it is false, ``high`` where true
        (reduced: a test whose branches agree is its branch)."""
        if low == high:
            return low
        key = (var << 32 | low) << 32 | high  # an int: nothing for the collector to scan
        found = self._inner.get(key)
        if found is None:
            found = self._inner[key] = self._add(var, low, high, None)
        return found

    def _add(self, var: int, low: int, high: int, value: Any) -> int:
        self.var.append(var)
        self.low.append(low)
        self.high.append(high)
        self.values.append(value)
        return len(self.var) - 1

    # The recursions below are methods, not nested functions: a nested recursive function is a
    # reference cycle, left for the cyclic garbage collector on every call.

    def apply(
        self, name: Hashable | None, op: Callable[[Any, Any], Hashable], f: int, g: int
    ) -> int:
        """The diagram of ``op(f(l), g(l))`` on every letter ``l``; ``name`` identifies ``op``
        for the memo (the same name must always mean the same operation; ``None`` for an
        operation made once, whose memo is not kept)."""
        if self.var[f] == LEAF and self.var[g] == LEAF:
            return self.leaf(op(self.values[f], self.values[g]))
        return self._apply(self._memo(name), op, f, g)

    def _apply(
        self, memo: dict[int, int], op: Callable[[Any, Any], Hashable], f: int, g: int
    ) -> int:
        key = f << 32 | g
        found = memo.get(key)
        if found is not None:
            return found
        self.deadline.check()
        var, low, high = self.var, self.low, self.high
        vf, vg = var[f], var[g]
        if vf == vg:
            if vf == LEAF:
                found = memo[key] = self.leaf(op(self.values[f], self.values[g]))
                return found
            lo = self._apply(memo, op, low[f], low[g])
            hi = self._apply(memo, op, high[f], high[g])
        elif vf > vg:
            vg = vf
            lo, hi = self._apply(memo, op, low[f], g), self._apply(memo, op, high[f], g)
        else:
            lo, hi = self._apply(memo, op, f, low[g]), self._apply(memo, op, f, high[g])
        found = memo[key] = self.node(vg, lo, hi)
        return found

    def map(self, name: Hashable | None, op: Callable[[Any], Hashable], f: int) -> int:
        """The diagram of ``op(f(l))``; ``name`` identifies ``op`` for the memo (``None``: an
        operation made once)."""
        if self.var[f] == LEAF:
            return self.leaf(op(self.values[f]))
        return self._map(self._memo(None if name is None else ("map", name)), op, f)

    def _map(self, memo: dict[int, int], op: Callable[[Any], Hashable], f: int) -> int:
        found = memo.get(f)
        if found is None:
            self.deadline.check()
            if self.var[f] == LEAF:
                found = self.leaf(op(self.values[f]))
            else:
                low, high = self._map(memo, op, self.low[f]), self._map(memo, op, self.high[f])
                found = self.node(self.var[f], low, high)
            memo[f] = found
        return found

    def evaluate(self, f: int, letter: int) -> Any:
        """The value of ``f`` on ``letter``."""
        var, low, high = self.var, self.low, self.high
        while var[f] != LEAF:
            f = high[f] if letter >> var[f] & 1 else low[f]
        return self.values[f]

    def classes(self, f: int) -> list[tuple[Any, int]]:
        """Each distinct value of ``f`` with its least letter, in increasing order of those."""
        var, low, high = self.var, self.low, self.high
        seen: set[int] = set()
        out: list[tuple[Any, int]] = []
        stack = [(f, 0)]  # depth first, low branch first
        while stack:
            node, letter = stack.pop()
            if node in seen:  # met before on a smaller letter, with all it leads to
                continue
            seen.add(node)
            if var[node] == LEAF:
                out.append((self.values[node], letter))
                continue
            stack.append((high[node], letter | 1 << var[node]))
            stack.append((low[node], letter))
        return out

    def paths(self, f: int) -> Iterator[tuple[int, int, Any]]:
        """Every path of ``f``: ``(care, value, terminal value)``, the propositions it tests,
        their values and where it ends (disjoint cubes that cover every letter)."""
        var, low, high = self.var, self.low, self.high
        stack = [(f, 0, 0)]
        while stack:
            node, care, value = stack.pop()
            if var[node] == LEAF:
                yield care, value, self.values[node]
                continue
            bit = 1 << var[node]
            stack.append((high[node], care | bit, value | bit))
            stack.append((low[node], care | bit, value))
