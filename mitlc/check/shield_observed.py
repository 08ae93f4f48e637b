"""Timed shields over what a POMDP's agent observes: ``observed_shield(world, product, ...)``.

An agent in a POMDP sees the observation ``o`` of its cell (drawn on entering it), the
automaton state ``q``, the frontier ``mask`` and the steps left ``r`` (what mitlc's learners
see), not the cell. A shield for it is a table over ``(r, mask, o, q)`` of the world actions
allowed: whatever the cell behind ``o``, the agent gets the same answer. It is computed, as
the MDP's (:mod:`mitlc.check.shield`), by one backward pass that keeps the *worst* a shielded
agent can do; each action is judged over every product state the observation allows (the
pairs ``x = (s, q)`` with ``P(o | s) > 0``), as the observation-based analysis of
:mod:`mitlc.check.observed` judges a policy over ``(o, q)``:

* ``theta``: the action's worst success within ``r`` steps over those states, the shield
  followed from then on, is at least ``theta`` times the best such worst case of any action
  (``theta = 1``: only the actions whose worst case is best);
* ``delta``: its largest violation probability over those states is at most ``delta`` more
  than the least such largest of any action.

Both tests compare the actions with one another, so some action always passes; with both, a
key where none passes both keeps the ``delta``-allowed ones (safety first). The guarantee is
the pass's own, exact: **every policy that follows the shield, whatever it remembers, succeeds
with probability at least** :attr:`ObservedShield.success` **and violates with probability at
most** :attr:`ObservedShield.violation` (from the start, over its observations). Unlike the
MDP's, ``theta`` is relative to what can be guaranteed from an observation, not to the
optimum of an agent that sees the cell (``optimum``, an upper bound); a task with epsilon
jumps is not shielded here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

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
        return {**summary(self), "observed": True}


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
    seen = _Seen.of(world, product)
    masks, num_a = 1 << product.num_sets, world.num_actions
    clock.reserve(horizon * masks * len(seen.keys) * num_a, "the shield's table")
    table = np.zeros((horizon, masks, len(seen.keys), num_a), dtype=np.bool_)
    matrices = mask_matrices(product)
    worst = recursion_ends(product)
    risk = np.zeros_like(worst)
    risk[:, VIOLATED] = 1.0
    for r in range(1, horizon + 1):
        clock.check_now()
        q_worst = np.stack([m @ worst.ravel() for m in matrices])
        q_risk = np.stack([m @ risk.ravel() for m in matrices])
        for mask in range(masks):
            table[r - 1, mask], worst[mask], risk[mask] = _step(
                seen, q_worst[mask], q_risk[mask], theta, delta, num_a, product.num_states
            )
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
        success=start_average(product, worst[0]),
        violation=start_average(product, risk[0]),
        least_violation=start_average(product, least),
    )


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
    q_worst: FloatArray,
    q_risk: FloatArray,
    theta: float | None,
    delta: float | None,
    num_a: int,
    num_states: int,
) -> tuple[BoolArray, FloatArray, FloatArray]:
    """One step of one mask: the allowed actions per key, and per product state the worst
    success and the largest violation of the shielded agent, averaged over its
    observations (the absorbing states' fixed)."""
    choice = seen.first_choice[:, None] + np.arange(num_a)[None, :]
    w, z = q_worst[choice], q_risk[choice]  # per pair and action
    robust_w = np.minimum.reduceat(w, seen.ptr, axis=0)  # per key and action
    robust_z = np.maximum.reduceat(z, seen.ptr, axis=0)
    ok = np.ones(robust_w.shape, dtype=np.bool_)
    if theta is not None:
        ok &= robust_w >= theta * robust_w.max(axis=1, keepdims=True) - TOLERANCE
    if delta is not None:
        safe = robust_z <= robust_z.min(axis=1, keepdims=True) + delta + TOLERANCE
        ok = np.where((ok & safe).any(axis=1, keepdims=True), ok & safe, safe)
    allowed = ok[seen.key]
    worst, risk = np.zeros(num_states), np.zeros(num_states)
    np.add.at(worst, seen.state, seen.prob * np.where(allowed, w, np.inf).min(axis=1))
    np.add.at(risk, seen.state, seen.prob * np.where(allowed, z, -np.inf).max(axis=1))
    worst[SATISFIED], worst[VIOLATED] = 1.0, 0.0
    risk[SATISFIED], risk[VIOLATED] = 0.0, 1.0
    return ok, np.clip(worst, 0.0, 1.0), np.clip(risk, 0.0, 1.0)
