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

import numpy as np
from scipy.sparse import csr_matrix

from mitlc.check.topo import spans
from mitlc.product.explicit import SATISFIED, VIOLATED, Product
from mitlc.worlds.model import FloatArray, IntArray, World

MAX_CELLS = 200_000_000
"""The largest ``horizon x (observation, state) pairs`` searched; larger problems raise."""


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

    def action(self, t: int, observation: int, automaton_state: int) -> int:
        """The policy's action at step ``t`` (0 for a key the search never met)."""
        key = observation * self.num_q + automaton_state
        index = int(np.searchsorted(self.keys, key))
        if automaton_state < self.num_q and index < len(self.keys) and self.keys[index] == key:
            return int(self.policy[min(t, len(self.policy) - 1), index])
        return 0


@dataclass(frozen=True, slots=True)
class _Model:
    """The product with its acceptance mask: ``moves[a]`` maps state ``z = mask * n + x`` to
    its successors under world action ``a``; ``pair_*`` list each state's observations."""

    moves: tuple[csr_matrix, ...]
    terminal: FloatArray
    absorbing: IntArray
    absorbing_values: FloatArray
    initial: int
    pair_state: IntArray
    pair_prob: FloatArray
    pair_key: IntArray
    keys: IntArray
    num_q: int


def observed_bound(
    world: World, product: Product, *, horizon: int | None = None, max_sweeps: int = 100
) -> ObservedBound:
    """The best observation-based policy found in at most ``max_sweeps`` sweeps and its exact
    success probability within ``horizon`` (default: the world's); see the module docstring.
    Raises :class:`ObservedBoundError` for a world without observations, a product with
    epsilon jumps (a choice the table does not express) or a problem past ``MAX_CELLS``."""
    steps = world.horizon if horizon is None else horizon
    model = _model(world, product)
    if steps * len(model.pair_state) > MAX_CELLS:
        raise ObservedBoundError(
            f"{steps} steps x {len(model.pair_state):,} (observation, state) pairs is past "
            f"the limit of {MAX_CELLS:,}"
        )
    start = np.zeros(model.terminal.shape[0])
    start[model.initial] = 1.0
    # The fully observable optimum's state distribution weighs the first sweep.
    identity = _identity_pairs(model)
    full = _backward(model, identity, [np.ones_like(start)] * steps, None)[1]
    weights = _forward(model, identity, full, start)
    policy: IntArray | None = None
    values: list[float] = []
    for _ in range(max_sweeps):
        value, policy = _backward(model, model, weights, policy)
        if values and value <= values[-1] + 1e-13:
            values.append(max(value, values[-1]))
            break
        values.append(value)
        weights = _forward(model, model, policy, start)
    assert policy is not None
    return ObservedBound(values[-1], tuple(values), model.keys, policy, model.num_q)


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
    moves = []
    for a in range(actions):
        choices = product.choice_ptr[live] + a  # a state's choices are its actions in order
        if (product.action[choices] != a).any():
            raise ObservedBoundError("the product's choices are not in action order")
        moves.append(_move_matrix(product, live, choices, masks))
    full_mask = masks - 1
    terminal = np.zeros(masks * n)
    terminal[full_mask * n + live] = 1.0
    absorbing = np.concatenate([np.arange(masks) * n + SATISFIED, np.arange(masks) * n + VIOLATED])
    absorbing_values = np.concatenate([np.ones(masks), np.zeros(masks)])
    terminal[absorbing] = absorbing_values
    num_q = int(product.automaton_state.max()) + 1
    pair_state, pair_prob, pair_key = _pairs(world, product, live, masks, num_q)
    keys, pair_index = np.unique(pair_key, return_inverse=True)
    return _Model(
        moves=tuple(moves),
        terminal=terminal,
        absorbing=absorbing,
        absorbing_values=absorbing_values,
        initial=int(product.initial),
        pair_state=pair_state,
        pair_prob=pair_prob,
        pair_key=pair_index.astype(np.int64),
        keys=keys.astype(np.int64),
        num_q=num_q,
    )


def _move_matrix(product: Product, live: IntArray, choices: IntArray, masks: int) -> csr_matrix:
    """Rows ``mask * n + x`` for every live ``x``: the successors ``(mask | marks, y)``."""
    n, t = product.num_states, product.transitions
    sizes = t.indptr[choices + 1] - t.indptr[choices]
    entries = spans(t.indptr, choices)
    rows, columns, probs = [], [], []
    for mask in range(masks):
        rows.append(np.repeat(mask * n + live, sizes))
        columns.append((mask | np.repeat(product.marks[choices], sizes)) * n + t.targets[entries])
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


@dataclass(frozen=True, slots=True)
class _Pairs:
    pair_state: IntArray
    pair_prob: FloatArray
    pair_key: IntArray
    keys: IntArray


def _identity_pairs(model: _Model) -> _Pairs:
    """Every live state observed as itself: the fully observable problem."""
    states = np.unique(model.pair_state)
    return _Pairs(states, np.ones(len(states)), np.arange(len(states)), states)


def _forward(
    model: _Model, pairs: _Model | _Pairs, policy: IntArray, start: FloatArray
) -> list[FloatArray]:
    """The distribution over states at each step under ``policy`` (mass that reaches an
    absorbing state stops there)."""
    size, actions = len(start), len(model.moves)
    found, d = [], start.copy()
    for t in range(len(policy)):
        found.append(d)
        chosen = policy[t][pairs.pair_key]
        w = d[pairs.pair_state] * pairs.pair_prob
        split = np.bincount(chosen * size + pairs.pair_state, w, minlength=actions * size)
        d = sum(
            (move.T @ split[a * size : (a + 1) * size] for a, move in enumerate(model.moves)),
            np.zeros(size),
        )
    return found


def _backward(
    model: _Model, pairs: _Model | _Pairs, weights: list[FloatArray], current: IntArray | None
) -> tuple[float, IntArray]:
    """One backward pass: the improved policy, step by step from the last, and its exact value
    from the initial state (``weights[t]``: the distribution at step ``t`` that weighs the
    choice; ``current``: the policy kept on ties)."""
    steps, count = len(weights), len(pairs.keys)
    policy = np.zeros((steps, count), dtype=np.int64)
    values = model.terminal.copy()
    for t in range(steps - 1, -1, -1):
        q = np.stack([move @ values for move in model.moves])  # (actions, states)
        q_pairs = q[:, pairs.pair_state] * pairs.pair_prob  # (actions, pairs)
        mass = weights[t][pairs.pair_state]
        score = _per_key(pairs.pair_key, q_pairs * mass, count)
        plain = _per_key(pairs.pair_key, q_pairs, count)
        weighted = np.bincount(pairs.pair_key, mass, minlength=count) > 0
        choice = np.where(weighted, score.argmax(axis=0), plain.argmax(axis=0))
        if current is not None:
            keep = score[current[t], np.arange(count)] >= score.max(axis=0) - 1e-15
            choice = np.where(weighted & keep, current[t], choice)
        policy[t] = choice
        chosen = choice[pairs.pair_key]
        values = np.bincount(
            pairs.pair_state, q_pairs[chosen, np.arange(len(chosen))], minlength=len(values)
        ).astype(np.float64)
        values[model.absorbing] = model.absorbing_values
    return float(values[model.initial]), policy


def _per_key(keys: IntArray, rows: FloatArray, count: int) -> FloatArray:
    """``out[a, k] = sum(rows[a, i] for i with keys[i] == k)``."""
    return np.stack([np.bincount(keys, row, minlength=count) for row in rows])
