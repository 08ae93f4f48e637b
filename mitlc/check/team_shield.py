"""Per-robot (decentralised) timed shields of a team's joint product:
``team_shield(product, horizon, radices, theta=..., delta=...)``.

A team world's actions are joint actions, one action per robot (mixed radix over ``radices``,
robot 0 the most significant digit: :mod:`mitlc.worlds.team_model`). The centralised shield of
the joint product (:func:`mitlc.check.shield.shield`) allows a *set of joint actions* at each
product state, frontier and step; robots that choose their actions independently cannot keep
to such a set unless it is a *rectangle*: a product ``B_0 x B_1 x ... x B_{n-1}`` of per-robot
sets. This module computes a shield whose allowed world choices are rectangles, so that it is
given to the robots as per-robot masks (robot ``i`` may take any action of ``B_i``) and **every
combination** of their choices keeps the guarantee.

**The construction.** The backward pass is :mod:`mitlc.check.shield`'s (the pre-emptive
shield of Alshiekh et al. 2018, probabilistic as in Jansen et al. 2020, over the worst case of
the shielded continuation), with one more step at each stage: of the joint choices that pass
the ``theta``/``delta`` tests, a rectangle is kept (:func:`rectangles`). It is grown greedily
around the passing joint action of best worst case (the *anchor*): robot 0's set becomes every
action that passes with the other robots at the anchor; robot 1's every action that passes
with every action of robot 0's set and the others at the anchor; and so on, the robots taken
again until no set grows. Every joint action of the rectangle passes, so the worst case ``W``
(the least over the rectangle) is at least ``theta`` times the optimum, and the induction of
the centralised shield goes through unchanged: **every policy of the robots that keeps to
their masks, each choosing on its own, succeeds with at least ``theta`` times the optimum**
(and violates with at most ``delta`` more than the least possible). The rectangle may be
smaller than the centralised set (a single joint action at worst, the anchor), never empty
where the centralised one is not; the summary reports both guarantees.

The masks read the joint product state (every robot's cell and the task's state): the robots
act independently but see the team's state, as a decentralised team with a shared view. Epsilon
jumps (a choice of the task, not of a robot) are shielded as in the centralised shield.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from mitlc.check.shield import Shield, check_settings, make_shield
from mitlc.limits import Deadline
from mitlc.product.explicit import Product
from mitlc.worlds.model import BoolArray, FloatArray, IntArray

CHUNK = 1 << 16
"""Product states whose rectangles are made at once (bounds the dense joint tables)."""


def rectangles(ok: BoolArray, score: FloatArray, radices: tuple[int, ...]) -> BoolArray:
    """Per row of ``ok`` (rows x joint actions, a joint action a mixed-radix number over
    ``radices``), a rectangle of joint actions inside the row's allowed ones, grown greedily
    around the allowed joint action of largest ``score`` (module docstring); rows with none
    allowed stay empty."""
    rows, width = ok.shape
    n = len(radices)
    table = ok.reshape((rows, *radices))
    anchor = np.argmax(np.where(ok, score, -np.inf), axis=1)
    digits = np.stack(np.unravel_index(anchor, radices), axis=1)  # (rows, n)
    sets = [np.arange(k)[None, :] == digits[:, [i]] for i, k in enumerate(radices)]
    grown = True
    while grown:
        grown = False
        for i in range(n):
            inside = table
            for j in range(n):  # joint actions outside the other robots' sets: no constraint
                if j != i:
                    shape = [rows] + [1] * n
                    shape[1 + j] = radices[j]
                    inside = inside | ~sets[j].reshape(shape)
            axes = tuple(1 + j for j in range(n) if j != i)
            passes = inside.all(axis=axes) if axes else inside
            passes = passes.reshape(rows, radices[i]) & sets[i].any(axis=1, keepdims=True)
            if (passes & ~sets[i]).any():
                grown = True
                sets[i] = sets[i] | passes
    product_ = sets[0]
    for i in range(1, n):
        product_ = (product_[:, :, None] & sets[i][:, None, :]).reshape(rows, -1)
    chosen: BoolArray = product_.reshape(rows, width) & ok
    return chosen


def rectangle_hook(
    product: Product, radices: tuple[int, ...]
) -> Callable[[BoolArray, FloatArray], BoolArray]:
    """What the backward pass calls on the passing choices ``ok[mask, c]`` with their worst
    cases: the same, the world choices of each state cut to a rectangle."""
    width = int(np.prod(radices))
    owner = np.repeat(np.arange(product.num_states), np.diff(product.choice_ptr))
    action = np.asarray(product.action, dtype=np.int64)
    world = np.flatnonzero(action >= 0)
    states = np.unique(owner[world])
    row_of = np.full(product.num_states, -1, dtype=np.int64)
    row_of[states] = np.arange(len(states))
    rows, cols = row_of[owner[world]], action[world]
    if cols.size and int(cols.max()) >= width:
        raise ValueError(f"a world action {int(cols.max())} is past the {width} joint actions")

    def cut(ok: BoolArray, worst: FloatArray) -> BoolArray:
        out = ok.copy()
        for mask in range(ok.shape[0]):
            for lo in range(0, len(states), CHUNK):
                hi = min(lo + CHUNK, len(states))
                here = (rows >= lo) & (rows < hi)
                r, c, choice = rows[here] - lo, cols[here], world[here]
                dense = np.zeros((hi - lo, width), dtype=np.bool_)
                score = np.full((hi - lo, width), -np.inf)
                dense[r, c] = ok[mask, choice]
                score[r, c] = worst[mask, choice]
                kept = rectangles(dense, score, radices)
                out[mask, choice] = kept[r, c]
        return out

    return cut


def team_shield(
    product: Product,
    horizon: int,
    radices: tuple[int, ...],
    *,
    theta: float | None = None,
    delta: float | None = None,
    values: list[FloatArray] | None = None,
    deadline: Deadline | None = None,
) -> Shield:
    """The per-robot shield of a team's joint ``product`` (module docstring): as
    :func:`mitlc.check.shield.shield`, its allowed world choices rectangles over the robots'
    action counts ``radices``."""
    check_settings(theta, delta)
    return make_shield(
        product, horizon, theta=theta, delta=delta, values=values, deadline=deadline,
        restrict=rectangle_hook(product, radices),
    )  # fmt: skip


def robot_masks(
    shield: Shield, choices: IntArray, radices: tuple[int, ...], remaining: int, mask: int
) -> list[BoolArray]:
    """Robot ``i``'s mask (over its own actions) at a product state whose world choices are
    ``choices`` (indexed by joint action), with ``remaining`` steps left and the frontier
    ``mask``: the sides of the state's rectangle."""
    allowed = shield.allowed(
        np.full(len(choices), remaining), np.full(len(choices), mask), choices
    ).reshape(radices)
    n = len(radices)
    return [np.asarray(allowed.any(axis=tuple(j for j in range(n) if j != i))) for i in range(n)]


__all__ = ["CHUNK", "rectangle_hook", "rectangles", "robot_masks", "team_shield"]
