"""Timed shields from the exact product: ``shield(product, horizon, theta=..., delta=...)``.

A shield says, for every product state ``x`` (world state and automaton state), frontier
``mask`` of acceptance sets seen and number ``r`` of steps left before the horizon, which
choices (world actions and epsilon jumps) an agent may take. It is computed from
:func:`mitlc.check.solve.pmax_horizon`'s per-step values ``V[r][mask, x]`` (the best success
probability within ``r`` steps) by one backward pass over the steps, the pre-emptive shield of
Alshiekh et al. ("Safe reinforcement learning via shielding", AAAI 2018) made probabilistic as
in Jansen et al. ("Safe reinforcement learning using probabilistic shields", CONCUR 2020), over
the product of the world with the task's automaton, whose states carry the task's deadlines.

**The rule.** A local rule (allow ``a`` when its optimal value is at least ``theta V``) does not
bound what a shielded agent achieves: losing a factor ``theta`` at each of ``r`` steps compounds
to ``theta^r``. The pass therefore keeps, beside ``V``, the *worst* a shielded agent can do,
and tests each choice against it:

* ``W[r][mask, x]``: the least success probability within ``r`` steps of any policy that
  follows the shield from ``(x, mask)`` (history-dependent and randomised ones included);
* ``U[r][x]``: the least probability of a violation (entering the task's *violated* state)
  within ``r`` steps of any policy, and ``Z[r][mask, x]`` the largest of any shielded one (an
  episode cut at the horizon while pending fails, but is no violation: ``delta`` bounds the
  verdict, the safety part of a task such as ``!hole U[0,100] goal``; ``theta`` the success).

A world choice ``c`` of ``x`` is allowed at ``(r, mask)`` when

* with ``theta``: ``sum_y P(c, y) W[r-1][mask', y] >= theta * V[r][mask, x]`` (``mask'`` the
  frontier after ``c``'s acceptance marks);
* with ``delta``: ``sum_y P(c, y) Z[r-1][mask', y] <= U[r][x] + delta``;

and an epsilon jump to ``t`` (which takes no step) when ``W[r][mask, t] >= theta * V[r][mask,
x]`` and ``Z[r][mask, t] <= U[r][x] + delta``. Then ``W[r]`` is the least and ``Z[r]`` the
largest of the allowed choices' values. By induction on ``r`` an optimal choice always passes
(its worst case is at least ``theta`` times its optimum because its successors' are), so
**every policy that follows the shield succeeds with probability at least ``theta`` times the
optimum** from every state at every step, and **violates with probability at most ``delta``
more than the least possible**. ``theta = 1`` allows only optimal choices and ``delta = 0``
only choices of least violation; a violation that the world makes unavoidable (a slippery
floor) stays possible, so ``delta`` is an excess over the least violation, not an absolute
bound. With both, a state where no choice passes both tests (the two ask for different
choices) keeps the ``delta``-allowed ones: safety first; :attr:`Shield.success` is then the
guarantee actually kept. Values are compared within :data:`TOLERANCE`.

Episodes take their steps as :class:`mitlc.learn.envs.vec.VecProduct` does: ``r`` is the
horizon less the world actions taken, the frontier is the episode's (the mask of all sets once
a round completed: :func:`mitlc.task.rules.saturate`); with no step left nothing is asked.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt
from scipy.sparse import csr_matrix

from mitlc.check.solve import jumps_in_order, mask_matrices, pmax_horizon
from mitlc.limits import Deadline
from mitlc.product.explicit import SATISFIED, VIOLATED, Product, recursion_ends, start_average
from mitlc.worlds.model import BoolArray, FloatArray, IntArray

if TYPE_CHECKING:
    from mitlc.check.shield_observed import ObservedShield

TOLERANCE = 1e-12
"""Values are compared within this much (the passes sum the same terms in the same order as
``pmax_horizon``, so an optimal choice passes ``theta = 1`` exactly but for rounding)."""

Bits = npt.NDArray[np.uint8]
Restrict = Callable[[BoolArray, FloatArray], BoolArray]
"""Cuts the passing choices ``ok[mask, c]`` (given their worst cases) to a subset."""


class ShieldError(ValueError):
    """A shield's settings are out of range."""


@dataclass(frozen=True, slots=True)
class Shield:
    """The choices allowed at each step (see the module docstring), and what they guarantee.

    ``bits[r - 1, mask]`` packs (``numpy.packbits``, big-endian within a byte) whether each
    product choice is allowed with ``r`` steps left and the frontier ``mask``."""

    horizon: int
    theta: float | None
    delta: float | None
    bits: Bits
    num_choices: int
    optimum: float
    """``pmax_horizon`` from the start."""
    success: float
    """The least success probability within the horizon of any shielded policy, from the
    start (at least ``theta * optimum``)."""
    violation: float
    """The largest probability of a violation within the horizon of any shielded policy."""
    least_violation: float
    """The least probability of a violation within the horizon of any policy."""

    def allowed(self, remaining: IntArray, mask: IntArray, choice: IntArray) -> BoolArray:
        """Whether ``choice[i]`` is allowed with ``remaining[i]`` steps left and the frontier
        ``mask[i]`` (arrays of one shape; a choice ``< 0`` is not; with no step left, or more
        steps than the horizon, every choice is)."""
        remaining, mask, choice = np.broadcast_arrays(remaining, mask, choice)
        inside = (remaining >= 1) & (remaining <= self.horizon)
        valid = choice >= 0
        c = np.where(valid, choice, 0)
        r = np.where(inside, remaining, 1) - 1
        byte = self.bits[r, mask, c >> 3]
        bit = (byte >> (7 - (c & 7))) & 1
        allowed: BoolArray = valid & (~inside | (bit == 1))
        return allowed

    def summary(self) -> dict[str, float | int | None]:
        """The settings and the guarantees, for reports."""
        return summary(self)


def summary(made: Shield | ObservedShield) -> dict[str, float | int | None]:
    """A shield's settings and guarantees, for reports (``summary.json``)."""
    return {
        "theta": made.theta,
        "delta": made.delta,
        "horizon": made.horizon,
        "optimum": made.optimum,
        "guaranteed_success": made.success,
        "guaranteed_violation": made.violation,
        "least_violation": made.least_violation,
    }


def check_settings(theta: float | None, delta: float | None) -> None:
    """Refuse a ``theta`` outside ``(0, 1]`` or a ``delta`` outside ``[0, 1]``
    (:class:`ShieldError`), or neither given."""
    if theta is None and delta is None:
        raise ShieldError("a shield needs theta (success) or delta (violation), or both")
    if theta is not None and not 0.0 < theta <= 1.0:
        raise ShieldError(f"theta must be in (0, 1], not {theta}")
    if delta is not None and not 0.0 <= delta <= 1.0:
        raise ShieldError(f"delta must be in [0, 1], not {delta}")


def shield(
    product: Product,
    horizon: int,
    *,
    theta: float | None = None,
    delta: float | None = None,
    values: list[FloatArray] | None = None,
    deadline: Deadline | None = None,
) -> Shield:
    """The shield of ``product`` over ``horizon`` steps for ``theta`` and/or ``delta`` (see
    the module docstring). ``values``: ``pmax_horizon(product, horizon)``'s history when the
    caller has it (it is computed otherwise). Reads ``deadline`` at every step and reserves
    the shield's bits (one per choice, mask and step) before making them."""
    check_settings(theta, delta)
    return make_shield(product, horizon, theta=theta, delta=delta, values=values,
                       deadline=deadline)  # fmt: skip


def make_shield(
    product: Product,
    horizon: int,
    *,
    theta: float | None,
    delta: float | None,
    values: list[FloatArray] | None = None,
    deadline: Deadline | None = None,
    restrict: Restrict | None = None,
) -> Shield:
    """:func:`shield`, the passing choices cut by ``restrict`` (``ok[mask, c]`` and their
    worst cases to a subset, e.g. the per-robot rectangles of
    :mod:`mitlc.check.team_shield`) at each step before the worst cases are taken."""
    clock = Deadline.none() if deadline is None else deadline
    if values is None:
        _, values = pmax_horizon(product, horizon, deadline=clock)
    masks, choices = 1 << product.num_sets, product.num_choices
    clock.reserve(horizon * masks * (choices // 8 + 1), "the shield's bits")
    bits = np.zeros((horizon, masks, (choices + 7) // 8), dtype=np.uint8)
    passes = _Passes(product, theta, delta, restrict)
    for r in range(1, horizon + 1):
        clock.check_now()
        bits[r - 1] = np.packbits(passes.step(values[r]), axis=1)
    return Shield(
        horizon=horizon,
        theta=theta,
        delta=delta,
        bits=bits,
        num_choices=choices,
        optimum=start_average(product, values[horizon][0]),
        success=start_average(product, passes.worst[0]),
        violation=start_average(product, passes.risk[0]),
        least_violation=start_average(product, passes.least),
    )


class _Passes:
    """The backward pass: ``worst`` (``W``), ``risk`` (``Z``) and ``least`` (``U``) after the
    steps done so far, one step at a time."""

    def __init__(
        self,
        product: Product,
        theta: float | None,
        delta: float | None,
        restrict: Restrict | None = None,
    ) -> None:
        self.product, self.theta, self.delta, self.restrict = product, theta, delta, restrict
        self.matrices = mask_matrices(product)
        self.moves = _Moves.of(product)
        self.is_jump, self.owner, self.jumps = (
            self.moves.is_jump,
            self.moves.owner,
            self.moves.jumps,
        )
        # No step left: success as the episode ends (pmax_horizon's first table); a violation
        # only in the violated state.
        self.worst: FloatArray = recursion_ends(product)
        self.risk = np.zeros_like(self.worst)
        self.risk[:, VIOLATED] = 1.0
        self.least = self.moves.no_step_left()

    def step(self, best: FloatArray) -> BoolArray:
        """One more step left, ``best`` being ``V`` there: the allowed choices
        ``ok[mask, c]``; ``worst``, ``risk`` and ``least`` move on a step."""
        p, ptr, owner, is_jump = (
            self.product,
            self.product.choice_ptr[:-1],
            self.owner,
            self.is_jump,
        )
        q_worst = np.stack([m @ self.worst.ravel() for m in self.matrices])
        q_risk = np.stack([m @ self.risk.ravel() for m in self.matrices])
        least = self.moves.least_step(self.least)
        ok = self._tests(q_worst, q_risk, best[:, owner], least[owner]) & ~is_jump
        if self.restrict is not None:
            ok = self.restrict(ok, q_worst)
        worst = _reduce(np.minimum, np.where(ok, q_worst, np.inf), ptr)
        risk = _reduce(np.maximum, np.where(ok, q_risk, -np.inf), ptr)
        for source, target, c in self.jumps:
            passed = self._tests(worst[:, target], risk[:, target], best[:, source], least[source])
            ok[:, c] = passed
            worst[:, source] = np.where(
                passed, np.minimum(worst[:, source], worst[:, target]), worst[:, source]
            )
            risk[:, source] = np.where(
                passed, np.maximum(risk[:, source], risk[:, target]), risk[:, source]
            )
            q_worst[:, c], q_risk[:, c] = worst[:, target], risk[:, target]
        empty = ~np.logical_or.reduceat(ok, ptr, axis=1)
        if empty.any():
            stuck = empty[:, owner]
            ok = np.where(stuck, self._fallback(q_worst, q_risk, least[owner]), ok)
            if self.restrict is not None:
                ok = self.restrict(ok, q_worst)
            worst = _reduce(np.minimum, np.where(ok, q_worst, np.inf), ptr)
            risk = _reduce(np.maximum, np.where(ok, q_risk, -np.inf), ptr)
        for table in (worst, risk):
            np.clip(table, 0.0, 1.0, out=table)
        worst[:, SATISFIED], worst[:, VIOLATED] = 1.0, 0.0
        risk[:, SATISFIED], risk[:, VIOLATED] = 0.0, 1.0
        for x in (SATISFIED, VIOLATED):  # the absorbing loops: nothing to shield
            ok[:, p.choice_ptr[x] : p.choice_ptr[x + 1]] = True
        self.worst, self.risk, self.least = worst, risk, least
        return ok

    def _tests(
        self, worst: FloatArray, risk: FloatArray, best: FloatArray, least: FloatArray
    ) -> BoolArray:
        """Which choices of values ``worst`` and ``risk`` pass ``theta`` against ``best`` and
        ``delta`` against ``least``."""
        passed = np.ones(np.shape(worst), dtype=np.bool_)
        if self.theta is not None:
            passed &= worst >= self.theta * best - TOLERANCE
        if self.delta is not None:
            passed &= risk <= least + self.delta + TOLERANCE
        return passed

    def _fallback(self, worst: FloatArray, risk: FloatArray, least: FloatArray) -> BoolArray:
        """The choices kept where none passed (``[mask, c]``, read only at those states): with
        ``delta`` the ``delta``-allowed ones (safety first), or those of least risk when
        rounding left none; with ``theta`` alone those of the best worst case."""
        ptr, owner = self.product.choice_ptr[:-1], self.owner
        if self.delta is None:
            top = _reduce(np.maximum, worst, ptr)
            kept: BoolArray = worst >= top[:, owner] - TOLERANCE
            return kept
        kept = risk <= least + self.delta + TOLERANCE
        none = ~np.logical_or.reduceat(kept, ptr, axis=1)
        low = _reduce(np.minimum, risk, ptr)
        kept |= none[:, owner] & (risk <= low[:, owner] + TOLERANCE)
        return kept


def least_violation(product: Product, horizon: int) -> FloatArray:
    """``U[horizon][x]``: the least probability, over all policies, of a violation (entering
    the violated state) within ``horizon`` steps from each product state."""
    moves = _Moves.of(product)
    least = moves.no_step_left()
    for _ in range(horizon):
        least = moves.least_step(least)
    return least


@dataclass(frozen=True, slots=True)
class _Moves:
    """The product's world choices as one matrix (jumps' rows zeroed), which choices are jumps,
    each choice's state, and the jumps as ``(source, target, choice)`` in ``pmax_horizon``'s
    order: what the least violation ``U`` steps over."""

    product: Product
    plain: csr_matrix
    is_jump: BoolArray
    owner: IntArray
    jumps: list[tuple[int, int, int]]

    @staticmethod
    def of(product: Product) -> _Moves:
        n, t = product.num_states, product.transitions
        is_jump = product.action < 0
        probs = np.where(np.repeat(~is_jump, np.diff(t.indptr)), t.probs, 0.0)
        plain = csr_matrix((probs, t.targets, t.indptr), shape=(product.num_choices, n))
        owner = np.repeat(np.arange(n), np.diff(product.choice_ptr))
        return _Moves(product, plain, is_jump, owner, jumps_in_order(product))

    def no_step_left(self) -> FloatArray:
        """``U[0]``: a violation only in the violated state."""
        least = np.zeros(self.product.num_states)
        least[VIOLATED] = 1.0
        return least

    def least_step(self, least: FloatArray) -> FloatArray:
        """One step of ``U``: the least over each state's world choices of the violation
        reached from their successors' ``least``, then the epsilon jumps (no step) in
        ``pmax_horizon``'s order (``_settle``)."""
        reached = np.where(self.is_jump, np.inf, self.plain @ least)
        after: FloatArray = np.minimum.reduceat(reached, self.product.choice_ptr[:-1])
        after[VIOLATED], after[SATISFIED] = 1.0, 0.0
        for source, target, _ in self.jumps:
            after[source] = min(after[source], after[target])
        return after


def _reduce(ufunc: np.ufunc, values: FloatArray, ptr: IntArray) -> FloatArray:
    """``ufunc.reduceat`` over each state's choices, along the last axis."""
    reduced: FloatArray = ufunc.reduceat(values, ptr, axis=-1)
    return reduced
