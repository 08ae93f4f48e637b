"""The task monitor: the single definition of a task during an episode.

``TaskMonitor(automaton, rewards)`` follows one run of a limit-deterministic generalized Büchi
automaton (DESIGN.md, "The automaton") along the letters an episode produces. Its state is
``(automaton state, frontier, rounds, steps)``; a world step reads the letter of the position
being left (position 0 is the start, before the first action), and an epsilon jump moves the
automaton without reading a letter or taking time. Each step gives the transition's marks, the
sets new in the round, the task's reward, the verdict, whether the episode is decided and
whether it is a success, by the rules of :mod:`mitlc.task.rules`.

The automaton is anything with the :class:`TaskAutomaton` interface: the eager
:class:`mitlc.automata.DigitalAutomaton` or the lazy one, whose states and successors are made
on first reach; the monitor memoises the successors it asks for in growing tables, so the
batched form (:meth:`TaskMonitor.successors`, :meth:`TaskMonitor.read_batch`) is a gather.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple, Protocol

import numpy as np

from mitlc.task import rules
from mitlc.task.rules import VERDICT_CODES, TaskRewards
from mitlc.worlds.model import BoolArray, FloatArray, IntArray

DENSE_LETTERS = 1 << 20
"""With at most this many letters (20 propositions) the batched form finds a letter's column in
a dense table; with more, by binary search among the letters seen."""


TABLE_SETS = 8
"""With at most this many acceptance sets the frontier rule is tabulated over every (frontier,
marks) pair (4**8 entries); with more, it is computed."""


class TaskAutomaton(Protocol):
    """What the monitor reads of an automaton (eager or lazy)."""

    @property
    def formula(self) -> str: ...
    @property
    def propositions(self) -> tuple[str, ...]: ...
    @property
    def num_sets(self) -> int: ...
    @property
    def initial(self) -> int: ...
    def successor(self, state: int, letter: int) -> tuple[int, int]:
        """``(target, marks)`` of the transition of ``state`` on ``letter``."""
        ...

    def verdict(self, state: int) -> str:
        """``pending``, ``violated`` or ``satisfied``."""
        ...

    def jumps(self, state: int) -> tuple[int, ...]:
        """The targets of the epsilon jumps of ``state``, in order."""
        ...

    def end(self, state: int) -> int:
        """What a trace that stops in ``state`` is worth: its end code
        (:attr:`mitlc.automata.DigitalState.end`)."""
        ...

    def obligation(self, state: int) -> str:
        """What ``state`` still owes, as a formula's text."""
        ...


class MonitorState(NamedTuple):
    """Where a run of the task is: automaton state, frontier, completed rounds, world steps."""

    q: int
    frontier: int
    rounds: int
    steps: int


class Outcome(NamedTuple):
    """What one step (a letter read, or a jump) did."""

    state: MonitorState
    marks: int
    new: int
    """Acceptance sets new in the round."""
    reward: float
    verdict: int
    """A code of :data:`mitlc.task.rules.VERDICT_NAMES`."""
    terminated: bool
    success: bool


class BatchOutcome(NamedTuple):
    """:class:`Outcome` for a batch of runs, as arrays."""

    q: IntArray
    frontier: IntArray
    rounds: IntArray
    marks: IntArray
    new: IntArray
    reward: FloatArray
    verdict: IntArray
    terminated: BoolArray
    success: BoolArray


class TaskMonitor:
    """A task's rules over an automaton (see the module docstring)."""

    def __init__(self, automaton: TaskAutomaton, rewards: TaskRewards) -> None:
        self.automaton, self.rewards = automaton, rewards
        self.num_sets = automaton.num_sets
        self.all_sets = (1 << self.num_sets) - 1
        self._popcount = rules.popcounts(self.num_sets)
        self._popcount_array = np.asarray(self._popcount, dtype=np.int64)
        self._memo: dict[tuple[int, int], tuple[int, int, int]] = {}
        self._verdicts: list[int] = []
        self._ends: list[int] = []
        self._jumps: list[tuple[int, ...]] = []
        self._letter_keys = np.zeros(0, dtype=np.int64)
        self._letter_columns = np.zeros(0, dtype=np.int64)
        letters = 1 << len(automaton.propositions)
        self._dense_size = letters if letters <= DENSE_LETTERS else 0
        self._dense = np.zeros(self._dense_size, dtype=np.int64)
        self._column_letters: list[int] = [-1]
        self._jump_count_array = np.zeros(0, dtype=np.int64)
        # successor tables, a row per automaton state and a column per letter seen (column 0
        # stays unfilled: the column of letters not seen yet)
        self._next = np.full((1, 1), -1, dtype=np.int64)
        self._marks = np.zeros((1, 1), dtype=np.int64)
        self._next_flat, self._marks_flat = self._next.reshape(-1), self._marks.reshape(-1)
        self._verdict_array = np.zeros(0, dtype=np.int64)
        self._end_array = np.zeros(0, dtype=np.int64)
        self._success_list: list[bool] = []
        self._rule_tables()

    @property
    def propositions(self) -> tuple[str, ...]:
        """The automaton's propositions: bit ``i`` of a letter is ``propositions[i]``."""
        return self.automaton.propositions

    def letter(self, true_props: Sequence[str] | set[str] | frozenset[str]) -> int:
        """The letter in which exactly ``true_props`` hold (others are ignored)."""
        return sum(1 << i for i, p in enumerate(self.propositions) if p in true_props)

    # -- one run -------------------------------------------------------------------------------

    def reset(self) -> MonitorState:
        """The start of a run: the initial state, an empty frontier, no rounds, no steps."""
        return MonitorState(self.automaton.initial, 0, 0, 0)

    def verdict(self, q: int) -> int:
        """The verdict code of automaton state ``q``."""
        verdicts = self._verdicts
        if q >= len(verdicts):
            self._learn_states(q)
        return verdicts[q]

    def jumps(self, q: int) -> tuple[int, ...]:
        """The epsilon-jump targets of ``q``."""
        if q >= len(self._jumps):
            self._learn_states(q)
        return self._jumps[q]

    def step(self, state: MonitorState, letter: int) -> Outcome:
        """A world step: the automaton reads ``letter`` (the position being left)."""
        q, frontier, rounds, steps = state
        found = self._memo.get((q, letter))
        if found is None:
            found = self._transition(q, letter)
        target, marks, verdict = found
        if self._account_rows is None:
            after, new, complete = rules.account(frontier, marks, self.all_sets, self._popcount)
        else:
            after, new, complete = self._account_rows[frontier * self._sets_size + marks]
        rounds += complete
        return Outcome(
            MonitorState(target, after, rounds, steps + 1),
            marks,
            new,
            self._reward_list[new * 3 + verdict],
            verdict,
            self._terminated_list[verdict],
            self._success_of(target, after, rounds),
        )

    def jump(self, state: MonitorState, index: int) -> Outcome | None:
        """The ``index``-th epsilon jump of the state (no letter, no time); ``None`` when the
        state has no such jump."""
        targets = self.jumps(state.q)
        if not 0 <= index < len(targets):
            return None
        q = targets[index]
        verdict = self.verdict(q)
        return Outcome(
            state._replace(q=q),
            0,
            0,
            float(rules.reward(0, verdict, self.rewards)),
            verdict,
            bool(rules.terminated(verdict)),
            self._success_of(q, state.frontier, state.rounds),
        )

    def success(self, state: MonitorState) -> bool:
        """Whether a run that stops in ``state`` is a success (:func:`mitlc.task.rules.success`
        of its verdict, rounds and end value)."""
        if state.q >= len(self._verdicts):
            self._learn_states(state.q)
        return self._success_of(state.q, state.frontier, state.rounds)

    def _success_of(self, q: int, frontier: int, rounds: int) -> bool:
        """:func:`mitlc.task.rules.success` of a run in ``q`` with that frontier and rounds."""
        if self._ends[q] <= 1:  # most states: the seen sets do not matter
            return self._success_list[q]
        seen = rules.seen_sets(frontier, rounds, self.all_sets)
        return bool(rules.success(self._verdicts[q], seen, self._ends[q]))

    def end(self, q: int) -> int:
        """The end code of automaton state ``q`` (:mod:`mitlc.automata.ends`)."""
        if q >= len(self._ends):
            self._learn_states(q)
        return self._ends[q]

    # -- batches -------------------------------------------------------------------------------
    #
    # The batched form evaluates the rules once over their whole (small) domain, every
    # (frontier, marks) pair and every (sets new, verdict) pair, and then gathers: the same
    # definitions as the scalar form, at a handful of array operations a step.

    def successors(self, q: IntArray, letters: IntArray) -> tuple[IntArray, IntArray]:
        """``(targets, marks)`` for each pair ``(q[i], letters[i])``, made on first use."""
        columns = self._column_of(letters)
        if len(columns) and columns.min() == 0:  # letters not seen yet get their columns
            for letter in np.unique(letters[columns == 0]).tolist():
                self._add_letter(letter)
            columns = self._column_of(letters)
        if len(q) and q.max() >= self._next.shape[0]:
            self._grow(int(q.max()) + 1, self._next.shape[1])
        width = self._next.shape[1]
        flat = q * width + columns
        target: IntArray = self._next_flat.take(flat)
        if len(target) and target.min() < 0:
            for index in np.unique(flat[target < 0]).tolist():
                state, column = divmod(index, width)
                self._transition(state, self._column_letters[column])
            target = self._next_flat.take(flat)
        marks: IntArray = self._marks_flat.take(flat)
        return target, marks

    def jump_counts(self, q: IntArray) -> IntArray:
        """How many epsilon jumps each state of ``q`` has."""
        if len(q) and int(q.max()) >= len(self._verdicts):
            self._learn_states(int(q.max()))
        counts: IntArray = self._jump_count_array.take(q)
        return counts

    def verdicts(self, q: IntArray) -> IntArray:
        """The verdict codes of the automaton states ``q``."""
        if len(q) and int(q.max()) >= len(self._verdict_array):
            self._learn_states(int(q.max()))
        found: IntArray = self._verdict_array[q]
        return found

    def ends(self, q: IntArray) -> IntArray:
        """The end codes of the automaton states ``q`` (:meth:`end`)."""
        if len(q) and int(q.max()) >= len(self._end_array):
            self._learn_states(int(q.max()))
        found: IntArray = self._end_array[q]
        return found

    def read_batch(
        self, q: IntArray, frontier: IntArray, rounds: IntArray, letters: IntArray
    ) -> BatchOutcome:
        """:meth:`step` for a batch of runs (the steps counter is the caller's)."""
        target, marks = self.successors(q, letters)
        verdict = self._verdict_array.take(target)
        if self._account_rows is None:
            after, new, complete = rules.account(
                frontier, marks, self.all_sets, self._popcount_array
            )
        else:
            pair = frontier * self._sets_size + marks
            after, new, complete = (
                self._frontier_after.take(pair),
                self._new.take(pair),
                self._complete.take(pair),
            )
        rounds = rounds + complete
        return BatchOutcome(
            target,
            after,
            rounds,
            marks,
            new,
            self._reward.take(new * 3 + verdict),
            verdict,
            self._terminated.take(verdict),
            np.asarray(
                rules.success(
                    self._verdict_array.take(target),
                    rules.seen_sets(after, rounds, self.all_sets),
                    self._end_array.take(target),
                ),
                dtype=np.bool_,
            ),
        )

    def _rule_tables(self) -> None:
        """The rules evaluated over their whole domains, once, as arrays (for
        :meth:`read_batch`) and lists (for :meth:`step`): every (frontier, marks) pair when
        there are at most :data:`TABLE_SETS` acceptance sets (beyond, the rules are called),
        every (sets new, verdict) pair, every verdict."""
        size = self._sets_size = self.all_sets + 1
        self._account_rows: list[tuple[int, int, int]] | None = None
        if self.num_sets <= TABLE_SETS:
            frontier, marks = np.divmod(np.arange(size * size, dtype=np.int64), size)
            after, new, complete = rules.account(
                frontier, marks, self.all_sets, self._popcount_array
            )
            self._frontier_after, self._new = after, new
            self._complete = np.asarray(complete, dtype=np.int64)
            self._account_rows = list(
                zip(after.tolist(), new.tolist(), self._complete.tolist(), strict=True)
            )
        counts, verdicts = np.divmod(np.arange((self.num_sets + 1) * 3, dtype=np.int64), 3)
        self._reward = np.asarray(rules.reward(counts, verdicts, self.rewards), dtype=np.float64)
        codes = np.arange(3, dtype=np.int64)
        self._terminated = np.asarray(rules.terminated(codes), dtype=np.bool_)
        self._reward_list: list[float] = self._reward.tolist()
        self._terminated_list: list[bool] = self._terminated.tolist()

    # -- memo ----------------------------------------------------------------------------------

    def _transition(self, q: int, letter: int) -> tuple[int, int, int]:
        target, marks = self.automaton.successor(q, letter)
        verdict = self.verdict(target)
        found = (target, marks, verdict)
        self._memo[(q, letter)] = found
        column = self._add_letter(letter)
        if max(q, target) >= self._next.shape[0]:
            self._grow(max(q, target) + 1, self._next.shape[1])
        self._next[q, column], self._marks[q, column] = target, marks
        if q >= len(self._verdicts):
            self._learn_states(q)
        return found

    def _learn_states(self, q: int) -> None:
        """Verdicts, end codes, jumps and success of every state up to ``q``:
        ``success[state]`` for a run stopping there having seen no set, by
        :func:`mitlc.task.rules.success`."""
        for state in range(len(self._verdicts), q + 1):
            self._verdicts.append(VERDICT_CODES[self.automaton.verdict(state)])
            self._ends.append(int(self.automaton.end(state)))
            self._jumps.append(tuple(self.automaton.jumps(state)))
        self._verdict_array = np.asarray(self._verdicts, dtype=np.int64)
        self._end_array = np.asarray(self._ends, dtype=np.int64)
        self._jump_count_array = np.array([len(j) for j in self._jumps], dtype=np.int64)
        seen_none = rules.success(self._verdict_array, 0, self._end_array)
        self._success_list = np.asarray(seen_none, dtype=np.bool_).tolist()

    def _column_of(self, letters: IntArray) -> IntArray:
        """The tables' column of each letter; 0 (a column never filled) for a letter not seen
        yet. A dense lookup for alphabets of at most :data:`DENSE_LETTERS` letters, a binary
        search among the letters seen otherwise."""
        if self._dense_size:
            found: IntArray = self._dense.take(letters)
            return found
        keys = self._letter_keys
        if not len(keys):
            return np.zeros(len(letters), dtype=np.int64)
        where = np.minimum(np.searchsorted(keys, letters), len(keys) - 1)
        found = np.where(keys[where] == letters, self._letter_columns[where], 0)
        return found

    def _add_letter(self, letter: int) -> int:
        """The column of ``letter``, a new one if it has none yet."""
        column = int(self._column_of(np.array([letter], dtype=np.int64))[0])
        if column:
            return column
        column = self._next.shape[1]
        self._grow(self._next.shape[0], column + 1)
        self._column_letters.append(letter)
        if self._dense_size:
            self._dense[letter] = column
        else:
            keys = np.append(self._letter_keys, letter)
            columns = np.append(self._letter_columns, column)
            order = np.argsort(keys, kind="stable")
            self._letter_keys, self._letter_columns = keys[order], columns[order]
        return column

    def _grow(self, rows: int, cols: int) -> None:
        old_rows, old_cols = self._next.shape
        rows, cols = max(rows, 2 * old_rows if rows > old_rows else old_rows), cols
        if (rows, cols) == (old_rows, old_cols):
            return
        nxt = np.full((rows, cols), -1, dtype=np.int64)
        marks = np.zeros((rows, cols), dtype=np.int64)
        nxt[:old_rows, :old_cols], marks[:old_rows, :old_cols] = self._next, self._marks
        self._next, self._marks = nxt, marks
        self._next_flat, self._marks_flat = nxt.reshape(-1), marks.reshape(-1)
