"""The validated world: an MDP (or a POMDP) on a grid, as plain immutable arrays.

States are the free cells of the grid, numbered row by row (``cells[s] = (row, col)``; a cell
with uncertain labels has a state per outcome of them, :mod:`mitlc.worlds.uncertain`). The
transition relation is sparse, in compressed rows: the successors of state ``s`` under action
``a`` are ``next_states[indptr[r]:indptr[r + 1]]`` with probabilities ``probs[...]``, where
``r = s * num_actions + a``. Labels are observable: ``letters[s]`` is the set of propositions
true in state ``s``, as the letter index over ``propositions``
(``sum(1 << i for each true propositions[i])``). A POMDP adds an observation distribution per
state, in the same compressed-row form over observation ids.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from mitlc.worlds.costs import Costs

if TYPE_CHECKING:
    from mitlc.gym import TaskWrapper
    from mitlc.worlds.grid import GridMap
    from mitlc.worlds.team_model import Team

IntArray = npt.NDArray[np.int64]
FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]


@dataclass(frozen=True, slots=True)
class Sparse:
    """Compressed rows of probability distributions: row ``r`` is
    ``{targets[i]: probs[i] for i in range(indptr[r], indptr[r + 1])}``, targets increasing."""

    indptr: IntArray
    targets: IntArray
    probs: FloatArray

    @staticmethod
    def from_rows(rows: list[dict[int, float]]) -> Sparse:
        """Compressed rows from distributions ``{target: probability}``; targets sorted, zero
        probabilities dropped."""
        indptr, targets, probs = [0], [], []
        for row in rows:
            for target in sorted(row):
                if row[target] > 0.0:
                    targets.append(target)
                    probs.append(row[target])
            indptr.append(len(targets))
        return Sparse(
            np.asarray(indptr, dtype=np.int64),
            np.asarray(targets, dtype=np.int64),
            np.asarray(probs, dtype=np.float64),
        )

    @property
    def num_rows(self) -> int:
        """The number of rows."""
        return len(self.indptr) - 1

    def row(self, r: int) -> tuple[IntArray, FloatArray]:
        """The targets and probabilities of row ``r``."""
        lo, hi = int(self.indptr[r]), int(self.indptr[r + 1])
        return self.targets[lo:hi], self.probs[lo:hi]


@dataclass(frozen=True, slots=True)
class Observations:
    """A POMDP's observation model: ``model.row(s)`` is the distribution of what the agent
    observes in state ``s``, over the ids of ``names``."""

    names: tuple[str, ...]
    model: Sparse


@dataclass(frozen=True, slots=True)
class Rewards:
    """Reward terms: per acceptance mark, on satisfied, on violated, per non-stay move."""

    accept: float = 100.0
    satisfied: float = 100.0
    violated: float = 0.0
    move: float = 0.0


@dataclass(frozen=True, slots=True)
class World:
    """A world with its task (see the module docstring): a grid, or a finite gymnasium env
    (:mod:`mitlc.worlds.gym_world`), whose states are then its observations."""

    name: str
    rows: int
    cols: int
    cells: tuple[tuple[int, int], ...]
    """``cells[s]``: the cell ``(row, col)`` of state ``s``; in a team world, the robots' cells
    as one flat tuple ``(r0, c0, r1, c1, ...)`` (:attr:`team` splits them; the annotation stays
    the one-robot pair's until the callers that draw cells take joint ones). Several states
    share a cell where the state carries more than the cell: a team's swap flag, or the
    outcome of a grid cell's uncertain labels (:mod:`mitlc.worlds.uncertain`)."""
    actions: tuple[str, ...]
    start: int
    transitions: Sparse
    """Row ``s * len(actions) + a``: the distribution of the next state."""
    propositions: tuple[str, ...]
    letters: IntArray
    """``letters[s]``: the letter (index) labelling state ``s``."""
    spec: str
    """The task: a formula's text."""
    spec_source: str
    """Where the task came from: a spec file's path, or ``<inline>``."""
    horizon: int
    discount: float
    rewards: Rewards = field(default_factory=Rewards)
    observations: Observations | None = None
    """``None`` for an MDP."""
    start_distribution: tuple[tuple[int, float], ...] = ()
    """Where an episode starts: empty for the certain start ``start`` (any world with a single
    start state); otherwise the ``(state, probability)`` pairs of positive probability, sorted
    by state, with ``start`` the most probable of them (the lowest id on ties). A world made
    from a gymnasium env takes it from ``initial_state_distrib``; a grid world from its
    ``start:`` (a list of cells, weighted cells or ``uniform``) times the outcomes of the start
    cells' uncertain labels (:mod:`mitlc.worlds.uncertain`)."""
    costs: Costs | None = None
    """What the steps of an episode cost beside its success (``costs:``; ``None``: none), read
    through :func:`mitlc.product.costs.product_costs`."""
    team: Team | None = None
    """The robots of a team world (:mod:`mitlc.worlds.team`): how its joint states, actions
    and observations split per robot; ``None`` for a world of one agent."""
    training: Mapping[str, Any] = field(default_factory=dict)
    """The file's ``training`` settings (:func:`mitlc.learn.config.config_for` reads them)."""
    drawing: GridMap | None = None
    """The map a plot draws trajectories on (``None``: the world has none, e.g. an env's)."""

    @property
    def default_algo(self) -> str:
        """The learner a run takes unless told: the recurrent DQN for a POMDP, else tabular
        Q-learning."""
        return "drqn" if self.is_pomdp else "q"

    def task_env(self, automaton: Any, *, flatten: bool = False, **options: Any) -> TaskWrapper:
        """A fresh gymnasium env of the world under its task (the product env,
        :class:`mitlc.product.env.ProductEnv`), with the task ``automaton`` compiled once for
        many envs; ``options``: the wrapper's ``task_obs`` and ``potential``."""
        from mitlc.product.env import ProductEnv

        env: TaskWrapper = ProductEnv(self, automaton, flatten=flatten, **options)
        return env

    @property
    def num_states(self) -> int:
        """The number of states (of a grid world: its free cells, with the outcomes of their
        uncertain labels)."""
        return len(self.cells)

    @property
    def num_actions(self) -> int:
        """The number of actions."""
        return len(self.actions)

    @property
    def is_pomdp(self) -> bool:
        """Whether the agent sees an observation rather than its cell."""
        return self.observations is not None

    def state_of(self, cell: tuple[int, int]) -> int:
        """The (first) state of a free cell."""
        return self.cells.index(cell)
