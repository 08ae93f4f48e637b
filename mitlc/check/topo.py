"""Maximal reachability in topological order of the strongly connected components.

The products of time-bounded tasks are nearly acyclic: the automaton's clock moves on at every
step, so most components are single states. Components are peeled off from the sinks, a whole
level at a time in numpy: a single state ``x`` gets its value directly,
``max_c (sum_{y != x} P(c, y) v_y) / (1 - P(c, x))`` over the choices that can leave it (a
choice that surely stays contributes nothing), and a larger component is solved by value
iteration from below with every later component's values already fixed (Ciesinski, Baier,
Größer and Klein, "Reduction techniques for model checking Markov decision processes", QEST
2008, describe the same topological ordering).
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

from mitlc.product.explicit import Product
from mitlc.worlds.model import BoolArray, FloatArray, IntArray

TOLERANCE = 1e-14


def _gather(ptr: IntArray, values: IntArray, keys: IntArray) -> IntArray:
    """``concatenate(values[ptr[k]:ptr[k+1]] for k in keys)``, vectorised."""
    counts = ptr[keys + 1] - ptr[keys]
    starts = np.repeat(ptr[keys] - np.cumsum(counts) + counts, counts)
    gathered: IntArray = values[starts + np.arange(int(counts.sum()))]
    return gathered


def _levels(component: IntArray, count: int, sources: IntArray, targets: IntArray) -> IntArray:
    """Each component's level: 0 for components without successors, else one more than the
    largest level among its successors."""
    crossing = component[sources] != component[targets]
    pairs = np.unique(component[sources][crossing] * count + component[targets][crossing])
    tails, heads = pairs // count, pairs % count
    remaining = np.bincount(tails, minlength=count)
    order = np.argsort(heads, kind="stable")
    back_tails = tails[order]
    back_ptr = np.searchsorted(heads[order], np.arange(count + 1))
    level = np.full(count, -1, dtype=np.int64)
    frontier = np.flatnonzero(remaining == 0)
    depth = 0
    while len(frontier):
        level[frontier] = depth
        before = _gather(back_ptr, back_tails, frontier)
        np.subtract.at(remaining, before, 1)
        frontier = np.unique(before[remaining[before] == 0])
        depth += 1
    return level


def topological_values(
    product: Product, matrix: csr_matrix, target: BoolArray, zero: BoolArray
) -> FloatArray:
    """The maximal probabilities of reaching ``target`` (``zero``: states that cannot)."""
    n = product.num_states
    ptr = product.choice_ptr
    choice_state = np.repeat(np.arange(n), np.diff(ptr))
    t = product.transitions
    edge_choice = np.repeat(np.arange(product.num_choices), np.diff(t.indptr))
    edge_source = choice_state[edge_choice]
    graph = csr_matrix((np.ones(len(edge_source)), (edge_source, t.targets)), shape=(n, n))
    count, labels = connected_components(graph, directed=True, connection="strong")
    component = labels.astype(np.int64)
    level = _levels(component, count, edge_source, t.targets)[component]
    size = np.bincount(component, minlength=count)[component]
    stays = np.zeros(product.num_choices)
    loops = t.targets == edge_source
    np.add.at(stays, edge_choice[loops], t.probs[loops])
    values = target.astype(np.float64)
    fixed = target | zero
    by_level = np.argsort(level[choice_state], kind="stable")
    level_ptr = np.searchsorted(level[choice_state][by_level], np.arange(level.max() + 2))
    for depth in range(int(level.max()) + 1):
        choices = by_level[level_ptr[depth] : level_ptr[depth + 1]]
        if len(choices):
            _solve_level(matrix, choices, choice_state, stays, size, values, fixed, n)
    return values


def _solve_level(
    matrix: csr_matrix,
    choices: IntArray,
    choice_state: IntArray,
    stays: FloatArray,
    size: IntArray,
    values: FloatArray,
    fixed: BoolArray,
    n: int,
) -> None:
    """Fix the values of one level's states in place."""
    owner = choice_state[choices]
    rows = matrix[choices]
    single = size[owner] == 1
    if single.any():
        chosen, who = choices[single], owner[single]
        saved = values[who].copy()
        values[who] = 0.0
        rest = rows[single] @ values
        values[who] = saved
        leaving = stays[chosen] < 1.0 - 1e-15
        best = np.full(n, -1.0)
        np.maximum.at(best, who[leaving], rest[leaving] / (1.0 - stays[chosen][leaving]))
        update = np.unique(who)
        update = update[~fixed[update]]
        values[update] = np.maximum(best[update], 0.0)
    group = ~single
    if group.any():
        who, sub = owner[group], rows[group]
        members = np.unique(who)
        members = members[~fixed[members]]
        for _ in range(1_000_000):
            best = np.full(n, -1.0)
            np.maximum.at(best, who, sub @ values)
            new = np.maximum(best[members], 0.0)
            change = np.max(np.abs(new - values[members])) if len(members) else 0.0
            values[members] = new
            if change < TOLERANCE:
                break
