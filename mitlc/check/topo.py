"""Maximal reachability in topological order of the strongly connected components.

The products of time-bounded tasks are nearly acyclic: the automaton's clock moves on at every
step, so most components are single states. The components are layered by Kahn's algorithm
(Kahn, "Topological sorting of large networks", CACM 1962), a whole layer at a time in numpy:
layer 0 has no successors, and layer ``d + 1`` the components whose successors all lie in
layers up to ``d``. Layers are solved from the sinks up: a single state ``x`` gets its value
directly, ``max_c (sum_{y != x} P(c, y) v_y) / (1 - P(c, x))`` over the choices that can leave
it (a choice that surely stays contributes nothing), and a larger component is solved by value
iteration from below with every later component's values already fixed (Ciesinski, Baier,
Größer and Klein, "Reduction techniques for model checking Markov decision processes", QEST
2008, describe the same topological ordering).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import breadth_first_order, connected_components

from mitlc.limits import Deadline
from mitlc.product.builder import INDEX_LIMIT
from mitlc.product.explicit import SATISFIED, VIOLATED, Product
from mitlc.worlds.model import BoolArray, FloatArray, IntArray

TOLERANCE = 1e-14

CHUNK = 1 << 18
"""States per block where a pass over the transitions makes scratch the size of a block's."""


def state_graph(product: Product) -> csr_matrix:
    """The product's state graph (``x -> y`` when some choice of ``x`` may reach ``y``) in
    compressed rows, read off the choice rows; each edge once (scipy 1.17's strongly connected
    components do not terminate on duplicate edges). Duplicates are merged on a boolean
    pattern (sorted in place; a sum of booleans never drops an edge), so the transient memory
    is 5 bytes a transition. Its data is one ``1.0`` seen through a zero stride (read-only):
    scipy's graph routines want float64 data but read only the structure, so the graph holds
    4 bytes an edge, not 12."""
    t = product.transitions
    n = product.num_states
    indptr = t.indptr[product.choice_ptr]
    pattern = np.ones(len(t.targets), dtype=np.bool_)
    graph = csr_matrix((pattern, t.targets.copy(), indptr), shape=(n, n))
    graph.sum_duplicates()
    return _ones(graph.indices, graph.indptr, n)


def _ones(indices: IntArray, indptr: IntArray, n: int) -> csr_matrix:
    """The ``n x n`` graph of ``indices`` and ``indptr`` with every weight ``1.0``, the
    weights a zero-stride view (no array of them is made)."""
    ones = np.broadcast_to(np.float64(1.0), (len(indices),))
    return csr_matrix((ones, indices, indptr), shape=(n, n))


def _reversed(graph: csr_matrix) -> tuple[IntArray, IntArray]:
    """``(ptr, tails)``: the predecessors of ``y`` in ``graph`` are ``tails[ptr[y]:ptr[y+1]]``
    (its pattern in compressed columns, made from a boolean one: 5 bytes an edge)."""
    pattern = np.ones(len(graph.indices), dtype=np.bool_)
    back = csr_matrix((pattern, graph.indices, graph.indptr), shape=graph.shape).tocsc()
    return back.indptr, back.indices


def choice_sources(product: Product) -> IntArray:
    """The state of every choice (32-bit)."""
    counts = np.diff(product.choice_ptr)
    sources: IntArray = np.repeat(np.arange(product.num_states, dtype=np.int32), counts)
    return sources


def into_choices(product: Product) -> tuple[IntArray, IntArray]:
    """``(ptr, choices)``: the choices that may reach state ``y`` are
    ``choices[ptr[y]:ptr[y+1]]`` (the choice matrix's pattern in compressed columns, made from
    a boolean pattern: about 5 bytes a transition)."""
    t = product.transitions
    pattern = np.ones(len(t.targets), dtype=np.bool_)
    shape = (product.num_choices, product.num_states)
    into = csr_matrix((pattern, t.targets, t.indptr), shape=shape).tocsc()
    return into.indptr.astype(np.int64), into.indices


def backward_reachable(graph: csr_matrix, target: BoolArray) -> BoolArray:
    """The states of ``graph`` with a path to ``target`` (``target`` included): one
    breadth-first search in C over the reversed graph, from a virtual state before every
    target state."""
    n = graph.shape[0]
    back_ptr, back_tails = _reversed(graph)
    sources = np.flatnonzero(target).astype(back_tails.dtype)
    indptr = np.concatenate([back_ptr, [back_ptr[-1] + len(sources)]]).astype(back_ptr.dtype)
    indices = np.concatenate([back_tails, sources])
    del back_ptr, back_tails
    extended = _ones(indices, indptr, n + 1)
    order = breadth_first_order(extended, n, directed=True, return_predecessors=False)
    found = np.zeros(n + 1, dtype=bool)
    found[order] = True
    return found[:n]


def spans(ptr: IntArray, keys: IntArray) -> IntArray:
    """``concatenate(arange(ptr[k], ptr[k+1]) for k in keys)``, vectorised."""
    counts = ptr[keys + 1] - ptr[keys]
    starts = np.repeat(ptr[keys] - np.cumsum(counts) + counts, counts)
    indices: IntArray = starts + np.arange(int(counts.sum()))
    return indices


def gather(ptr: IntArray, values: IntArray, keys: IntArray) -> IntArray:
    """``concatenate(values[ptr[k]:ptr[k+1]] for k in keys)``, vectorised."""
    gathered: IntArray = values[spans(ptr, keys)]
    return gathered


def layers(forward: csr_matrix) -> tuple[IntArray, IntArray]:
    """``(order, ptr)``: the nodes of an acyclic graph (self-loops allowed) layered by Kahn's
    algorithm, layer ``d`` being ``order[ptr[d]:ptr[d+1]]`` (``ptr`` ends with the node count);
    layer 0 has no successors."""
    order, ptr, _ = _kahn(forward)
    return order, ptr


def _kahn(forward: csr_matrix) -> tuple[IntArray, IntArray, IntArray]:
    """:func:`layers`, and the nodes with a self-loop (found on the way)."""
    count = forward.shape[0]
    per_row = np.diff(forward.indptr)
    tails = np.repeat(np.arange(count, dtype=np.int32), per_row)
    looped = tails[tails == forward.indices]  # a row's edges are distinct: one loop at most
    del tails
    remaining = per_row.astype(np.int64) - np.bincount(looped, minlength=count)
    del per_row
    back_ptr, back_tails = _reversed(forward)  # column j lists the predecessors of j
    slot = np.zeros(count, dtype=np.int64)
    frontier = np.flatnonzero(remaining == 0)
    found = [frontier]
    while len(frontier):
        before = gather(back_ptr, back_tails, frontier)
        np.subtract.at(remaining, before, 1)
        ready = before[remaining[before] == 0]  # a self-loop takes its own node below 0
        index = np.arange(len(ready))
        slot[ready] = index
        frontier = ready[slot[ready] == index]  # one copy of each
        found.append(frontier)
    sizes = np.array([len(f) for f in found[:-1]], dtype=np.int64)
    ptr = np.concatenate([[0], np.cumsum(sizes)])
    order = np.concatenate(found)
    if len(order) != count:
        raise ValueError("the graph has a cycle of more than one node")
    return order, ptr, looped


@dataclass(frozen=True, slots=True)
class Layering:
    """The Kahn layers of a product whose state graph is acyclic but for self-loops
    (:func:`layers`' ``order`` and ``ptr``), found once by ``pmax`` and read again by
    ``pmax_horizon``; ``absorbing_loops`` says whether the only self-loops are those of the
    two absorbing states (what :func:`acyclic_horizon` needs)."""

    order: IntArray
    ptr: IntArray
    absorbing_loops: bool


def layering(graph: csr_matrix) -> Layering | None:
    """The product's :class:`Layering` from its :func:`state_graph`, or ``None`` when the
    graph has a cycle of more than one state."""
    try:
        order, ptr, looped = _kahn(graph)
    except ValueError:
        return None
    absorbing = not ((looped != SATISFIED) & (looped != VIOLATED)).any()
    if len(order) <= INDEX_LIMIT:  # held from pmax to pmax_horizon: 4 bytes a state
        order = order.astype(np.int32)
    return Layering(order, ptr, absorbing)


def topological_values(
    product: Product,
    matrix: csr_matrix,
    target: BoolArray,
    zero: BoolArray,
    graph: csr_matrix,
    *,
    deadline: Deadline | None = None,
    components: IntArray | None = None,
    layered: Layering | None = None,
) -> FloatArray:
    """The maximal probabilities of reaching ``target`` (``zero``: states that cannot);
    ``graph`` is the product's :func:`state_graph`. ``deadline`` (none by default) is read at
    every layer and every sweep of a larger component's value iteration; ``components``: the
    graph's strongly connected components (scipy's labels), when the caller has them;
    ``layered``: the graph's :func:`layering`, when the caller has it (then the graph is
    acyclic but for self-loops and ``components`` is not read)."""
    clock = Deadline.none() if deadline is None else deadline
    n = product.num_states
    if layered is not None:
        size = np.ones(n, dtype=np.int64)
        return _solve_layers(product, matrix, layered.order, layered.ptr, size, target, zero, clock)
    if components is None:
        count, labels = connected_components(graph, directed=True, connection="strong")
    else:
        count, labels = int(components.max()) + 1 if len(components) else 0, components
    if count == n:  # every component a single state: the state graph is the condensation
        order, ptr = layers(graph)
        size = np.ones(n, dtype=np.int64)
    else:
        component = labels.astype(np.int64)
        sources = np.repeat(component, np.diff(graph.indptr))
        condensed = csr_matrix(
            (np.ones(len(sources)), (sources, component[graph.indices])), shape=(count, count)
        )
        level = np.empty(count, dtype=np.int64)
        by_level, level_ptr = layers(condensed)
        level[by_level] = np.repeat(np.arange(len(level_ptr) - 1), np.diff(level_ptr))
        order = np.argsort(level[component], kind="stable")
        ptr = np.searchsorted(level[component][order], np.arange(len(level_ptr)))
        size = np.bincount(component, minlength=count)[component]
    return _solve_layers(product, matrix, order, ptr, size, target, zero, clock)


def _solve_layers(
    product: Product,
    matrix: csr_matrix,
    order: IntArray,
    ptr: IntArray,
    size: IntArray,
    target: BoolArray,
    zero: BoolArray,
    deadline: Deadline,
) -> FloatArray:
    """The values, layer by layer from the sinks; ``order[ptr[d]:ptr[d+1]]`` are layer ``d``'s
    states and ``size`` each state's component size."""
    t = product.transitions
    per_state = np.diff(product.choice_ptr)
    if (per_state[order] == 0).any():
        raise ValueError("a product state without choices")
    stays, leaving = _self_loops(product)
    denominator = np.where(leaving, 1.0 - stays, 1.0)
    del stays
    # A state's own value is 0 until its layer is solved, so its self-loops add nothing to the
    # sums below: each layer reads the product's rows where they are, nothing is copied.
    values = target.astype(np.float64)
    fixed = target | zero
    single = size == 1
    for depth in range(len(ptr) - 1):
        deadline.check_now()
        states = order[int(ptr[depth]) : int(ptr[depth + 1])]
        choices = spans(product.choice_ptr, states)
        edges = spans(t.indptr, choices)
        counts = t.indptr[choices + 1] - t.indptr[choices]
        starts = np.cumsum(counts) - counts
        q_values = np.add.reduceat(t.probs[edges] * values[t.targets[edges]], starts)
        q_values = np.where(leaving[choices], q_values / denominator[choices], -1.0)
        state_starts = np.cumsum(per_state[states]) - per_state[states]
        best = np.maximum.reduceat(q_values, state_starts)
        if single[states].all():
            update = ~fixed[states]
            values[states[update]] = np.maximum(best[update], 0.0)
        else:
            alone = single[states] & ~fixed[states]
            values[states[alone]] = np.maximum(best[alone], 0.0)
            _solve_components(matrix, states[~single[states]], product, values, fixed, deadline)
    return values


def _self_loops(product: Product) -> tuple[FloatArray, BoolArray]:
    """Per choice, the probability of staying in its state (a choice's targets are distinct,
    so one transition at most) and whether it may leave (at least 1e-15 of leaving); read a
    block of ``CHUNK`` choices at a time."""
    t = product.transitions
    ptr = product.choice_ptr
    stays = np.zeros(product.num_choices)
    for lo in range(0, product.num_states, CHUNK):
        hi = min(lo + CHUNK, product.num_states)
        first, last = int(ptr[lo]), int(ptr[hi])
        a, b = int(t.indptr[first]), int(t.indptr[last])
        per_choice = np.diff(t.indptr[first : last + 1])
        owners = np.repeat(np.arange(lo, hi, dtype=t.targets.dtype), np.diff(ptr[lo : hi + 1]))
        loops = np.flatnonzero(t.targets[a:b] == np.repeat(owners, per_choice)) + a
        owner = np.searchsorted(t.indptr, loops, side="right") - 1
        stays[owner] = t.probs[loops]
    leaving: BoolArray = stays < 1.0 - 1e-15
    return stays, leaving


def _solve_components(
    matrix: csr_matrix,
    states: IntArray,
    product: Product,
    values: FloatArray,
    fixed: BoolArray,
    deadline: Deadline,
) -> None:
    """Value iteration from below on one layer's larger components (their exits fixed)."""
    ptr = product.choice_ptr
    choices = spans(ptr, states)
    local = np.concatenate([[0], np.cumsum(ptr[states + 1] - ptr[states])])[:-1]
    rows = matrix[choices]
    members = ~fixed[states]
    for _ in range(1_000_000):
        deadline.check_now()
        new = np.maximum(np.maximum.reduceat(rows @ values, local), 0.0)[members]
        change = np.max(np.abs(new - values[states[members]])) if members.any() else 0.0
        values[states[members]] = new
        if change < TOLERANCE:
            break


def acyclic_horizon(
    product: Product,
    matrices: list[csr_matrix],
    ends: FloatArray,
    horizon: int,
    deadline: Deadline,
    layered: Layering | None = None,
) -> FloatArray | None:
    """``pmax_horizon``'s table after ``horizon`` steps, ``table[mask, x]``, when the product
    is acyclic but for the absorbing states' self-loops, has no epsilon jump and ``horizon``
    covers its layers; ``None`` otherwise (the caller then runs the steps). ``matrices``: per
    mask, the choices' rows over all masks' values, and ``ends`` the table with no step left
    (``pmax_horizon``'s); ``layered``: the product's :func:`layering` when the caller has it
    (it is computed otherwise).

    Layer ``d`` (Kahn's, :func:`layers`; the absorbing states in layer 0) has all its
    successors in layers below ``d``. The layer-0 states keep one value from the first step
    on (from no step left on, when ``ends`` already has it), so by induction a state of layer
    ``d`` has the same value after every ``r >= d + 1`` steps (``r >= d``): the fixpoint of the
    Bellman step, ``T(x) = max_c P(c) T`` over the world choices with the satisfied state 1
    and the violated 0. One pass over the layers from the sinks up computes it with the very
    row products a step computes (scipy's ``csr_matvec``, a row's terms summed in order), so
    the table is bit-identical to the steps' (backward induction on an acyclic graph in
    topological order: Bertsekas, Dynamic Programming and Optimal Control, vol. 1, sec. 2.1)."""
    n = product.num_states
    ptr = product.choice_ptr
    if horizon < 1 or (product.action < 0).any() or (np.diff(ptr) == 0).any():
        return None
    if layered is None:
        layered = layering(state_graph(product))
    if layered is None or not layered.absorbing_loops:
        return None
    order, layer_ptr = layered.order, layered.ptr
    if horizon < len(layer_ptr) - 2:
        return None
    table = np.zeros((len(matrices), n))
    flat = table.ravel()
    for depth in range(len(layer_ptr) - 1):
        deadline.check_now()
        states = order[int(layer_ptr[depth]) : int(layer_ptr[depth + 1])]
        choices = spans(ptr, states)
        counts = ptr[states + 1] - ptr[states]
        starts = np.cumsum(counts) - counts
        for mask, matrix in enumerate(matrices):
            table[mask, states] = np.maximum.reduceat(matrix[choices] @ flat, starts)
        if depth == 0:
            table[:, SATISFIED], table[:, VIOLATED] = 1.0, 0.0
            settled = np.array_equal(table[:, states], ends[:, states])
            if horizon < len(layer_ptr) - 1 and not settled:
                return None
    return table
