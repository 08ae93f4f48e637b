"""The joint arrays of a team world, built with numpy a block of joint states at a time.

Each robot's motion is its grid table (:func:`mitlc.worlds.grid.transitions`) made dense:
``succ[c, a, k]`` with probability ``prob[c, a, k]``, a row's outcomes padded to the widest row
with probability 0. A block of joint states then gets every (joint action, joint outcome) at
once: robot ``r``'s next cell is ``succ_r[cell_r, action_r, outcome_r]`` and the probability is
the product over the robots; blocking or the swap flag is applied, the next cells are looked up
as a state, and equal targets of a row are summed. The semantics are
:mod:`mitlc.worlds.team`'s docstring.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mitlc.worlds.grid import DIRECTIONS, Layout, local_pattern, noisy_cell, transitions
from mitlc.worlds.model import BoolArray, FloatArray, IntArray, Observations, Sparse
from mitlc.worlds.schema import LocalPattern
from mitlc.worlds.team_model import radix_parts, radix_weights
from mitlc.worlds.team_schema import TeamWorldFile

CHUNK_ENTRIES = 4_000_000
"""Entries (robot, joint state, joint action, outcome) computed at once."""
LOOKUP_CELLS = 50_000_000
"""The largest ``cells ** robots`` looked up through a dense array (else a binary search)."""


@dataclass(frozen=True, slots=True)
class RobotTables:
    """One robot's motion over the free cells, dense (see the module docstring), and its
    observation model (``None``: it sees its cell)."""

    actions: tuple[str, ...]
    succ: IntArray
    prob: FloatArray
    observations: Observations | None

    @property
    def widest(self) -> int:
        """The most outcomes of one move."""
        return int(self.succ.shape[2])

    def outcomes(self) -> IntArray:
        """``outcomes()[c]``: the outcomes of every action from cell ``c``, summed."""
        counts: IntArray = (self.prob > 0).sum(axis=(1, 2)).astype(np.int64)
        return counts


def padded(rows: Sparse, shape: tuple[int, int]) -> tuple[IntArray, FloatArray]:
    """Compressed rows as dense arrays of targets and probabilities of ``shape + (widest,)``,
    each row padded with its first target at probability 0."""
    counts = np.diff(rows.indptr)
    width = int(counts.max())
    column = np.arange(len(rows.targets)) - np.repeat(rows.indptr[:-1], counts)
    row = np.repeat(np.arange(rows.num_rows), counts)
    succ = np.repeat(rows.targets[rows.indptr[:-1]][:, None], width, axis=1)
    prob = np.zeros((rows.num_rows, width))
    succ[row, column] = rows.targets
    prob[row, column] = rows.probs
    return succ.reshape((*shape, width)), prob.reshape((*shape, width))


def robot_tables(world: TeamWorldFile, layout: Layout) -> list[RobotTables]:
    """Each robot's tables (robots with the same actions and motion share them)."""
    out = []
    m = len(layout.cells())
    made: dict[tuple[object, ...], tuple[IntArray, FloatArray]] = {}
    for robot in world.robots.values():
        actions = tuple(robot.actions or world.actions)
        motion = robot.motion or world.motion
        if (actions, motion) not in made:
            made[actions, motion] = padded(transitions(layout, actions, motion), (m, len(actions)))
        succ, prob = made[actions, motion]
        model: Observations | None = None
        if isinstance(robot.observation, LocalPattern):
            model = local_pattern(layout)
        elif robot.observation is not None:
            model = noisy_cell(layout, robot.observation.correct, robot.observation.neighbourhood)
        out.append(RobotTables(actions, succ, prob, model))
    return out


def pairs(n: int) -> list[tuple[int, int]]:
    """Every pair of robots ``i < j``."""
    return [(i, j) for i in range(n) for j in range(i + 1, n)]


def configurations(m: int, n: int, distinct: bool) -> IntArray:
    """Every tuple of ``n`` cell indices below ``m`` (pairwise distinct if ``distinct``), in
    lexicographic order, as rows."""
    configs = np.arange(m, dtype=np.int64)[:, None]
    for _ in range(n - 1):
        grown = np.concatenate(
            [np.repeat(configs, m, axis=0), np.tile(np.arange(m), len(configs))[:, None]], axis=1
        )
        configs = grown[(grown[:, :-1] != grown[:, -1:]).all(axis=1)] if distinct else grown
    return configs


def adjacent(layout: Layout) -> BoolArray:
    """``adjacent(layout)[c, d]``: a feasible move leads from free cell ``c`` to ``d``."""
    cells = layout.cells()
    index = {cell: i for i, cell in enumerate(cells)}
    adj = np.zeros((len(cells), len(cells)), dtype=bool)
    for i, cell in enumerate(cells):
        for direction in DIRECTIONS:
            target = layout.step(cell, direction)
            if target is not None:
                adj[i, index[target]] = True
    return adj


def joint_states(layout: Layout, n: int, block: bool, flag: bool) -> tuple[IntArray, BoolArray]:
    """The joint states' cell indices ``(states, n)`` and swap flags: every cell tuple (of
    distinct cells if ``block``), then, if ``flag``, those where a swap can end (two robots
    in cells joined by a feasible move) again, flagged."""
    configs = configurations(len(layout.cells()), n, distinct=block)
    flagged = configs[:0]
    if flag:
        adj = adjacent(layout)
        near = np.zeros(len(configs), dtype=bool)
        for i, j in pairs(n):
            near |= adj[configs[:, i], configs[:, j]]
        flagged = configs[near]
    positions = np.concatenate([configs, flagged])
    return positions, np.arange(len(positions)) >= len(configs)


def transition_entries(robots: list[RobotTables], positions: IntArray) -> int:
    """The entries of the joint table before equal targets are summed: per state, the product
    over robots of the outcomes of all their actions."""
    total = np.ones(len(positions), dtype=np.int64)
    for r, robot in enumerate(robots):
        total *= robot.outcomes()[positions[:, r]]
    return int(total.sum())


@dataclass(frozen=True, slots=True)
class JointMotion:
    """How the rows of the joint table are made (see the module docstring)."""

    robots: list[RobotTables]
    positions: IntArray
    swapped: BoolArray
    block: bool

    def table(self, entries: int) -> Sparse:
        """The joint transitions, row ``s * joint actions + a``; ``entries``: at least the
        number of entries (:func:`transition_entries`)."""
        n, s = len(self.robots), len(self.positions)
        parts = radix_parts(tuple(len(r.actions) for r in self.robots))
        outcomes = radix_parts(tuple(r.widest for r in self.robots))
        m = len(self.robots[0].succ)
        weights = radix_weights((m,) * n)
        lookup = _Lookup(self.positions, self.swapped, weights, m**n)
        chunk = max(1, CHUNK_ENTRIES // (len(parts) * len(outcomes) * n))
        indptr = np.zeros(s * len(parts) + 1, dtype=np.int64)
        targets = np.empty(entries, dtype=np.int64)
        probs = np.empty(entries, dtype=np.float64)
        filled = 0
        for lo in range(0, s, chunk):
            block = self.positions[lo : lo + chunk]
            counts, t, p = self._rows(block, parts, outcomes, weights, lookup)
            rows = slice(lo * len(parts) + 1, (lo + len(block)) * len(parts) + 1)
            indptr[rows] = filled + np.cumsum(counts)
            targets[filled : filled + len(t)] = t
            probs[filled : filled + len(p)] = p
            filled += len(t)
        if filled < entries:
            targets, probs = targets[:filled].copy(), probs[:filled].copy()
        return Sparse(indptr, targets, probs)

    def _rows(
        self,
        old: IntArray,
        parts: IntArray,
        outcomes: IntArray,
        weights: IntArray,
        lookup: _Lookup,
    ) -> tuple[IntArray, IntArray, FloatArray]:
        """A block of states' rows: entries per row, targets, probabilities."""
        n, b, a, k = len(self.robots), len(old), len(parts), len(outcomes)
        new = np.empty((n, b, a, k), dtype=np.int64)
        prob = np.ones((b, a, k))
        for r, robot in enumerate(self.robots):
            at = (old[:, r, None, None], parts[None, :, r, None], outcomes[None, None, :, r])
            new[r] = robot.succ[at]
            prob *= robot.prob[at]
        was = old.T[:, :, None, None]
        swap = np.zeros((b, a, k), dtype=bool)
        if self.block:
            new = unblocked(new, was)
        elif len(lookup.flagged):
            for i, j in pairs(n):
                swap |= (new[i] == was[j]) & (new[j] == was[i]) & (was[i] != was[j])
        ids = sum((new[r] * weights[r] for r in range(n)), np.zeros((b, a, k), dtype=np.int64))
        target = lookup.states(ids, swap)
        if k == 1:  # one outcome a row: nothing to sum
            return np.ones(b * a, dtype=np.int64), target.ravel(), prob.ravel()
        keep = prob > 0
        rows = np.broadcast_to(np.arange(b * a).reshape(b, a, 1), (b, a, k))
        num_states = len(lookup.positions)
        key = rows[keep] * num_states + target[keep]
        order = np.argsort(key, kind="stable")
        key, weight = key[order], prob[keep][order]
        first = np.flatnonzero(np.concatenate([[True], key[1:] != key[:-1]]))
        sums = np.add.reduceat(weight, first)
        unique = key[first]
        counts = np.bincount(unique // num_states, minlength=b * a).astype(np.int64)
        return counts, (unique % num_states).astype(np.int64), sums.astype(np.float64)


def unblocked(new: IntArray, was: IntArray) -> IntArray:
    """Outcomes ``new[r, ...]`` where every robot in a conflict (the same cell as another's,
    or a swap) stays at ``was[r, ...]``, repeated until none is left (at most one round per
    robot: :mod:`mitlc.worlds.team`)."""
    n = len(new)
    for _ in range(n + 1):
        conflict = np.zeros(new.shape, dtype=bool)
        for i, j in pairs(n):
            clash = (new[i] == new[j]) | ((new[i] == was[j]) & (new[j] == was[i]))
            conflict[i] |= clash
            conflict[j] |= clash
        if not conflict.any():
            return new
        new = np.where(conflict, was, new)
    raise AssertionError("blocking did not settle")  # pragma: no cover: see the docstring


class _Lookup:
    """The joint state of a cell tuple's mixed-radix id (and swap flag)."""

    def __init__(
        self, positions: IntArray, swapped: BoolArray, weights: IntArray, space: int
    ) -> None:
        self.positions = positions
        ids = positions @ weights
        self.plain, self.flagged = ids[~swapped], ids[swapped]
        self.dense: IntArray | None = None
        if space <= LOOKUP_CELLS:
            self.dense = np.full(space, -1, dtype=np.int64)
            self.dense[self.plain] = np.arange(len(self.plain))
            self.dense_flagged = np.full(space, -1, dtype=np.int64)
            self.dense_flagged[self.flagged] = len(self.plain) + np.arange(len(self.flagged))

    def states(self, ids: IntArray, swap: BoolArray) -> IntArray:
        """The states of cell tuples ``ids``, flagged where ``swap``."""
        if self.dense is not None:
            plain = self.dense[ids]
            flagged = self.dense_flagged[ids] if len(self.flagged) else plain
        else:
            plain = np.searchsorted(self.plain, ids)
            flagged = len(self.plain) + np.searchsorted(self.flagged, ids)
        return np.where(swap, flagged, plain) if len(self.flagged) else plain


def observation_entries(robots: list[RobotTables], positions: IntArray) -> tuple[int, int]:
    """The joint observations' number, and the entries of the joint observation table."""
    m = len(robots[0].succ)
    total = np.ones(len(positions), dtype=np.int64)
    for r, robot in enumerate(robots):
        if robot.observations is not None:
            total *= np.diff(robot.observations.model.indptr)[positions[:, r]]
    ids = math.prod(m if r.observations is None else len(r.observations.names) for r in robots)
    return ids, int(total.sum())


def joint_observations(
    robots: list[RobotTables], positions: IntArray, cells: tuple[tuple[int, int], ...]
) -> Observations | None:
    """The joint observation model (see :mod:`mitlc.worlds.team`), or ``None`` when no robot
    has one. Each robot's ids in a row are increasing, so their mixed-radix combinations in
    lexicographic order are too."""
    if all(r.observations is None for r in robots):
        return None
    m = len(cells)
    names, tables = [], []
    for robot in robots:
        model = robot.observations
        if model is None:
            model = Observations(
                tuple(f"r{r}c{c}" for r, c in cells),
                Sparse.from_rows([{c: 1.0} for c in range(m)]),
            )
        names.append(model.names)
        tables.append(padded(model.model, (m, 1)))
    weights = radix_weights(tuple(len(x) for x in names))
    parts = radix_parts(tuple(t[0].shape[2] for t in tables))
    ids = np.zeros((len(positions), len(parts)), dtype=np.int64)
    prob = np.ones((len(positions), len(parts)))
    for r, (succ, p) in enumerate(tables):
        ids += succ[positions[:, r], 0][:, parts[:, r]] * weights[r]
        prob *= p[positions[:, r], 0][:, parts[:, r]]
    keep = prob > 0
    indptr = np.concatenate([[0], np.cumsum(keep.sum(axis=1))]).astype(np.int64)
    joint: list[str] = [""]
    for options in names:
        joint = [f"{prefix}|{x}" if prefix else x for prefix in joint for x in options]
    return Observations(tuple(joint), Sparse(indptr, ids[keep], prob[keep]))
