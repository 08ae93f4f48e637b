"""Runs of a digital automaton on words: acceptance of lassos and runs over finite words.

:func:`accepts_lasso` decides whether a :class:`~mitlc.automata.digital.DigitalAutomaton` has an
accepting run on the ultimately periodic word ``prefix loop^omega``, exactly, on the product of
the automaton's states with the lasso's canonical positions. It is the bridge between the
translation and the reference semantics (:func:`mitlc.semantics.holds_lasso`) in the tests.
"""

from __future__ import annotations

from collections.abc import Sequence

from mitlc.automata.digital import DigitalAutomaton
from mitlc.semantics import Lasso

_EPSILON = -1
"""The mark recorded for an epsilon edge of the product (letter edges have marks ``>= 0``)."""


def accepts_lasso(automaton: DigitalAutomaton, lasso: Lasso) -> bool:
    """Whether ``automaton`` has an accepting run on ``lasso.prefix lasso.loop^omega``.

    A run starts in ``automaton.initial`` at position 0; at each position it may take epsilon
    jumps (no letter, no marks) and then takes the letter transition of its state. It accepts iff
    it takes, infinitely often, a transition of every acceptance set; with zero sets, iff it
    never enters a violated state.

    The product graph has a node per (state, canonical position). The word is accepted iff some
    strongly connected component reachable from ``(initial, 0)`` contains a letter edge and the
    marks of its internal letter edges cover every set. With zero sets violated states are left
    out of the graph (their self-loops must not count). Without epsilon jumps the product is a
    single path that ends in a cycle, which is simulated directly.
    """
    size = lasso.size
    loop_start = len(lasso.prefix)
    letters = [automaton.letter_index(letter) for letter in lasso.letters]
    following = [*range(1, size), loop_start]
    step = automaton.successor
    need = automaton.all_sets
    if automaton.num_sets == 0:
        bad = frozenset(i for i, st in enumerate(automaton.states) if st.verdict == "violated")
    else:
        bad = frozenset()
    if automaton.initial in bad:
        return False
    if not automaton.epsilon:
        return _deterministic_accepts(automaton, letters, following, bad, need)

    jumps: dict[int, list[int]] = {}
    for source, target in automaton.epsilon:
        if target not in bad:
            jumps.setdefault(source, []).append(target)

    def successors(node: int) -> list[tuple[int, int]]:
        state, pos = divmod(node, size)
        letter = letters[pos]
        out = [(t * size + pos, _EPSILON) for t in jumps.get(state, ())]
        target, marks = step(state, letter)
        if target not in bad:
            out.append((target * size + following[pos], marks))
        return out

    # Iterative Tarjan, exploring the product on the fly from (initial, 0).
    root = automaton.initial * size
    index: dict[int, int] = {root: 0}
    low: dict[int, int] = {root: 0}
    succ: dict[int, list[tuple[int, int]]] = {root: successors(root)}
    stack: list[int] = [root]
    on_stack: set[int] = {root}
    work: list[tuple[int, int]] = [(root, 0)]  # (node, next successor to look at)
    while work:
        node, i = work[-1]
        edges = succ[node]
        if i < len(edges):
            work[-1] = (node, i + 1)
            child = edges[i][0]
            if child not in index:
                index[child] = low[child] = len(index)
                succ[child] = successors(child)
                stack.append(child)
                on_stack.add(child)
                work.append((child, 0))
            elif child in on_stack and index[child] < low[node]:
                low[node] = index[child]
            continue
        work.pop()
        if work:
            parent = work[-1][0]
            if low[node] < low[parent]:
                low[parent] = low[node]
        if low[node] != index[node]:
            continue
        members: set[int] = set()
        while True:
            member = stack.pop()
            on_stack.discard(member)
            members.add(member)
            if member == node:
                break
        if _component_accepts(members, succ, need):
            return True
    return False


def _component_accepts(
    members: set[int], succ: dict[int, list[tuple[int, int]]], need: int
) -> bool:
    """Whether the component has an internal letter edge and its marks cover ``need``."""
    covered = 0
    cyclic = False
    for member in members:
        for target, mark in succ[member]:
            if mark != _EPSILON and target in members:
                cyclic = True
                covered |= mark
    return cyclic and covered & need == need


def _deterministic_accepts(
    automaton: DigitalAutomaton,
    letters: list[int],
    following: list[int],
    bad: frozenset[int],
    need: int,
) -> bool:
    """Acceptance without epsilon jumps: follow the one run until a product node repeats."""
    size = len(letters)
    seen: dict[int, int] = {}  # product node -> step at which it was entered
    step_marks: list[int] = []
    state, pos = automaton.initial, 0
    while True:
        node = state * size + pos
        if node in seen:
            covered = 0
            for mark in step_marks[seen[node] :]:
                covered |= mark
            return covered & need == need
        seen[node] = len(step_marks)
        letter = letters[pos]
        state, marks = automaton.successor(state, letter)
        step_marks.append(marks)
        pos = following[pos]
        if state in bad:
            return False


def run_states(automaton: DigitalAutomaton, word: Sequence[frozenset[str]]) -> list[int]:
    """The states of the run without jumps over the finite ``word``, ``len(word) + 1`` of them:
    ``automaton.initial`` followed by the successor after each letter."""
    state = automaton.initial
    visited = [state]
    for letter in word:
        state = automaton.successor(state, automaton.letter_index(letter))[0]
        visited.append(state)
    return visited
