"""The breadth-first builder behind :func:`mitlc.product.explicit.build_product`.

The product is written straight into compact arrays, level by level of the breadth-first
search: the states a level discovers get consecutive ids, and every choice of a state is made
while its level is expanded, so each level's choices and transitions are appended to the
product's arrays on their own. Those arrays grow in place (:class:`Column`: ``realloc``, which
the C library does by remapping pages for large blocks, so a growing array is never held
twice), with 32-bit indices wherever they fit: the product's memory is about 12 bytes a
transition (a 32-bit target and a 64-bit probability, kept exact), and the build's own is one
level's worth beside it. Pairs ``(s, q)`` are coded ``q * S + s`` and numbered through a dense
index array over the codes seen (its bound ``S * Q``, 4 bytes a pair: the bound of the
product's states, a fraction of the product's own bytes).

A level costs no sort over all its transitions:

* the product order of choices (by state, then action, jumps last) is known beforehand, so
  every transition is written straight to its place in the product's arrays
  (:class:`Layout`, :meth:`Column.room`): a level makes no array of its transitions of its
  own, and the scratch it does make is one action's worth (memory touched for the first
  time costs more than the arithmetic on it; scratch that small is reused);
* new states are numbered in order of first appearance through the dense index array itself
  (:meth:`Builder.intern`: each fresh code's entry keeps the least position it occurs at,
  ``np.minimum.at``), with no ``np.unique``;
* within a choice the targets are put in increasing order and repeated ones summed
  (:func:`merge_rows`) only where a choice's targets are not already increasing, by a stable
  sort of ``(choice, target)`` keys that are already ordered by choice (Timsort's runs, as
  numpy's ``kind="stable"`` sorts them), a block of choices at a time. A repeated target's
  probabilities are summed in the order the world lists them, as a whole-product merge sums
  them, so every array is the same, bit for bit, as a merge of the whole product would give.
"""

from __future__ import annotations

from dataclasses import dataclass
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

Index = npt.NDArray[np.integer[Any]]
"""Integers of 32 or 64 bits (ids, targets, counts)."""

MERGE_BLOCK = 1 << 21
"""Transitions per block of :func:`merge_rows` (its scratch is about 40 bytes a transition)."""


class Column:
    """A one-dimensional array that grows in place (``ndarray.resize``: ``realloc``, which the
    C library does by remapping pages for large blocks, so a growing array is never copied
    whole) by a quarter at least, so that appending costs amortised constant time and the
    capacity past the values (which ``resize`` zeroes, so makes resident) is small.

    A level writes its transitions straight into the room :meth:`room` makes (no array of
    its own to append), and keeps them with :meth:`keep`."""

    GROWTH = 1.25

    def __init__(self, dtype: npt.DTypeLike, deadline: Deadline | None = None) -> None:
        self.data = np.empty(1024, dtype=dtype)
        self.size = 0
        self.deadline = deadline

    @property
    def dtype(self) -> np.dtype[Any]:
        """The column's type."""
        return self.data.dtype

    def room(self, count: int) -> npt.NDArray[Any]:
        """The ``count`` entries after the values, made room for (a view: valid until the
        column grows again; what is written there is kept by :meth:`keep`)."""
        end = self.size + count
        if end > len(self.data):
            capacity = max(end, int(self.GROWTH * len(self.data)))
            if self.deadline is not None:
                more = (capacity - len(self.data)) * self.data.itemsize
                self.deadline.reserve(more, "the product's arrays")
            self.data.resize(capacity, refcheck=False)
        return self.data[self.size : end]

    def keep(self, count: int) -> None:
        """Count the next ``count`` entries (written through :meth:`room`) as values."""
        self.size += count

    def append(self, values: npt.ArrayLike) -> None:
        """Append ``values`` (cast to the column's type; a 32-bit column whose values pass
        :data:`INDEX_LIMIT` becomes a 64-bit one first)."""
        array = np.asarray(values)
        wide = self.data.dtype == np.int32 and array.dtype.itemsize > 4 and len(array) > 0
        if wide and int(np.abs(array).max()) > INDEX_LIMIT:
            self.data = self.data.astype(np.int64)
        self.room(len(array))[:] = array
        self.keep(len(array))

    def finish(self) -> npt.NDArray[Any]:
        """The array of the values appended (the column's buffer, trimmed in place)."""
        self.data.resize(self.size, refcheck=False)
        return self.data


def exclusive_sum(counts: Index) -> IntArray:
    """``[0, c0, c0 + c1, ...]``: where each of ``counts``' blocks starts (one more entry
    than ``counts``, the last the total)."""
    starts = np.zeros(len(counts) + 1, dtype=np.int64)
    np.cumsum(counts, out=starts[1:])
    return starts


@dataclass(frozen=True, slots=True)
class Layout:
    """Where a level's choices and transitions go, in product order: state ``i``'s world
    action ``a`` is choice ``first[i] + a``, its jump of rank ``r`` choice
    ``first[i] + A + r``, and choice ``c``'s transitions start at ``edge_start[c]`` (both
    with a last entry: the level's choices and transitions)."""

    first: IntArray
    edge_start: IntArray

    @staticmethod
    def of(lengths: Index, jump_counts: IntArray) -> Layout:
        """The layout of states with ``lengths[i, a]`` transitions for world action ``a``
        and ``jump_counts[i]`` jumps (one transition each)."""
        actions = lengths.shape[1]
        first = exclusive_sum(actions + jump_counts)
        sizes: Index
        if jump_counts.any():
            sizes = np.ones(int(first[-1]), dtype=np.int64)
            sizes[first[:-1, None] + np.arange(actions)] = lengths
        else:
            sizes = lengths.ravel()
        return Layout(first, exclusive_sum(sizes))

    def world_choices(self, a: int) -> IntArray:
        """Every state's choice of world action ``a``."""
        return self.first[:-1] + a


def merge_rows(
    starts: IntArray, targets: Index, probs: FloatArray, span: int
) -> tuple[Index, FloatArray, Index]:
    """Rows (row ``r``: ``starts[r] .. starts[r+1]-1``, targets below ``span``) with targets
    put in increasing order and repeated targets merged, their probabilities summed in the
    order given; ``(targets, probs, sizes)``. Rows whose targets already increase are left
    as they are, and when every row's do, nothing is sorted or copied."""
    sizes = np.diff(starts)
    if not len(targets) or int(sizes.max()) <= 1:
        return targets, probs, sizes
    later = np.ones(len(targets), dtype=np.bool_)  # an entry that is not first in its row
    later[starts[:-1][sizes > 0]] = False
    later = later[1:]
    if not (later & (targets[1:] <= targets[:-1])).any():
        return targets, probs, sizes
    row = np.repeat(np.arange(len(sizes), dtype=np.int64), sizes)
    order = np.argsort(row * span + targets, kind="stable")  # runs by row already
    targets, probs = targets[order], probs[order]
    repeated = later & (targets[1:] == targets[:-1])
    if not repeated.any():
        return targets, probs, sizes
    keep = np.concatenate([[True], ~repeated])
    # Stable: a target's entries are summed in the order given, as ``np.bincount`` over the
    # unsorted entries would sum them.
    summed = np.bincount(np.cumsum(keep) - 1, weights=probs).astype(np.float64, copy=False)
    sizes = sizes - np.bincount(row[1:][repeated], minlength=len(sizes))
    return targets[keep], summed, sizes


class Builder:
    """Breadth-first exploration, one frontier (all states of a level) at a time in numpy.

    A pair ``(s, q)`` is coded ``q * S + s``, so the table of ids grows with the automaton
    states the monitor makes; the automaton's steps, verdicts and jumps are the monitor's,
    asked in the order a level's actions are taken (which matters for a lazy automaton, whose
    states are numbered as they are first asked for)."""

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
        self.row_lengths = np.diff(world.transitions.indptr).astype(np.int32)
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

    def intern(self, codes: IntArray, kind: IntArray | None = None) -> tuple[Index, IntArray]:
        """Product ids (32-bit) of ``q * S + s`` codes, new ones numbered in order of first
        appearance, and the new states' codes; ``kind``: the codes' verdicts when the caller
        has them (else the monitor's of ``q``)."""
        if kind is None:
            kind = self.monitor.verdicts(codes // self.num_s)
        is_pending = kind == rules.PENDING
        every = bool(is_pending.all())
        if not every:
            out = (kind != rules.VIOLATED).astype(np.int32)  # VIOLATED is 0, SATISFIED 1
            pending = np.flatnonzero(is_pending)
            codes = codes[pending]
        if len(codes) and int(codes.max()) >= len(self.ids):
            grown = np.full(max(int(codes.max()) + 1, 2 * len(self.ids)), -1, dtype=np.int32)
            grown[: len(self.ids)] = self.ids
            self.ids = grown
        found = self.ids[codes]
        fresh_at = np.flatnonzero(found < 0)
        fresh = codes[fresh_at]
        new_codes = self._first_seen(fresh)
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
        self.ids[new_codes] = np.arange(self.count, self.count + len(new_codes))
        self.codes.append(new_codes)
        self.count += len(new_codes)
        found[fresh_at] = self.ids[fresh]
        if every:
            return found, new_codes
        out[pending] = found
        return out, new_codes

    def _first_seen(self, fresh: IntArray) -> IntArray:
        """The distinct codes of ``fresh`` (none in the table yet) in order of first
        appearance, found on the table of ids: each code's entry is set to the least position
        it occurs at (``np.minimum.at``), and an occurrence is the first exactly when its
        position is the one left there. No sort; the entries are left unseen (``-1``)."""
        if not len(fresh):
            return fresh
        position = np.arange(len(fresh), dtype=self.ids.dtype)
        self.ids[fresh] = INDEX_LIMIT
        np.minimum.at(self.ids, fresh, position)
        first: IntArray = fresh[self.ids[fresh] == position]
        self.ids[fresh] = -1
        return first

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

    def build(self, start_codes: IntArray) -> Index:
        """Explore from ``start_codes`` (the start states' pair codes); the start states'
        product ids (absorbing ones for a start already decided)."""
        initial, codes = self.intern(start_codes)
        while len(codes):
            self.deadline.check_now()
            codes = self._level(codes)
        return initial

    def _level(self, codes: IntArray) -> IntArray:
        """Expand one level (the states of ``codes``, numbered consecutively in that order),
        append its choices and transitions in product order; the next level's codes.

        New states are numbered as the actions are taken: action 0 from every state of the
        level, then action 1, ..., then the jumps."""
        world, num_s, num_a, monitor = self.world, self.num_s, self.world.num_actions, self.monitor
        s, q = codes % num_s, codes // num_s
        q_next, marks = monitor.successors(q, self.letters[s])
        lengths = self.row_lengths.reshape(num_s, num_a)[s]  # a state's rows are consecutive
        moving = lengths.any(axis=1)  # the verdicts asked for: those of states that move
        verdict = np.zeros(len(q_next), dtype=np.int64)
        verdict[moving] = monitor.verdicts(q_next[moving])
        jump_counts, jump_targets, jump_ranks = self.jumps(q)
        layout = Layout.of(lengths, jump_counts)
        lengths = lengths.T.copy()  # by action, for the loop over actions
        edges = int(layout.edge_start[-1])
        targets, probs = self.targets.room(edges), self.probs.room(edges)
        new_codes, transitions = [], world.transitions
        lo = transitions.indptr[s * num_a]  # where each state's row of action ``a`` starts
        for a in range(num_a):
            counts = lengths[a]
            # The world's entries of each state's row, and where they go in the product.
            index = np.repeat(lo - exclusive_sum(counts)[:-1], counts) + np.arange(counts.sum())
            to = index + np.repeat(layout.edge_start[layout.world_choices(a)] - lo, counts)
            pair = np.repeat(q_next * num_s, counts) + transitions.targets[index]
            ids, new = self.intern(pair, np.repeat(verdict, counts))
            targets[to], probs[to] = ids, transitions.probs[index]
            new_codes.append(new)
            lo += counts
        del lengths
        choices = int(layout.first[-1])
        self.choice_ptr.append(self.action.size + layout.first[1:])
        action, choice_marks = self.action.room(choices), self.marks.room(choices)
        if jump_counts.any():
            world_choices = layout.first[:-1, None] + np.arange(num_a)
            action[world_choices], choice_marks[world_choices] = np.arange(num_a), marks[:, None]
            del world_choices
            owner = np.repeat(np.arange(len(codes)), jump_counts)
            choice = layout.first[owner] + num_a + jump_ranks  # after the world actions
            ids, new = self.intern(jump_targets * num_s + s[owner])
            targets[layout.edge_start[choice]], probs[layout.edge_start[choice]] = ids, 1.0
            action[choice], choice_marks[choice] = -1 - jump_targets, 0
            new_codes.append(new)
        else:  # every state's actions in order
            action.reshape(len(codes), num_a)[:] = np.arange(num_a)
            choice_marks.reshape(len(codes), num_a)[:] = marks[:, None]
        self.action.keep(choices)
        self.marks.keep(choices)
        self._merge_level(layout.edge_start, targets, probs)
        return np.concatenate(new_codes)

    def _merge_level(self, starts: IntArray, targets: Index, probs: FloatArray) -> None:
        """Merge a level's transitions (choice ``c``'s: ``starts[c] .. starts[c+1]-1``,
        written in the room after the product's) by :func:`merge_rows`, about
        :data:`MERGE_BLOCK` of them at a time, each block moved down to where the merged ones
        before it end; keep them and their choices' pointers."""
        lo, choices, at = 0, len(starts) - 1, 0
        while lo < choices:
            hi = int(np.searchsorted(starts, starts[lo] + MERGE_BLOCK, side="right")) - 1
            hi = min(max(hi, lo + 1), choices)
            block = slice(int(starts[lo]), int(starts[hi]))
            given = targets[block]
            merged, summed, sizes = merge_rows(
                starts[lo : hi + 1] - starts[lo], given, probs[block], self.count
            )
            self.indptr.append(self.targets.size + at + np.cumsum(sizes))
            if merged is not given or at != block.start:  # merged, or moved down
                targets[at : at + len(merged)], probs[at : at + len(merged)] = merged, summed
            at += len(merged)
            lo = hi
        self.targets.keep(at)
        self.probs.keep(at)
