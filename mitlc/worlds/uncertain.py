"""Uncertain labels and drawn starts on a grid: the world's states made exact for both.

A grid label may hold with a probability (``labels: {a: {cells: [...], probability: 0.9}}``):
each time the robot is in one of its cells, the proposition holds with that probability,
independently of every other step and every other label. ``World.letters`` must stay a function
of the state (the product, the checker, the DRN export, the simulator, the wrapper, the exact
evaluation, the learners and the shields all read it so), so the outcome goes into the state,
as a team world puts its swap flag there (:mod:`mitlc.worlds.team`). A finite env world whose
labels carry a probability is expanded the same way (:func:`expand_outcomes`, over its env
states: :mod:`mitlc.worlds.gym_uncertain`):

**States.** A world state is a cell with the outcome of its uncertain labels: the set of them
that holds now. A cell without uncertain labels has one state; a cell with ``k`` of them has
one per outcome of positive probability (``2 ** k`` at most). States are numbered cell by cell,
row by row, and within a cell by the outcome's bits over the world's propositions, the empty
outcome first, so that a world without uncertain labels keeps its states exactly.
``World.cells[s]`` is the cell of state ``s`` (repeated across its outcomes) and
``World.state_of(cell)`` its first state. Only the propositions the world keeps (the task's and
the costs') are expanded: an uncertain label that nothing reads adds no state.

**Moves.** A move from state ``(c, o)`` goes to ``(c', o')`` with the motion model's
``P(c' | c, a)`` times the probability of outcome ``o'`` in ``c'``, the labels' probabilities
multiplied (``p`` where one holds, ``1 - p`` where it does not). Staying in a cell draws its
outcome again: the draw is made at every step, not once per visit.

**Starts.** The start distribution over cells (:func:`start_cells`) times the outcome's
probability in each start cell is :attr:`World.start_distribution`; ``World.start`` is its
most probable state (the lowest on ties), and the distribution is left empty when it is
certain.

**What the agent observes.** In an MDP world the agent observes its *state*: its cell and what
it perceives there. mitlc's automaton reads the letter of a cell on the step *from* it
(:mod:`mitlc.product.explicit`), so an agent seeing only its cell would not know the letter it
is about to read: the world would be partially observable and the checker's optimum out of its
reach. Seeing the outcome is what the usual product gives (the automaton state after reading
the label of the cell just entered, as in the paper and the peers' code); the observation ids
of an MDP stay its state ids (``tables.num_observations = num_states``). In a POMDP world the
agent observes its sensor's reading of the *cell* (the noisy-cell or local-pattern row of the
cell, the same for every outcome, over the same observation names): it learns an outcome only
through the automaton state after the step, as it learns a certain label in a POMDP.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from mitlc.worlds.grid import Cell, Layout
from mitlc.worlds.model import BoolArray, FloatArray, IntArray, Observations, Sparse
from mitlc.worlds.schema import UncertainLabel, WeightedStart, label_cells


@dataclass(frozen=True, slots=True)
class Expansion:
    """The world's states over its free cells (see the module docstring)."""

    cell: IntArray
    """``cell[s]``: the free cell (an index into ``Layout.cells()``) of state ``s``."""
    letter: IntArray
    """``letter[s]``: the world's letter of state ``s`` (certain and uncertain labels)."""
    prob: FloatArray
    """``prob[s]``: the probability of state ``s``'s outcome in its cell."""
    first: IntArray
    """``first[c] .. first[c + 1] - 1``: the states of cell ``c``."""

    @property
    def trivial(self) -> bool:
        """Whether every cell has one state (no uncertain label is read)."""
        return len(self.cell) == len(self.first) - 1

    def transitions(
        self, motion: Sparse, num_actions: int, absorbing: BoolArray | None = None
    ) -> Sparse:
        """The motion model over cells (rows ``c * num_actions + a``) as rows
        ``s * num_actions + a`` over the states, each target cell split by its outcomes. The
        states of a cell ``c`` with ``absorbing[c]`` keep their outcome: each of their actions
        loops to the state itself (an env world's ended episode, whose last letter stays:
        :mod:`mitlc.worlds.gym_uncertain`)."""
        if self.trivial:
            return motion
        over_cells = self._split(motion)
        rows = (self.cell[:, None] * num_actions + np.arange(num_actions)).ravel()
        if absorbing is None or not absorbing.any():
            return _gather(over_cells, rows)
        loops = _loops(len(self.cell), num_actions)
        both = _stacked(over_cells, loops)
        stay = np.repeat(absorbing[self.cell], num_actions)
        return _gather(both, np.where(stay, over_cells.num_rows + np.arange(len(rows)), rows))

    def observations(self, model: Observations | None) -> Observations | None:
        """The sensor's row of each state's cell (see the module docstring)."""
        if model is None or self.trivial:
            return model
        return Observations(model.names, _gather(model.model, self.cell))

    def starts(self, weights: Sequence[tuple[int, float]]) -> list[tuple[int, float]]:
        """The start states and their probabilities, from start cells with probabilities."""
        found = []
        for c, w in weights:
            for s in range(int(self.first[c]), int(self.first[c + 1])):
                found.append((s, w * float(self.prob[s])))
        return sorted(found)

    def _split(self, motion: Sparse) -> Sparse:
        """Each target cell replaced by its states, the outcome's probability multiplied."""
        counts = np.diff(self.first)[motion.targets]
        targets = _ranges(self.first[motion.targets], counts)
        probs = np.repeat(motion.probs, counts) * self.prob[targets]
        row_of = np.repeat(np.arange(motion.num_rows), np.diff(motion.indptr))
        per_row = np.bincount(row_of, weights=counts, minlength=motion.num_rows)
        indptr = np.concatenate([[0], np.cumsum(per_row)]).astype(np.int64)
        return Sparse(indptr, targets.astype(np.int64), probs)


def expand(
    cells: Sequence[Cell], certain: Sequence[int], uncertain: Sequence[tuple[int, set[Cell], float]]
) -> Expansion:
    """The states of free ``cells`` whose certain letters are ``certain`` and whose uncertain
    labels are ``(bit, cells, probability)`` (probability below 1)."""
    return expand_outcomes(
        certain, [[(bit, p) for bit, where, p in uncertain if cell in where] for cell in cells]
    )


def expand_outcomes(
    certain: Sequence[int], uncertain: Sequence[Sequence[tuple[int, float]]]
) -> Expansion:
    """The states of cells ``c`` whose certain letter is ``certain[c]`` and whose uncertain
    labels are ``uncertain[c]``, pairs ``(bit, probability)`` (bit ``i`` of the letter, a
    probability below 1), each holding independently of the others."""
    cell_ids, letters, probs, first = [], [], [], [0]
    for c, here in enumerate(uncertain):
        outcomes: list[tuple[int, float]] = [(0, 1.0)]
        for bit, p in here:
            outcomes = [(o | (1 << bit), q * p) for o, q in outcomes] + [
                (o, q * (1.0 - p)) for o, q in outcomes
            ]
        for outcome, q in sorted(outcomes):
            if q > 0.0:
                cell_ids.append(c)
                letters.append(certain[c] | outcome)
                probs.append(q)
        first.append(len(cell_ids))
    return Expansion(
        np.asarray(cell_ids, dtype=np.int64),
        np.asarray(letters, dtype=np.int64),
        np.asarray(probs, dtype=np.float64),
        np.asarray(first, dtype=np.int64),
    )


def label_letters(
    cells: Sequence[Cell],
    labels: Mapping[str, Sequence[Cell] | UncertainLabel],
    propositions: Sequence[str],
) -> Expansion:
    """The states of a grid file's free ``cells`` under its ``labels``, read over the world's
    ``propositions`` (bit ``i`` for ``propositions[i]``; see the module docstring)."""
    certain = [0] * len(cells)
    index = {cell: c for c, cell in enumerate(cells)}
    uncertain: list[tuple[int, set[Cell], float]] = []
    for i, p in enumerate(propositions):
        label = labels.get(p)
        if label is None:
            continue
        where, _ = label_cells(label)
        if isinstance(label, UncertainLabel) and label.probability < 1.0:
            uncertain.append((i, set(where), label.probability))
            continue
        for cell in where:
            certain[index[cell]] |= 1 << i
    return expand(cells, certain, uncertain)


def start_cells(
    layout: Layout, start: Cell | list[Cell] | WeightedStart | str
) -> list[tuple[Cell, float]]:
    """The start cells and their probabilities, the most probable first (the first listed
    on ties): a cell, a list of cells (uniform), weighted cells, or ``uniform`` (every free
    cell)."""
    if isinstance(start, str):
        cells: Sequence[Cell] = layout.cells()
        weights: Sequence[float] = [1.0] * len(cells)
    elif isinstance(start, tuple):
        cells, weights = [start], [1.0]
    elif isinstance(start, list):
        cells, weights = start, [1.0] * len(start)
    else:
        cells, weights = start.cells, start.weights
    total = float(sum(weights))
    pairs = [(cell, float(w) / total) for cell, w in zip(cells, weights, strict=True)]
    order = sorted(range(len(pairs)), key=lambda i: (-pairs[i][1], i))
    return [pairs[i] for i in order]


def start_of(
    distribution: Sequence[tuple[int, float]],
) -> tuple[int, tuple[tuple[int, float], ...]]:
    """``World.start`` and ``World.start_distribution`` of start states with probabilities:
    the most probable (the lowest on ties), and the pairs sorted by state (empty when one
    state is certain)."""
    pairs = sorted((s, p) for s, p in distribution if p > 0.0)
    start = min(pairs, key=lambda sp: (-sp[1], sp[0]))[0]
    return start, (() if len(pairs) == 1 else tuple(pairs))


def _ranges(starts: IntArray, counts: IntArray) -> IntArray:
    """``concatenate(arange(starts[i], starts[i] + counts[i]))``, vectorised."""
    offsets = np.arange(int(counts.sum())) - np.repeat(np.cumsum(counts) - counts, counts)
    found: IntArray = np.repeat(starts, counts) + offsets
    return found


def _loops(num_states: int, num_actions: int) -> Sparse:
    """Rows ``s * num_actions + a`` that stay in ``s`` with probability 1."""
    n = num_states * num_actions
    targets = np.repeat(np.arange(num_states, dtype=np.int64), num_actions)
    return Sparse(np.arange(n + 1, dtype=np.int64), targets, np.ones(n))


def _stacked(top: Sparse, bottom: Sparse) -> Sparse:
    """The rows of ``top``, then those of ``bottom``."""
    indptr = np.concatenate([top.indptr, top.indptr[-1] + bottom.indptr[1:]])
    return Sparse(
        indptr,
        np.concatenate([top.targets, bottom.targets]),
        np.concatenate([top.probs, bottom.probs]),
    )


def _gather(sparse: Sparse, rows: IntArray) -> Sparse:
    """The rows ``rows`` of ``sparse``, in that order."""
    counts = np.diff(sparse.indptr)[rows]
    entries = _ranges(sparse.indptr[rows], counts)
    indptr = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    return Sparse(indptr, sparse.targets[entries], sparse.probs[entries])
