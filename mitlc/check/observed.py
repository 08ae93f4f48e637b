"""An exact lower bound on a POMDP's optimum: the best observation-based policy found by
policy search, evaluated exactly (``observed_bound(world, product)``).

The event is the episode's success within the horizon, as in
:func:`mitlc.check.solve.pmax_horizon`: the state is ``(mask, x)``, a product state ``x``
with the acceptance sets ``mask`` seen so far; success is ending the horizon (or reaching the
absorbing ``satisfied``) not violated, with every set seen. The agent sees, at step ``t``,
the world's observation ``o`` of its cell (drawn on entering it) and the automaton state
``q``; a policy here is a table ``action[t][(o, q)]`` — no belief, no further memory, no
acceptance mask — so every such policy is one an agent with the whole observation history
could follow, and its exact success probability is a lower bound on the POMDP's optimum
(and on the value of any learner's observations, which include ``o`` and ``q``).

The search is block-coordinate ascent over the time steps, the classic policy improvement for
memoryless policies of finite-horizon POMDPs (e.g. Littman, "Memoryless policies", SAB 1994):
a forward pass gives the distribution ``d_t`` over states at every step under the current
policy; a backward pass, from the last step down, picks for every ``(o, q)`` the action that
maximises ``sum_z d_t(z) P(o | z) Q_t(z, a)``, where ``Q_t`` reads the values of the steps
after ``t`` under the policy already improved there. The earlier steps are untouched while
``t`` changes, so the exact value never decreases from one sweep to the next. The first sweep
weighs the states by the distribution of the fully observable optimal policy.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import EllipsisType

import numpy as np
from scipy.sparse import csr_matrix, vstack

from mitlc.check.topo import spans
from mitlc.limits import DEFAULT_TIME_LIMIT, Deadline
from mitlc.product.explicit import SATISFIED, VIOLATED, Product, recursion_ends
from mitlc.task import rules
from mitlc.worlds.model import BoolArray, FloatArray, IntArray, World

MAX_CELLS = 20_000_000
"""The largest ``horizon x (observation, state) pairs`` searched by default (a few seconds:
a 20x20 noisy grid with an 81-step horizon is 10 million, 2.4 s); larger problems raise."""


class ObservedBoundError(ValueError):
    """The observation-based bound does not apply to this product (or it is too large)."""


@dataclass(frozen=True, slots=True)
class ObservedBound:
    """The exact success probability of the policy found, the value after each sweep
    (non-decreasing) and the policy: ``policy[t, k]`` is the action at step ``t`` for the
    observation key ``keys[k] = o * num_q + q``."""

    value: float
    sweeps: tuple[float, ...]
    keys: IntArray
    policy: IntArray
    num_q: int
    reached: BoolArray
    """``reached[t, k]``: the policy meets key ``k`` at step ``t`` with positive probability."""

    def rows(self) -> list[tuple[int, int, int, int]]:
        """``(step, observation, automaton state, action)`` for every key the policy meets
        at that step, by step and key."""
        steps, index = np.nonzero(self.reached)
        keys = self.keys[index]
        return list(
            zip(
                steps.tolist(),
                (keys // self.num_q).tolist(),
                (keys % self.num_q).tolist(),
                self.policy[steps, index].tolist(),
                strict=True,
            )
        )

    def action(self, t: int, observation: int, automaton_state: int) -> int:
        """The policy's action at step ``t`` (0 for a key the search never met)."""
        key = observation * self.num_q + automaton_state
        index = int(np.searchsorted(self.keys, key))
        if automaton_state < self.num_q and index < len(self.keys) and self.keys[index] == key:
            return int(self.policy[min(t, len(self.policy) - 1), index])
        return 0


@dataclass(frozen=True, slots=True)
class _Observing:
    """Who sees what: every (state, observation) pair with positive probability, its state,
    probability and key index; ``key_matrix[k, z]`` sums the pairs of state ``z`` and key
    ``k`` (their probabilities)."""

    pair_state: IntArray
    pair_prob: FloatArray
    pair_key: IntArray
    keys: IntArray
    key_matrix: csr_matrix

    @staticmethod
    def of(
        pair_state: IntArray, pair_prob: FloatArray, pair_key: IntArray, size: int
    ) -> _Observing:
        """The pairs given by state, probability and key value (``size``: the states)."""
        keys, index = np.unique(pair_key, return_inverse=True)
        index = index.astype(np.int64)
        matrix = csr_matrix((pair_prob, (index, pair_state)), shape=(len(keys), size))
        return _Observing(pair_state, pair_prob, index, keys.astype(np.int64), matrix)


@dataclass(frozen=True, slots=True)
class _Model:
    """The product with its acceptance mask: row ``a * size + z`` of ``moves`` lists the
    successors of state ``z = mask * n + x`` under world action ``a`` (``moves_t``: its
    transpose); ``observing``: the world's observations and the automaton state."""

    moves: csr_matrix
    moves_t: csr_matrix
    actions: int
    terminal: FloatArray
    absorbing: IntArray
    absorbing_values: FloatArray
    initial: int
    observing: _Observing
    num_q: int
    start: FloatArray
    """The start distribution over the states (mask 0: the product's start states)."""

    @property
    def size(self) -> int:
        """States ``(mask, x)``, the unreachable masks included."""
        return len(self.terminal)


def observed_bound(
    world: World,
    product: Product,
    *,
    horizon: int | None = None,
    max_sweeps: int = 30,
    tolerance: float = 1e-9,
    max_cells: int = MAX_CELLS,
    time_limit: float | None = DEFAULT_TIME_LIMIT,
    memory_limit: float | EllipsisType | None = ...,
    deadline: Deadline | None = None,
) -> ObservedBound:
    """The best observation-based policy found and its exact success probability within
    ``horizon`` (default: the world's); see the module docstring. The sweeps stop when one
    gains at most ``tolerance``, or after ``max_sweeps``. Raises :class:`ObservedBoundError` for
    a world without observations, a product with epsilon jumps (a choice the table does not
    express) or more than ``max_cells`` steps x (observation, state) pairs. Stops with
    :class:`mitlc.limits.LimitError` after ``time_limit`` seconds
    or past ``memory_limit`` GB held (``None``: no limit), or at
    ``deadline`` when one is given (read at every step of every pass)."""
    clock = Deadline.of(deadline, time_limit, "the observation-based bound", memory_limit)
    steps = world.horizon if horizon is None else horizon
    model = _model(world, product)
    observing = model.observing
    if steps * len(observing.pair_state) > max_cells:
        raise ObservedBoundError(
            f"{steps} steps x {len(observing.pair_state):,} (observation, state) pairs is past "
            f"the limit of {max_cells:,} (observed_bound's max_cells lifts it)"
        )
    start = model.start
    # The fully observable optimum's state distribution weighs the first sweep.
    states = np.unique(observing.pair_state)
    identity = _Observing.of(states, np.ones(len(states)), states, model.size)
    full = _backward(model, identity, [np.ones_like(start)] * steps, None, clock)[1]
    weights = _forward(model, identity, full, start, clock)
    policy: IntArray | None = None
    values: list[float] = []
    for _ in range(max_sweeps):
        value, policy = _backward(model, observing, weights, policy, clock)
        # the next sweep's weights, or the last policy's `reached`
        weights = _forward(model, observing, policy, start, clock)
        if values and value <= values[-1] + tolerance:
            values.append(max(value, values[-1]))
            break
        values.append(value)
    assert policy is not None
    met = [observing.key_matrix @ d > 0 for d in weights]
    return ObservedBound(
        values[-1], tuple(values), observing.keys, policy, model.num_q, np.array(met, dtype=bool)
    )


def _model(world: World, product: Product) -> _Model:
    if world.observations is None:
        raise ObservedBoundError(f"world {world.name!r} has no observation model")
    if (product.action < 0).any():
        raise ObservedBoundError("the product has epsilon jumps")
    n, actions, masks = product.num_states, world.num_actions, 1 << product.num_sets
    live = np.flatnonzero(product.world_state >= 0)
    per_state = np.diff(product.choice_ptr)
    if (per_state[live] != actions).any():
        raise ObservedBoundError("some product state lacks a world action")
    blocks = []
    for a in range(actions):
        choices = product.choice_ptr[live] + a  # a state's choices are its actions in order
        if (product.action[choices] != a).any():
            raise ObservedBoundError("the product's choices are not in action order")
        blocks.append(_move_matrix(product, live, choices, masks))
    moves = vstack(blocks, format="csr")
    terminal = recursion_ends(product).ravel()
    absorbing = np.concatenate([np.arange(masks) * n + SATISFIED, np.arange(masks) * n + VIOLATED])
    absorbing_values = np.concatenate([np.ones(masks), np.zeros(masks)])
    terminal[absorbing] = absorbing_values
    num_q = int(product.automaton_state.max()) + 1
    pair_state, pair_prob, pair_key = _pairs(world, product, live, masks, num_q)
    start = np.zeros(masks * n)
    for x, p in product.starts:  # a drawn start (mitlc.worlds.uncertain) weighs its states
        start[x] += p
    return _Model(
        moves=moves,
        moves_t=moves.T.tocsr(),
        actions=actions,
        terminal=terminal,
        absorbing=absorbing,
        absorbing_values=absorbing_values,
        initial=int(product.initial),
        observing=_Observing.of(pair_state, pair_prob, pair_key, masks * n),
        num_q=num_q,
        start=start,
    )


def _move_matrix(product: Product, live: IntArray, choices: IntArray, masks: int) -> csr_matrix:
    """Rows ``mask * n + x`` for every live ``x``: the successors ``(mask | marks, y)``."""
    n, t = product.num_states, product.transitions
    sizes = t.indptr[choices + 1] - t.indptr[choices]
    entries = spans(t.indptr, choices)
    rows, columns, probs = [], [], []
    for mask in range(masks):
        rows.append(np.repeat(mask * n + live, sizes))
        after = rules.saturate(mask, np.repeat(product.marks[choices], sizes), masks - 1)
        columns.append(after * n + t.targets[entries])
        probs.append(t.probs[entries])
    return csr_matrix(
        (np.concatenate(probs), (np.concatenate(rows), np.concatenate(columns))),
        shape=(masks * n, masks * n),
    )


def _pairs(
    world: World, product: Product, live: IntArray, masks: int, num_q: int
) -> tuple[IntArray, FloatArray, IntArray]:
    """Every (state, observation) pair with positive probability: the state ``mask * n + x``,
    the probability of the observation in ``x``'s cell and the key ``o * num_q + q``."""
    assert world.observations is not None
    obs, n = world.observations.model, product.num_states
    cells = product.world_state[live]
    sizes = obs.indptr[cells + 1] - obs.indptr[cells]
    entries = spans(obs.indptr, cells)
    x = np.repeat(live, sizes)
    key = obs.targets[entries] * num_q + product.automaton_state[x]
    return (
        np.concatenate([mask * n + x for mask in range(masks)]),
        np.tile(obs.probs[entries], masks),
        np.tile(key, masks),
    )


def _forward(
    model: _Model, observing: _Observing, policy: IntArray, start: FloatArray, deadline: Deadline
) -> list[FloatArray]:
    """The distribution over states at each step under ``policy`` (mass that reaches an
    absorbing state stops there)."""
    size, pairs = model.size, observing
    found, d = [], start.copy()
    for t in range(len(policy)):
        deadline.check_now()
        found.append(d)
        chosen = policy[t][pairs.pair_key]
        w = d[pairs.pair_state] * pairs.pair_prob
        split = np.bincount(chosen * size + pairs.pair_state, w, minlength=model.actions * size)
        d = np.asarray(model.moves_t @ split)
    return found


def _backward(
    model: _Model,
    observing: _Observing,
    weights: list[FloatArray],
    current: IntArray | None,
    deadline: Deadline,
) -> tuple[float, IntArray]:
    """One backward pass: the improved policy, step by step from the last, and its exact value
    from the initial state (``weights[t]``: the distribution at step ``t`` that weighs the
    choice; ``current``: the policy kept on ties)."""
    steps, count, pairs = len(weights), len(observing.keys), observing
    policy = np.zeros((steps, count), dtype=np.int64)
    values = model.terminal.copy()
    keys = np.arange(count)
    for t in range(steps - 1, -1, -1):
        deadline.check_now()
        q = np.asarray(model.moves @ values).reshape(model.actions, model.size)
        mass = weights[t]
        score = np.asarray(pairs.key_matrix @ (q * mass).T)  # (keys, actions)
        weighted = np.asarray(pairs.key_matrix @ mass) > 0
        choice = score.argmax(axis=1)
        if not weighted.all():  # keys this policy never meets: the unweighted best
            choice = np.where(weighted, choice, np.asarray(pairs.key_matrix @ q.T).argmax(axis=1))
        if current is not None:
            keep = score[keys, current[t]] >= score[keys, choice] - 1e-15
            choice = np.where(weighted & keep, current[t], choice)
        policy[t] = choice
        gained = q[choice[pairs.pair_key], pairs.pair_state] * pairs.pair_prob
        values = np.bincount(pairs.pair_state, gained, minlength=model.size).astype(np.float64)
        values[model.absorbing] = model.absorbing_values
    return float(values @ model.start), policy
