"""Maximal end components of a product MDP, and which of them are accepting.

The classical decomposition (de Alfaro, PhD thesis 1997; Baier and Katoen, Principles of Model
Checking, Alg. 47): repeatedly split the states into strongly connected components of the graph
of the remaining choices, and drop every choice that may leave its component, until nothing
changes. An end component is accepting for generalized Büchi acceptance when its choices
together carry every acceptance set: a policy that plays all of them uniformly visits each set
infinitely often with probability 1. With zero sets every end component is accepting except
the violated state's.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

from mitlc.check.topo import choice_sources, spans, state_graph
from mitlc.limits import Deadline
from mitlc.product.explicit import VIOLATED, Product
from mitlc.worlds.model import BoolArray, IntArray


def maximal_end_components(
    product: Product,
    graph: csr_matrix | None = None,
    *,
    deadline: Deadline | None = None,
    components: IntArray | None = None,
) -> tuple[IntArray, BoolArray]:
    """``(component, kept)``: each state's MEC label (``-1`` for none) and a mask of the choices
    that stay inside their MEC (``graph``: :func:`mitlc.check.topo.state_graph`'s, when the
    caller has it). The first round splits the whole state graph; later rounds only the graph
    of the choices kept so far, which in a nearly acyclic product is small. ``deadline`` (none
    by default) is read every round; ``components``: the graph's strongly connected components
    (scipy's labels), when the caller has them."""
    clock = Deadline.none() if deadline is None else deadline
    n = product.num_states
    t = product.transitions
    sources = choice_sources(product)
    per_choice = np.diff(t.indptr)
    graph = state_graph(product) if graph is None else graph
    if components is None:
        _, components = connected_components(graph, directed=True, connection="strong")
    kept = _staying(components, sources, t.targets, t.indptr)
    del components
    alive = np.zeros(n, dtype=bool)
    alive[sources[kept]] = True
    chosen = np.flatnonzero(kept)
    while True:
        clock.check_now()
        edges = spans(t.indptr, chosen)
        local = np.repeat(np.arange(len(chosen)), per_choice[chosen])
        heads, tails = np.repeat(sources[chosen], per_choice[chosen]), t.targets[edges]
        sub = csr_matrix((np.ones(len(heads)), (heads, tails)), shape=(n, n))
        _, found = connected_components(sub, directed=True, connection="strong")
        labels = np.where(alive, found, -1)
        leaves = (labels[heads] != labels[tails]) | ~alive[tails]
        stay = (np.bincount(local[leaves], minlength=len(chosen)) == 0) & alive[sources[chosen]]
        new_alive = np.zeros(n, dtype=bool)
        new_alive[sources[chosen[stay]]] = True
        new_alive &= alive
        if stay.all() and np.array_equal(new_alive, alive):
            return labels, kept
        kept[chosen[~stay]] = False
        chosen, alive = chosen[stay], new_alive


CHUNK = 1 << 20
"""Choices per block in :func:`_staying` (its scratch: a few bytes a transition of a block)."""


def _staying(labels: IntArray, sources: IntArray, targets: IntArray, indptr: IntArray) -> BoolArray:
    """Per choice, whether all its targets lie in its source's component (a choice without
    transitions stays), a block of :data:`CHUNK` choices at a time."""
    choices = len(indptr) - 1
    kept = np.ones(choices, dtype=bool)
    for lo in range(0, choices, CHUNK):
        hi = min(lo + CHUNK, choices)
        a, b = int(indptr[lo]), int(indptr[hi])
        if a == b:
            continue
        per_choice = np.diff(indptr[lo : hi + 1])
        leaves = np.repeat(labels[sources[lo:hi]], per_choice)
        np.not_equal(leaves, labels[targets[a:b]], out=leaves)
        starts = np.minimum(indptr[lo:hi] - a, b - a - 1)
        kept[lo:hi] = (np.maximum.reduceat(leaves, starts) == 0) | (per_choice == 0)
    return kept


def accepting_states(
    product: Product,
    graph: csr_matrix | None = None,
    *,
    deadline: Deadline | None = None,
    components: IntArray | None = None,
) -> BoolArray:
    """The states that lie in an accepting maximal end component (a boolean mask);
    ``components``: the strongly connected components of ``graph`` (scipy's labels), when the
    caller has them."""
    labels, kept = maximal_end_components(product, graph, deadline=deadline, components=components)
    sources = choice_sources(product)
    all_sets = (1 << product.num_sets) - 1
    chosen = np.flatnonzero(kept)
    covered = np.zeros(product.num_states, dtype=np.int64)
    np.bitwise_or.at(covered, labels[sources[chosen]], product.marks[chosen].astype(np.int64))
    good = covered == all_sets
    if labels[VIOLATED] >= 0:
        good[labels[VIOLATED]] = False
    mask: BoolArray = (labels >= 0) & good[labels]
    return mask
