"""The breadth-first builder behind :func:`mitlc.product.explicit.build_product`.

The product is written straight into compact arrays, level by level of the breadth-first
search: the states a level discovers get consecutive ids, and every choice of a state is made
while its level is expanded, so each level's choices are sorted (by state, then action, jumps
last) and its transitions merged (duplicate targets summed, targets increasing within a choice)
on their own, and appended to the product's arrays. Those arrays grow in place
(:class:`Column`: ``realloc``, which the C library does by remapping pages for large blocks,
so a growing array is never held twice), with 32-bit indices wherever they fit: the product's
memory is about 12 bytes a transition (a 32-bit target and a 64-bit probability, kept exact),
and the build's own is one level's worth beside it. Pairs ``(s, q)`` are coded ``q * S + s``
and numbered through an index array over the codes seen (its bound ``S * Q``, 4 bytes a pair:
the bound of the product's states, a fraction of the product's own bytes).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from mitlc.limits import Deadline
from mitlc.task import TaskMonitor, rules
from mitlc.worlds.model import FloatArray, IntArray, World

VIOLATED, SATISFIED = 0, 1
"""The ids of the two absorbing product states (as in :mod:`mitlc.product.explicit`)."""

INDEX_LIMIT = 2**31 - 1
"""Indices up to this fit the 32-bit arrays; past it a column switches to 64 bits."""

BYTES_PER_TRANSITION = 12
"""A transition's bytes in the product (32-bit target, 64-bit probability)."""

BYTES_PER_CHOICE = 12
"""A choice's bytes in the product (32-bit pointer, action and marks)."""

BYTES_PER_STATE = 13
"""A state's bytes in the product (32-bit pointer, world and automaton state, end flag)."""


class Column:
    """A one-dimensional array that grows in place by doubling (``ndarray.resize``), so that
    appending costs amortised constant time and a large array is never copied whole."""

    def __init__(self, dtype: npt.DTypeLike, deadline: Deadline | None = None) -> None:
        self.data = np.empty(1024, dtype=dtype)
        self.size = 0
        self.deadline = deadline

    def append(self, values: npt.ArrayLike) -> None:
        """Append ``values`` (cast to the column's type; a 32-bit column whose values pass
        :data:`INDEX_LIMIT` becomes a 64-bit one first)."""
        array = np.asarray(values)
        end = self.size + len(array)
        if self.data.dtype == np.int32 and len(array) and int(np.abs(array).max()) > INDEX_LIMIT:
            self.data = self.data.astype(np.int64)
        if end > len(self.data):
            capacity = max(end, 2 * len(self.data))
            if self.deadline is not None:
                more = (capacity - len(self.data)) * self.data.itemsize
                self.deadline.reserve(more, "the product's arrays")
            self.data.resize(capacity, refcheck=False)
        self.data[self.size : end] = array
        self.size = end

    def finish(self) -> npt.NDArray[Any]:
        """The array of the values appended (the column's buffer, trimmed in place)."""
        self.data.resize(self.size, refcheck=False)
        return self.data


class Builder:
    """Breadth-first exploration, one frontier (all states of a level) at a time in numpy.

    A pair ``(s, q)`` is coded ``q * S + s``, so the table of ids grows with the automaton
    states the monitor makes; the automaton's steps, verdicts and jumps are the monitor's."""

    def __init__(
        self,
        world: World,
        monitor: TaskMonitor,
        letters: IntArray,
        deadline: Deadline,
        limit: int | None,
    ) -> None:
        self.world, self.monitor, self.deadline, self.limit = world, monitor, deadline, limit
        self.letters = letters
        self.num_s = world.num_states
        self.ids = np.full(0, -1, dtype=np.int32)
        self.codes = Column(np.int64)
        self.codes.append([-1, -1])
        self.count = 2
        # The product's arrays: per state, per choice, per transition.
        marks = np.int32 if monitor.num_sets < 31 else np.int64
        self.choice_ptr, self.action = Column(np.int32, deadline), Column(np.int32, deadline)
        self.marks, self.indptr = Column(marks, deadline), Column(np.int32, deadline)
        self.targets, self.probs = Column(np.int32, deadline), Column(np.float64, deadline)
        self.choice_ptr.append([0, 1, 2])
        self.action.append([0, 0])
        self.marks.append([0, monitor.all_sets])
        self.indptr.append([0, 1, 2])
        self.targets.append([VIOLATED, SATISFIED])
        self.probs.append([1.0, 1.0])

    def too_large(self, grown: int) -> bool:
        """Whether ``grown`` states pass the limit."""
        return self.limit is not None and grown > self.limit

    def intern(self, codes: IntArray) -> tuple[IntArray, IntArray]:
        """Product ids of ``q * S + s`` codes (new ones numbered in order of first
        appearance), and the new states' ids."""
        kind = self.monitor.verdicts(codes // self.num_s)
        out = np.where(kind == rules.VIOLATED, VIOLATED, SATISFIED).astype(np.int64)
        pending = kind == rules.PENDING
        if len(codes) and int(codes.max()) >= len(self.ids):
            grown = np.full(max(int(codes.max()) + 1, 2 * len(self.ids)), -1, dtype=np.int32)
            grown[: len(self.ids)] = self.ids
            self.ids = grown
        fresh = codes[pending][self.ids[codes[pending]] < 0]
        unique, first = np.unique(fresh, return_index=True)
        new_codes = unique[np.argsort(first, kind="stable")]
        if self.too_large(self.count + len(new_codes)):
            from mitlc.product.explicit import _too_large

            assert self.limit is not None
            raise _too_large(
                f"the product of {self.num_s:,} world states and its task grows past "
                f"{self.limit:,} states",
                self.limit,
            )
        if self.count + len(new_codes) > INDEX_LIMIT:
            raise OverflowError("a product of more than 2^31 states")
        new_ids = np.arange(self.count, self.count + len(new_codes), dtype=np.int64)
        self.ids[new_codes] = new_ids
        self.codes.append(new_codes)
        self.count += len(new_codes)
        out[pending] = self.ids[codes[pending]]
        return out, new_ids

    def jumps(self, q: IntArray) -> tuple[IntArray, IntArray, IntArray]:
        """For each entry of ``q``: how many epsilon jumps it has, their targets and their
        ranks in the monitor's order of the state's jumps (all of them, entry after entry);
        the monitor is asked once per distinct state."""
        counts = self.monitor.jump_counts(q)
        none = np.zeros(0, dtype=np.int64)
        if not counts.any():
            return counts, none, none
        distinct, inverse = np.unique(q, return_inverse=True)
        lists = [self.monitor.jumps(state) for state in distinct.tolist()]
        sizes = np.array([len(targets) for targets in lists], dtype=np.int64)
        counts = sizes[inverse]
        if not sizes.any():
            return counts, none, none
        flat = np.array([t for targets in lists for t in targets], dtype=np.int64)
        start = np.cumsum(sizes) - sizes
        owner = np.repeat(np.arange(len(q)), counts)
        rank = np.arange(len(owner)) - np.repeat(np.cumsum(counts) - counts, counts)
        targets: IntArray = flat[start[inverse[owner]] + rank]
        return counts, targets, rank

    def build(self, start_codes: IntArray) -> IntArray:
        """Explore from ``start_codes`` (the start states' pair codes); the start states'
        product ids (absorbing ones for a start already decided)."""
        initial, frontier = self.intern(start_codes)
        codes = self.codes.data[self.codes.size - len(frontier) : self.codes.size].copy()
        while len(frontier):
            self.deadline.check_now()
            level_start = self.codes.size
            frontier = self._level(frontier, codes)
            # The new states' ids are consecutive, in the order their codes were appended.
            codes = self.codes.data[level_start : self.codes.size].copy()
        return initial

    def _level(self, frontier: IntArray, codes: IntArray) -> IntArray:
        """Expand one level (``frontier``: consecutive ids, ``codes`` their pairs), append its
        choices and transitions in product order; the next level's ids."""
        world, num_s, monitor = self.world, self.num_s, self.monitor
        s, q = codes % num_s, codes // num_s
        q_next, marks = monitor.successors(q, self.letters[s])
        c_owner, c_key, c_action, c_marks, e_choice, e_target, e_prob = [], [], [], [], [], [], []
        new_frontier, made = [], 0
        for a in range(world.num_actions):
            rows = s * world.num_actions + a
            lo, hi = world.transitions.indptr[rows], world.transitions.indptr[rows + 1]
            counts = hi - lo
            index = np.repeat(lo - np.cumsum(counts) + counts, counts) + np.arange(counts.sum())
            ids, new = self.intern(
                np.repeat(q_next, counts) * num_s + world.transitions.targets[index]
            )
            new_frontier.append(new)
            c_owner.append(np.arange(len(frontier)))
            c_key.append(np.full(len(frontier), a, dtype=np.int64))
            c_action.append(np.full(len(frontier), a, dtype=np.int64))
            c_marks.append(marks)
            e_choice.append(np.repeat(np.arange(made, made + len(frontier)), counts))
            e_target.append(ids)
            e_prob.append(world.transitions.probs[index])
            made += len(frontier)
        jump_counts, jump_targets, jump_ranks = self.jumps(q)
        if jump_counts.any():
            owner = np.repeat(np.arange(len(frontier)), jump_counts)
            ids, new = self.intern(jump_targets * num_s + s[owner])
            new_frontier.append(new)
            c_owner.append(owner)
            c_key.append(world.num_actions + jump_ranks)  # jumps after the world actions
            c_action.append(-1 - jump_targets)
            c_marks.append(np.zeros(len(owner), dtype=np.int64))
            e_choice.append(np.arange(made, made + len(owner)))
            e_target.append(ids)
            e_prob.append(np.ones(len(owner)))
        self._append_level(
            len(frontier),
            np.concatenate(c_owner),
            np.concatenate(c_key),
            np.concatenate(c_action),
            np.concatenate(c_marks),
            (np.concatenate(e_choice), np.concatenate(e_target), np.concatenate(e_prob)),
        )
        return np.concatenate(new_frontier)

    def _append_level(
        self,
        states: int,
        owner: IntArray,
        key: IntArray,
        action: IntArray,
        marks: IntArray,
        edges: tuple[IntArray, IntArray, FloatArray],
    ) -> None:
        """Append one level's choices sorted by state, then action (jumps last, in the order
        of the automaton state's jumps: the wrapper's jump actions), and their transitions
        with duplicate targets summed and targets sorted within each choice (in the order the
        edges were made, so sums are those of a whole-product merge)."""
        e_choice, e_target, e_prob = edges
        order = np.lexsort((key, owner))
        rank = np.empty_like(order)
        rank[order] = np.arange(len(order))
        combined = rank[e_choice] * self.count + e_target
        unique, inverse = np.unique(combined, return_inverse=True)
        # Summed in the order the edges were made, as ``np.add.at`` sums them: the same floats.
        probs = np.bincount(inverse, weights=e_prob, minlength=len(unique))
        edge_choice = unique // self.count
        base_choice, base_edge = self.action.size, self.targets.size
        per_state = np.bincount(owner, minlength=states)
        self.choice_ptr.append(base_choice + np.cumsum(per_state))
        self.action.append(action[order])
        self.marks.append(marks[order])
        per_choice = np.bincount(edge_choice, minlength=len(order))
        self.indptr.append(base_edge + np.cumsum(per_choice))
        self.targets.append(unique % self.count)
        self.probs.append(probs)
