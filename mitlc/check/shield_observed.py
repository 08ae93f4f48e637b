"""Timed shields over what a POMDP's agent observes: ``observed_shield(world, product, ...)``.

An agent in a POMDP sees the observation ``o`` of its cell (drawn on entering it), the
automaton state ``q``, the frontier ``mask`` and the steps left ``r`` (what mitlc's learners
see), not the cell. A shield for it is a table over ``(r, mask, o, q)`` of the world actions
allowed: whatever the cell behind ``o``, the agent gets the same answer.

The reference is the observation-based analysis (:mod:`mitlc.check.observed`): the best
policy ``pi`` over ``(t, o, q)`` that its search finds, whose exact success is ``mitlc
check``'s lower bound of the POMDP's optimum. Its values ``L[r][mask, x]`` (success) and
``Lz`` (violation) from every product state are computed in the same backward pass as the
shield's own worst cases ``W`` and ``Z`` (the least success and the largest violation of
any agent that follows the shield, whatever it remembers). An action is allowed at ``(r,
mask, o, q)`` when, in *every* product state ``x = (s, q)`` the observation allows (``P(o |
s) > 0``):

* ``theta``: its success over ``W`` is at least ``theta * L[r][mask, x]``;
* ``delta``: its violation over ``Z`` is at most ``Lz[r][mask, x] + delta``.

``pi``'s own action always passes (its successors' worst cases are at least ``theta`` times
theirs, by induction), so **every policy that follows the shield succeeds with probability at
least ``theta`` times the observation-based bound, and violates with probability at most
``delta`` more than ``pi`` does**, from the start (``theta = 1``, ``delta = 0``: every
shielded agent does at least as well as ``pi``, wherever it is). With both, a key where no
action passes both keeps the ``delta``-allowed ones. :attr:`ObservedShield.success` and
:attr:`ObservedShield.violation` are the pass's exact worst cases. A task with epsilon jumps is
not shielded here (the analysis does not take them).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mitlc.check.observed import ObservedBound, ObservedBoundError, observed_bound
from mitlc.check.shield import (
    TOLERANCE,
    ShieldError,
    check_settings,
    least_violation,
    summary,
)
from mitlc.check.solve import mask_matrices, pmax_horizon
from mitlc.limits import Deadline
from mitlc.product.explicit import SATISFIED, VIOLATED, Product, recursion_ends, start_average
from mitlc.worlds.model import BoolArray, FloatArray, IntArray, World


@dataclass(frozen=True, slots=True)
class ObservedShield:
    """The world actions allowed per ``(r, mask, o, q)`` (see the module docstring)."""

    horizon: int
    theta: float | None
    delta: float | None
    keys: IntArray
    """The keys ``o * num_q + q`` met, sorted."""
    num_q: int
    table: BoolArray
    """``table[r - 1, mask, k, a]``: action ``a`` is allowed at key ``keys[k]``."""
    optimum: float
    """``pmax_horizon`` of an agent that sees the cell (an upper bound)."""
    reference: float
    """The exact success of the observation-based policy (the lower bound)."""
    success: float
    """The least success probability within the horizon of any shielded policy."""
    violation: float
    """The largest violation probability within the horizon of any shielded policy."""
    least_violation: float
    """The least violation probability of an agent that sees the cell (a lower bound)."""

    def actions(
        self, remaining: IntArray, mask: IntArray, observation: IntArray, q: IntArray
    ) -> BoolArray:
        """``allowed[i, a]`` for the episodes' steps left, frontiers, observations and
        automaton states (every action where no step is left or the key was never met)."""
        key = observation * self.num_q + q
        at = np.minimum(np.searchsorted(self.keys, key), len(self.keys) - 1)
        met = (self.keys[at] == key) & (q < self.num_q)
        inside = met & (remaining >= 1) & (remaining <= self.horizon)
        r = np.where(inside, remaining, 1) - 1
        rows = self.table[r, mask, at]
        allowed: BoolArray = np.where(inside[:, None], rows, True)
        return allowed

    def summary(self) -> dict[str, float | int | None]:
        """The settings and the guarantees, for reports (:func:`mitlc.check.shield.summary`)."""
        return {**summary(self), "observed": True, "observation_based": self.reference}


def observed_shield(
    world: World,
    product: Product,
    horizon: int,
    *,
    theta: float | None = None,
    delta: float | None = None,
    deadline: Deadline | None = None,
) -> ObservedShield:
    """The shield of the POMDP ``world``'s ``product`` over its observations (see the module
    docstring); :class:`ShieldError` for a world without observations or a task with jumps."""
    check_settings(theta, delta)
    if world.observations is None:
        raise ShieldError(f"{world.name}: not a POMDP (use mitlc.check.shield.shield)")
    if (product.action < 0).any():
        raise ShieldError("a POMDP shield for a task with epsilon jumps is not built")
    clock = Deadline.none() if deadline is None else deadline
    try:
        found = observed_bound(world, product, horizon=horizon, deadline=clock)
    except ObservedBoundError as err:
        raise ShieldError(f"the observation-based analysis it reads: {err}") from None
    seen = _Seen.of(world, product)
    masks, num_a = 1 << product.num_sets, world.num_actions
    clock.reserve(horizon * masks * len(seen.keys) * num_a, "the shield's table")
    table = np.zeros((horizon, masks, len(seen.keys), num_a), dtype=np.bool_)
    matrices = mask_matrices(product)
    # worst success, largest violation (the shield's); success and violation of pi
    tables = [recursion_ends(product), np.zeros((masks, product.num_states))]
    tables[1][:, VIOLATED] = 1.0
    tables += [tables[0].copy(), tables[1].copy()]
    for r in range(1, horizon + 1):
        clock.check_now()
        steps = [np.stack([m @ v.ravel() for m in matrices]) for v in tables]
        chosen = _policy_actions(found, seen, horizon - r)
        for mask in range(masks):
            table[r - 1, mask], *values = _step(
                seen, [q[mask] for q in steps], chosen, theta, delta, num_a, product.num_states
            )
            for v, new in zip(tables, values, strict=True):
                v[mask] = new
    optimum, _ = pmax_horizon(product, horizon, keep_history=False, deadline=clock)
    least = least_violation(product, horizon)
    return ObservedShield(
        horizon=horizon,
        theta=theta,
        delta=delta,
        keys=seen.keys,
        num_q=seen.num_q,
        table=table,
        optimum=optimum,
        reference=start_average(product, tables[2][0]),
        success=start_average(product, tables[0][0]),
        violation=start_average(product, tables[1][0]),
        least_violation=start_average(product, least),
    )


def _policy_actions(found: ObservedBound, seen: _Seen, t: int) -> IntArray:
    """The observation-based policy's action at step ``t`` for each of ``seen``'s keys (0
    where its search never met the key, as :meth:`ObservedBound.action` says)."""
    at = np.minimum(np.searchsorted(found.keys, seen.keys), len(found.keys) - 1)
    met = found.keys[at] == seen.keys
    step = min(t, len(found.policy) - 1)
    actions: IntArray = np.where(met, found.policy[step, at], 0)
    return actions


@dataclass(frozen=True, slots=True)
class _Seen:
    """Every (product state, observation) pair with positive probability, sorted by key
    ``o * num_q + q``: its state, probability, key index, and where each key's pairs begin."""

    state: IntArray
    prob: FloatArray
    key: IntArray
    ptr: IntArray
    keys: IntArray
    num_q: int
    first_choice: IntArray
    """Per pair, its state's first choice (world action ``a`` is ``first + a``)."""

    @staticmethod
    def of(world: World, product: Product) -> _Seen:
        assert world.observations is not None
        model = world.observations.model
        live = np.flatnonzero(product.world_state >= 0)
        s = product.world_state[live]
        counts = model.indptr[s + 1] - model.indptr[s]
        state = np.repeat(live, counts)
        index = np.repeat(model.indptr[s] - np.cumsum(counts) + counts, counts)
        index = index + np.arange(int(counts.sum()))
        num_q = int(product.automaton_state.max()) + 1
        raw = model.targets[index].astype(np.int64) * num_q + product.automaton_state[state]
        order = np.argsort(raw, kind="stable")
        keys, first = np.unique(raw[order], return_index=True)
        key = np.repeat(np.arange(len(keys)), np.diff(np.append(first, len(order))))
        state = state[order]
        return _Seen(
            state=state,
            prob=model.probs[index][order],
            key=key,
            ptr=first,
            keys=keys,
            num_q=num_q,
            first_choice=product.choice_ptr[state].astype(np.int64),
        )


def _step(
    seen: _Seen,
    q_values: list[FloatArray],
    chosen: IntArray,
    theta: float | None,
    delta: float | None,
    num_a: int,
    num_states: int,
) -> tuple[BoolArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """One step of one mask. ``q_values``: per choice, the next step's worst success, largest
    violation, and the policy's success and violation; ``chosen``: the policy's action per
    key. The allowed actions per key, and per product state the four values (averaged over its
    observations; the absorbing states' fixed)."""
    choice = seen.first_choice[:, None] + np.arange(num_a)[None, :]
    w, z, ref_w, ref_z = (q[choice] for q in q_values)  # per pair and action
    pick = chosen[seen.key][:, None]
    anchor_w = np.take_along_axis(ref_w, pick, axis=1)  # pi's values from each pair's state
    anchor_z = np.take_along_axis(ref_z, pick, axis=1)
    passes_w = w >= theta * anchor_w - TOLERANCE if theta is not None else np.ones_like(w, bool)
    passes_z = z <= anchor_z + delta + TOLERANCE if delta is not None else np.ones_like(z, bool)
    ok_w = np.logical_and.reduceat(passes_w, seen.ptr, axis=0)  # in every state of the key
    ok_z = np.logical_and.reduceat(passes_z, seen.ptr, axis=0)
    ok = np.where((ok_w & ok_z).any(axis=1, keepdims=True), ok_w & ok_z, ok_z)
    allowed = ok[seen.key]
    out = []
    for values, empty, pick_min in ((w, np.inf, True), (z, -np.inf, False)):
        masked = np.where(allowed, values, empty)
        out.append(masked.min(axis=1) if pick_min else masked.max(axis=1))
    out += [anchor_w[:, 0], anchor_z[:, 0]]
    per_state = []
    for k, each in enumerate(out):
        total = np.zeros(num_states)
        np.add.at(total, seen.state, seen.prob * each)
        success = k % 2 == 0
        total[SATISFIED], total[VIOLATED] = (1.0, 0.0) if success else (0.0, 1.0)
        per_state.append(np.clip(total, 0.0, 1.0))
    return ok, per_state[0], per_state[1], per_state[2], per_state[3]
