"""Exact maximal probabilities on a product MDP, and the policies that achieve them.

* ``pmax``: the maximal probability of satisfying the formula, i.e. of reaching an accepting
  maximal end component (:mod:`mitlc.check.mec`). States that cannot reach one are 0; values
  computed component by component in topological order (:mod:`mitlc.check.topo`), then
  checked by value iteration, give a first policy, choosing among the optimal choices one
  that moves closer to the target (so no optimal choice loops forever away from it); policy
  iteration then solves each policy's Markov chain (sparse LU, or iteration to 1e-15 for
  large chains) until no choice improves.
* ``pmax_horizon``: the maximal probability of the episode's success within ``H`` steps (never
  violated, and satisfied or a round of all acceptance sets completed), by backward induction
  over the product and the set of acceptance sets seen so far. Epsilon jumps take no step.

Every loop whose length depends on the input (value iteration, policy iteration, the steps of
the horizon, the layers of the topological solve) reads a :class:`mitlc.limits.Deadline`, so a
solve stops with :class:`mitlc.limits.LimitError` at its time limit; only a single sparse LU
solve (:func:`_solve_chain`'s fallback) runs to its end once started.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import EllipsisType

import numpy as np
from scipy.sparse import csr_matrix, identity
from scipy.sparse.csgraph import connected_components
from scipy.sparse.linalg import spsolve

from mitlc.check.mec import accepting_states
from mitlc.check.topo import (
    Layering,
    acyclic_horizon,
    backward_reachable,
    choice_sources,
    gather,
    into_choices,
    layering,
    spans,
    state_graph,
    topological_values,
)
from mitlc.limits import DEFAULT_TIME_LIMIT, Deadline
from mitlc.product.explicit import (
    SATISFIED,
    VIOLATED,
    Product,
    recursion_ends,
    start_average,
)
from mitlc.task import rules
from mitlc.worlds.model import BoolArray, FloatArray, IntArray

TOLERANCE = 1e-12


@dataclass(frozen=True, slots=True)
class Solution:
    """Values per product state and an optimal memoryless policy (a choice per state)."""

    values: FloatArray
    policy: IntArray
    layers: Layering | None = None
    """The product's layers when it is acyclic but for self-loops (``pmax``'s, which
    ``pmax_horizon`` reads again instead of computing them a second time)."""


def _choice_matrix(product: Product) -> csr_matrix:
    t = product.transitions
    return csr_matrix(
        (t.probs, t.targets, t.indptr), shape=(product.num_choices, product.num_states)
    )


def _best(product: Product, q_values: FloatArray) -> tuple[FloatArray, IntArray]:
    """Per state, the largest choice value and the first choice that attains it."""
    ptr = product.choice_ptr
    values = np.maximum.reduceat(q_values, ptr[:-1])
    sources = choice_sources(product)
    candidates = np.flatnonzero(q_values >= values[sources] - TOLERANCE)
    first = np.full(product.num_states, product.num_choices, dtype=np.int64)
    np.minimum.at(first, sources[candidates], candidates)
    return values, first


def _backward_search(
    product: Product, allowed: BoolArray, target: BoolArray
) -> tuple[BoolArray, IntArray]:
    """Breadth-first search backwards from ``target`` along the ``allowed`` choices, a whole
    frontier at a time (:func:`mitlc.check.topo.into_choices` lists the choices that may
    reach each state). Returns the states found (``target`` included)
    and, for each found state outside ``target``, a choice that may reach a state found one
    step earlier (the other states keep their first choice)."""
    ptr = product.choice_ptr
    sources = choice_sources(product)
    policy = ptr[:-1].astype(np.int64)
    done = target.copy()
    frontier = np.flatnonzero(target)
    slot = np.zeros(product.num_states, dtype=np.int64)
    into_ptr, reaching = into_choices(product)
    while len(frontier):
        choices = gather(into_ptr, reaching, frontier)
        choices = choices[allowed[choices]]
        states = sources[choices]
        new = ~done[states]
        choices, states = choices[new], states[new]
        index = np.arange(len(states))
        slot[states] = index
        first = slot[states] == index  # one choice per state
        frontier = states[first]
        policy[frontier] = choices[first]
        done[frontier] = True
    return done, policy


def _evaluate(
    product: Product,
    matrix: csr_matrix,
    policy: IntArray,
    target: BoolArray,
    zero: BoolArray,
    deadline: Deadline,
) -> FloatArray:
    """The exact reachability probabilities of ``target`` under ``policy``."""
    free = ~target & ~zero
    chain = matrix[policy]
    values = target.astype(np.float64)
    index = np.flatnonzero(free)
    if len(index):
        sub = chain[index][:, index].tocsr()
        rhs = np.asarray(chain[index][:, np.flatnonzero(target)].sum(axis=1)).ravel()
        values[index] = _solve_chain(sub, rhs, deadline)
    return values


DIRECT_LIMIT = 20_000
"""Above this many unknowns, a policy's chain is first solved by iteration (products of
time-bounded tasks are nearly acyclic, so it converges in about as many sweeps as the horizon);
sparse LU is the fallback when it does not converge."""


def _solve_chain(sub: csr_matrix, rhs: FloatArray, deadline: Deadline) -> FloatArray:
    """The solution ``v`` of ``v = sub v + rhs`` (the chain's reachability probabilities)."""
    if len(rhs) > DIRECT_LIMIT:
        v = rhs.copy()
        for _ in range(20_000):
            deadline.check_now()
            new = sub @ v + rhs
            if np.max(np.abs(new - v)) < 1e-15:
                return np.asarray(new)
            v = new
    identity_minus = identity(len(rhs), format="csc") - sub.tocsc()
    return np.asarray(spsolve(identity_minus, rhs))


def max_reach(
    product: Product,
    target: BoolArray,
    graph: csr_matrix | None = None,
    *,
    time_limit: float | None = DEFAULT_TIME_LIMIT,
    memory_limit: float | EllipsisType | None = ...,
    deadline: Deadline | None = None,
) -> Solution:
    """The maximal probability of reaching ``target`` from every state, and a policy for it
    (``graph``: :func:`mitlc.check.topo.state_graph`'s, when the caller has it). Stops with
    :class:`mitlc.limits.LimitError` after ``time_limit`` seconds
    or past ``memory_limit`` GB held (``None``: no limit), or at
    ``deadline`` when one is given."""
    clock = Deadline.of(deadline, time_limit, "pmax", memory_limit)
    return _max_reach(product, target, [state_graph(product) if graph is None else graph], clock)


def _max_reach(
    product: Product,
    target: BoolArray,
    graphs: list[csr_matrix],
    clock: Deadline,
    components: IntArray | None = None,
    layered: Layering | None = None,
) -> Solution:
    """:func:`max_reach`, taking the state graph out of ``graphs`` (so that it is freed once
    the topological values are computed, when the caller holds no other reference);
    ``components``: its strongly connected components, and ``layered`` its layering, when the
    caller has them."""
    matrix = _choice_matrix(product)
    graph = graphs.pop()
    zero = ~backward_reachable(graph, target)
    values = topological_values(
        product,
        matrix,
        target,
        zero,
        graph,
        deadline=clock,
        components=components,
        layered=layered,
    )
    del graph, components
    sweeps = 0
    for sweeps in range(1, 100_001):  # noqa: B007 - the count says whether the seed was exact
        clock.check_now()
        q_values = matrix @ values
        new = np.maximum.reduceat(q_values, product.choice_ptr[:-1])
        new = np.where(target, 1.0, np.where(zero, 0.0, new))
        if np.max(np.abs(new - values)) < TOLERANCE:
            values = new
            break
        values = new
    # Among the optimal choices, one per state that makes progress towards the target, so that
    # no optimal choice loops forever away from it.
    sources = choice_sources(product)
    allowed = q_values >= values[sources] - 1e-9
    del sources, q_values
    _, policy = _backward_search(product, allowed, target)
    if sweeps == 1:
        # The topological values are already the Bellman fixpoint reached from below, and the
        # policy climbs to the target along optimal choices: nothing for policy iteration to do.
        return Solution(np.clip(values, 0.0, 1.0), policy, layered)
    for _ in range(100):
        clock.check_now()
        values = _evaluate(product, matrix, policy, target, zero, clock)
        q_values = matrix @ values
        best, choice = _best(product, q_values)
        improve = (best > values + 1e-9) & ~target & ~zero
        if not improve.any():
            break
        policy = np.where(improve, choice, policy)
    return Solution(np.clip(values, 0.0, 1.0), policy, layered)


def pmax(
    product: Product,
    *,
    time_limit: float | None = DEFAULT_TIME_LIMIT,
    memory_limit: float | EllipsisType | None = ...,
    deadline: Deadline | None = None,
) -> Solution:
    """The maximal probability of satisfying the formula (accepting MECs, then reachability).
    Stops with :class:`mitlc.limits.LimitError` after ``time_limit`` seconds
    or past ``memory_limit`` GB held (``None``: no
    limit), or at ``deadline`` when one is given."""
    clock = Deadline.of(deadline, time_limit, "pmax", memory_limit)
    graphs = [state_graph(product)]
    # Layers first (products of time-bounded tasks are mostly acyclic but for self-loops:
    # then every strongly connected component is one state); otherwise the components once,
    # for the end components and the layers both.
    layered = layering(graphs[0])
    if layered is not None:
        components = np.arange(product.num_states)
    else:
        _, components = connected_components(graphs[0], directed=True, connection="strong")
    accepting = accepting_states(product, graphs[0], deadline=clock, components=components)
    return _max_reach(product, accepting, graphs, clock, components, layered)


FULL_STEP = 0.25
"""``pmax_horizon`` recomputes every state, in one sparse product per mask, when more than this
share of the states must be recomputed."""


def pmax_horizon(
    product: Product,
    horizon: int,
    *,
    keep_history: bool = True,
    time_limit: float | None = DEFAULT_TIME_LIMIT,
    memory_limit: float | EllipsisType | None = ...,
    deadline: Deadline | None = None,
    layered: Layering | None = None,
) -> tuple[float, list[FloatArray]]:
    """The maximal probability of success within ``horizon`` steps from the initial state
    (:func:`mitlc.task.rules.success` of the state the episode stops in; epsilon jumps take no
    step, and none is taken once the horizon is reached, where the episode is over), and
    the values (``values[r][mask, x]``: ``r`` steps remaining, the sets in ``mask`` seen), all
    ``horizon + 1`` of them (what a time-dependent policy needs), or with ``keep_history`` off
    only the last (the memory of one table instead of ``horizon + 1``).

    Each step recomputes only the states with a choice into a state whose values changed in
    the step before (in a product of a time-bounded task most values settle once the clock
    has run out, so a step touches a few percent of the states); the others keep their values,
    which is exactly what a full step would give them. The matrix of a mask reads the values
    of the mask ``mask | marks[c]`` that choice ``c`` moves to from the whole table at once.

    With ``keep_history`` off, an acyclic product without jumps whose layers the horizon
    covers gets that last table in one pass over its layers instead
    (:func:`mitlc.check.topo.acyclic_horizon`: the same row products, bit-identical);
    ``layered``: those layers when the caller has them (``pmax``'s :attr:`Solution.layers`).

    Once a step changes nothing the table is a fixpoint and the steps left are not computed
    (with ``keep_history`` they are one read-only copy of it), so a horizon far past the
    product's depth costs no more than the depth. Otherwise a step costs at least the states it
    recomputes and a horizon of a billion steps is stopped by the time limit:
    :class:`mitlc.limits.LimitError` after ``time_limit`` seconds
    or past ``memory_limit`` GB held (``None``: no limit), or at
    ``deadline`` when one is given."""
    clock = Deadline.of(deadline, time_limit, "pmax_horizon", memory_limit)
    matrices = mask_matrices(product)
    raw = _ends(product)
    if not keep_history:  # an acyclic product's fixpoint, layer by layer, when the steps reach it
        last = acyclic_horizon(product, matrices, raw, horizon, clock, layered)
        if last is not None:
            return start_average(product, last[0]), [last]
    n = product.num_states
    t = product.transitions
    ptr = product.choice_ptr
    sources = choice_sources(product)
    jumps = np.flatnonzero(product.action < 0)
    preds_ptr, preds = _predecessors(product, sources)
    jump_sources = sources[jumps]
    jump_targets = t.targets[t.indptr[jumps]]
    fixed = np.unique(np.concatenate([jump_sources, [SATISFIED, VIOLATED]]))
    table = raw.copy()  # no step left: the episode is over, so no jump is taken either
    history = [table.copy()]
    seen = np.zeros(n, dtype=np.bool_)
    dirty = np.arange(n)
    for step in range(horizon):
        clock.check_now()
        flat = table.ravel()
        if len(dirty) > FULL_STEP * n:
            dirty = np.arange(n)
            for mask, matrix in enumerate(matrices):
                q_values = matrix @ flat
                q_values[jumps] = -1.0
                raw[mask] = np.maximum.reduceat(q_values, ptr[:-1])
        else:
            choices = spans(ptr, dirty)
            starts = np.concatenate([[0], np.cumsum(ptr[dirty + 1] - ptr[dirty])])[:-1]
            world = product.action[choices] >= 0
            for mask, matrix in enumerate(matrices):
                q_values = np.where(world, matrix[choices] @ flat, -1.0)
                raw[mask, dirty] = np.maximum.reduceat(q_values, starts)
        columns = _distinct(np.concatenate([dirty, fixed]), seen)
        before = table[:, columns]
        table[:, columns] = raw[:, columns]
        _settle(table, jump_sources, jump_targets)
        changed = columns[(table[:, columns] != before).any(axis=0)]
        dirty = _distinct(gather(preds_ptr, preds, changed), seen)
        if keep_history:
            history.append(table.copy())
        if not len(changed):  # a fixpoint: every later step gives this table again
            if keep_history:  # one read-only table for all of them, not a copy each
                final = table.copy()
                final.setflags(write=False)
                history.extend([final] * (horizon - step - 1))
            break
    if not keep_history:
        history = [table]
    return start_average(product, table[0]), history


def mask_matrices(product: Product) -> list[csr_matrix]:
    """Per mask of sets seen, the world choices' rows (jumps zeroed) over the table of all
    masks' values: choice ``c`` reads the mask ``mask | marks[c]``. With one mask (no sets) the
    rows share the product's targets, and its probabilities too when there are no jumps."""
    masks = 1 << product.num_sets
    n = product.num_states
    t = product.transitions
    sizes = np.diff(t.indptr)
    if (product.action < 0).any():
        probs = np.where(np.repeat(product.action >= 0, sizes), t.probs, 0.0)
    else:
        probs = t.probs
    shape = (product.num_choices, masks * n)
    if masks == 1:
        return [csr_matrix((probs, t.targets, t.indptr), shape=shape)]
    all_sets = masks - 1
    return [
        csr_matrix(
            (
                probs,
                t.targets
                + np.repeat(
                    rules.saturate(mask, product.marks.astype(np.int64), all_sets) * n, sizes
                ),
                t.indptr,
            ),
            shape=shape,
        )
        for mask in range(masks)
    ]


def _ends(product: Product) -> FloatArray:
    """The values when the horizon ends (:func:`mitlc.task.rules.recursion_ends`)."""
    return recursion_ends(product)


def _predecessors(product: Product, sources: IntArray) -> tuple[IntArray, IntArray]:
    """``(ptr, before)``: the states with a choice that may reach ``y`` are
    ``before[ptr[y]:ptr[y+1]]``, each once. A state's entries in
    :func:`mitlc.check.topo.into_choices` come in increasing choice order, so a predecessor's
    repeats are adjacent and dropped in one pass (a repeat left would only cost time)."""
    into_ptr, into = into_choices(product)
    into = sources[into]
    keep = np.ones(len(into), dtype=np.bool_)
    np.not_equal(into[1:], into[:-1], out=keep[1:])
    keep[into_ptr[:-1][np.diff(into_ptr) > 0]] = True
    kept = np.zeros(len(into) + 1, dtype=np.int64)
    np.cumsum(keep, out=kept[1:])
    before: IntArray = into[keep]
    return kept[into_ptr], before


def _distinct(keys: IntArray, seen: BoolArray) -> IntArray:
    """``keys`` without repeats, in increasing order (``seen``: scratch, a flag per key, all
    off before and after): a byte written per key and one pass over the flags, no sort. The
    order of the states a step recomputes changes none of their values (each is its own
    choices' rows)."""
    seen[keys] = True
    distinct: IntArray = np.flatnonzero(seen)
    seen[distinct] = False
    return distinct


def _settle(values: FloatArray, jump_sources: IntArray, jump_targets: IntArray) -> None:
    """Absorbing outcomes, then epsilon jumps (which take no step) from their sources, in
    place."""
    values[:, SATISFIED] = 1.0
    values[:, VIOLATED] = 0.0
    for source, target in zip(jump_sources.tolist(), jump_targets.tolist(), strict=True):
        values[:, source] = np.maximum(values[:, source], values[:, target])


def jumps_in_order(product: Product) -> list[tuple[int, int, int]]:
    """The product's epsilon jumps as ``(source, target, choice)``, in the order
    :func:`pmax_horizon` settles them (:func:`_settle`): the passes that follow its values
    (the shield's, the least cost's) take them in that order too."""
    t = product.transitions
    jumps = np.flatnonzero(product.action < 0)
    sources = choice_sources(product)[jumps].tolist()
    return list(zip(sources, t.targets[t.indptr[jumps]].tolist(), jumps.tolist(), strict=True))
