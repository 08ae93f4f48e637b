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

from mitlc.product.explicit import VIOLATED, Product
from mitlc.worlds.model import BoolArray, IntArray


def _choice_sources(product: Product) -> IntArray:
    counts = np.diff(product.choice_ptr)
    return np.repeat(np.arange(product.num_states), counts)


def maximal_end_components(product: Product) -> tuple[IntArray, IntArray]:
    """``(component, kept)``: each state's MEC label (``-1`` for none) and a mask of the choices
    that stay inside their MEC."""
    sources = _choice_sources(product)
    per_choice = np.diff(product.transitions.indptr)
    edge_source = np.repeat(sources, per_choice)
    edge_choice = np.repeat(np.arange(product.num_choices), per_choice)
    targets = product.transitions.targets
    kept = np.ones(product.num_choices, dtype=bool)
    alive = np.ones(product.num_states, dtype=bool)
    n = product.num_states
    while True:
        use = kept[edge_choice]
        graph = csr_matrix(
            (np.ones(int(use.sum())), (edge_source[use], targets[use])), shape=(n, n)
        )
        _, labels = connected_components(graph, directed=True, connection="strong")
        labels = np.where(alive, labels, -1)
        leaves = labels[edge_source] != labels[targets]
        leaving = np.zeros(product.num_choices, dtype=bool)
        np.logical_or.at(leaving, edge_choice, leaves | ~alive[targets])
        new_kept = kept & ~leaving & alive[sources]
        has_choice = np.zeros(n, dtype=bool)
        has_choice[sources[new_kept]] = True
        new_alive = alive & has_choice
        if np.array_equal(new_kept, kept) and np.array_equal(new_alive, alive):
            return labels, kept
        kept, alive = new_kept, new_alive


def accepting_states(product: Product) -> BoolArray:
    """The states that lie in an accepting maximal end component (a boolean mask)."""
    labels, kept = maximal_end_components(product)
    sources = _choice_sources(product)
    all_sets = (1 << product.num_sets) - 1
    covered: dict[int, int] = {}
    for c in np.flatnonzero(kept).tolist():
        label = int(labels[sources[c]])
        covered[label] = covered.get(label, 0) | int(product.marks[c])
    good = {label for label, marks in covered.items() if marks == all_sets}
    good.discard(int(labels[VIOLATED]))
    mask: BoolArray = np.isin(labels, list(good)) & (labels >= 0)
    return mask
