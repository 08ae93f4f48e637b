"""Counterfactual experience on worlds that are not finite (Toro Icarte, Klassen, Valenzano and
McIlraith, "Reward Machines: Exploiting Reward Function Structure in Reinforcement Learning",
JAIR 73, 2022: CRM), for mitlc's DQN on wrapped envs (``dqn.crm``) and for SB3's replay
(``sb3.crm``, :mod:`mitlc.learn.backends.sb3_crm`).

As on a finite product (:mod:`mitlc.learn.learners.crm`), the env's step does not depend on
the task's state: an env step ``obs --action--> obs'`` that the task read in automaton state
``q`` with frontier ``f`` is a sample of what the same step does in every other task state.
Here there is no product to enumerate, so the task states are the automaton's own: from each
experienced step, :meth:`EnvCounterfactuals.rows` makes, for other task states ``(q', f')``,
the transition with the same ``obs``, action and ``obs'``, the task's part replaced. The task
step is the monitor's (:meth:`mitlc.task.TaskMonitor.read_batch`, its :meth:`step` for a
batch): from ``MonitorState(q', f', rounds, steps)`` it reads the step's letter
(``info["letter"]``, that of the position left), giving the next automaton state and frontier,
the reward, whether a set was added to the frontier and whether the task is decided (the
episode terminates). Where the wrapper adds the env's reward (``reward_mode="add"``), the
step's ``info["env_reward"]`` is added, as the wrapper does. Rounds and steps enter neither
the reward nor the termination (only success and the horizon's truncation, which the caller
reads from the experienced step's own count).

**Which task states, and the bound.** Every *pending* automaton state of the (eager) digital
automaton times every frontier a round can have (``0 .. 2^k - 2`` for ``k`` acceptance sets,
just 0 without any; a completed round empties the frontier), the experienced one left out, as
:mod:`mitlc.learn.learners.crm` enumerates every frontier; a decided state is never left by a
step, since an episode ends on entering it. That is at most ``|Q| * max(2^k - 1, 1) - 1``
transitions a step; where it is more than ``limit`` (:data:`LIMIT` by default) a step gives a
uniform sample of ``limit`` of them, drawn without replacement from the learner's random
generator, so the memory is not flooded by one step's counterfactuals (a deadline task's
automaton counts time in its states: PointMaze's task has 203).

**Skipped steps** (the experienced transition is kept as it is; only its counterfactuals are
not made), by :meth:`EnvCounterfactuals.tells`:

* a step that read no letter (``letter`` -1): an epsilon jump, or an invalid action, moves the
  automaton alone and the env does not step (and a state's jumps are its own), as in
  :mod:`mitlc.learn.learners.crm`;
* a step with ``info["env_ended"]``: where the env had already ended, the wrapper keeps the
  world on its last position, which the env's observation does not show (an env cut by its
  own time limit stops where a live one moves on), so the step is no sample of the env's
  dynamics at that observation, and its counterfactuals would repeat that wrong sample once
  per task state; where the env ended on this very step, with ``env_end="finish"`` (the
  default without jumps) the wrapper ran the rest of the episode within the step, reading the
  last position's letter (which no info holds) up to the horizon, which is not one task step.
  (With ``env_end="step"`` that one step an episode would be a fair sample; the info does not
  tell the two apart, and it is left out too.)
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from gymnasium import spaces

from mitlc.automata.digital import DigitalAutomaton
from mitlc.errors import MitlcError
from mitlc.task import PENDING, TaskMonitor
from mitlc.task.potential import shaped
from mitlc.worlds.model import BoolArray, FloatArray, IntArray

LIMIT = 64
"""The most counterfactual transitions one experienced step gives (a uniform sample above)."""


class CounterfactualError(MitlcError, ValueError):
    """Counterfactual experience cannot be made here (see the message)."""


@dataclass(frozen=True, slots=True)
class Rows:
    """The counterfactual transitions of a batch of experienced steps, as arrays: row ``r`` is
    the step ``source[r]`` of the batch, taken in task state ``(q[r], frontier[r])``."""

    source: IntArray
    q: IntArray
    frontier: IntArray
    reward: FloatArray
    """The task's reward, plus the env's where the wrapper adds it."""
    accepting: BoolArray
    """The step added a set to the frontier."""
    terminated: BoolArray
    """The task is decided: the episode ends."""
    next_q: IntArray
    next_frontier: IntArray


class EnvCounterfactuals:
    """The task states of a wrapped env and the monitor's step over them (see the module
    docstring)."""

    def __init__(
        self,
        monitor: TaskMonitor,
        num_states: int,
        *,
        add_env_reward: bool,
        horizon: int,
        masks: BoolArray | None = None,
        limit: int = LIMIT,
        potential: Callable[[IntArray, FloatArray], FloatArray] | None = None,
    ) -> None:
        """``monitor``: the task's, over an automaton of ``num_states`` states; the wrapper's
        ``reward_mode`` (``add_env_reward``), ``horizon``, with ``Discrete`` actions its
        action masks by automaton state (``masks[q]``, :meth:`TaskWrapper.masks_of`), and where
        it has one its shaping potential (:meth:`TaskWrapper.potential_at`)."""
        if limit < 1:
            raise CounterfactualError(f"limit: expected a positive number, got {limit}")
        self.monitor, self.add_env_reward, self.horizon = monitor, add_env_reward, horizon
        self.masks, self.limit, self.potential = masks, limit, potential
        pending = np.flatnonzero(monitor.verdicts(np.arange(num_states)) == PENDING)
        self.num_frontiers = max(monitor.all_sets, 1)
        """The frontiers a round can have: ``0 .. num_frontiers - 1``."""
        self.pair_q = np.repeat(pending, self.num_frontiers)
        self.pair_frontier = np.tile(np.arange(self.num_frontiers), len(pending))
        """The task states a step is taken in, in order (``q`` major)."""
        self._rank = np.full(num_states, -1, dtype=np.int64)
        self._rank[pending] = np.arange(len(pending))

    @staticmethod
    def of(wrapper: Any, limit: int = LIMIT) -> EnvCounterfactuals:
        """The counterfactuals of :class:`mitlc.gym.TaskWrapper` ``wrapper`` (or an env that
        wraps one), over its own monitor's rules (a :class:`CounterfactualError` for a lazy
        automaton, whose states are not known in advance)."""
        wrapper = task_wrapper(wrapper)
        automaton = wrapper.automaton
        if not isinstance(automaton, DigitalAutomaton):
            raise CounterfactualError(
                "counterfactual experience needs the automaton's states: not a lazy automaton's"
            )
        monitor = TaskMonitor(automaton, wrapper.monitor.rewards)
        masks = None
        if isinstance(wrapper.action_space, spaces.Discrete):
            masks = np.stack([wrapper.masks_of(q) for q in range(wrapper.num_q)])
        return EnvCounterfactuals(
            monitor, len(automaton.states), add_env_reward=wrapper.reward_mode == "add",
            horizon=wrapper.horizon, masks=masks, limit=limit,
            potential=wrapper.potential_at if wrapper.has_potential else None,
        )  # fmt: skip

    @property
    def num_pairs(self) -> int:
        """The task states a step may be taken in."""
        return len(self.pair_q)

    @staticmethod
    def tells(letter: IntArray, env_ended: BoolArray) -> BoolArray:
        """Which experienced steps give counterfactuals: those that read a letter with the env
        still going (see the module docstring)."""
        told: BoolArray = (np.asarray(letter) >= 0) & ~np.asarray(env_ended, dtype=np.bool_)
        return told

    def pair_index(self, q: IntArray, frontier: IntArray) -> IntArray:
        """The index of each task state ``(q, frontier)`` among :attr:`pair_q` (-1 where it
        is not one: a decided state)."""
        q, frontier = np.asarray(q, dtype=np.int64), np.asarray(frontier, dtype=np.int64)
        rank = np.where(q < len(self._rank), self._rank[np.minimum(q, len(self._rank) - 1)], -1)
        inside = (rank >= 0) & (frontier >= 0) & (frontier < self.num_frontiers)
        index: IntArray = np.where(inside, rank * self.num_frontiers + frontier, -1)
        return index

    def choose(self, experienced: IntArray, rng: np.random.Generator) -> tuple[IntArray, IntArray]:
        """``(source, pair)``: for each experienced step ``i`` (its task state's index
        ``experienced[i]``, -1 for none), the task states its counterfactuals are taken in:
        every other one, or a uniform sample of :attr:`limit` of them."""
        sources, pairs = [], []
        every = np.arange(self.num_pairs)
        for i, e in enumerate(experienced.tolist()):
            others = self.num_pairs - (e >= 0)
            if others <= self.limit:
                pick = every if e < 0 else np.delete(every, e)
            else:
                pick = rng.choice(others, self.limit, replace=False)
                pick = pick + (pick >= e) if e >= 0 else pick
            sources.append(np.full(len(pick), i, dtype=np.int64))
            pairs.append(np.asarray(pick, dtype=np.int64))
        if not pairs:
            return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
        return np.concatenate(sources), np.concatenate(pairs)

    def rows(
        self,
        q: IntArray,
        frontier: IntArray,
        letter: IntArray,
        env_reward: FloatArray,
        told: BoolArray,
        rng: np.random.Generator,
        rounds: IntArray | None = None,
    ) -> Rows:
        """The counterfactual transitions of the experienced steps where ``told``
        (:meth:`tells`): step ``i`` read ``letter[i]`` in task state ``(q[i], frontier[i])``
        after ``rounds[i]`` completed rounds (default 0: rounds change no reward) and the env
        gave ``env_reward[i]``."""
        steps = np.flatnonzero(told)
        experienced = self.pair_index(np.asarray(q)[steps], np.asarray(frontier)[steps])
        chosen, pair = self.choose(experienced, rng)
        source = steps[chosen]
        cq, cf = self.pair_q[pair], self.pair_frontier[pair]
        done = np.zeros(len(source), dtype=np.int64) if rounds is None else rounds[source]
        read = np.asarray(letter, dtype=np.int64)[source]
        out = self.monitor.read_batch(cq, cf, np.asarray(done, dtype=np.int64), read)
        reward = np.asarray(out.reward, dtype=np.float64)
        if self.add_env_reward:
            reward = reward + np.asarray(env_reward, dtype=np.float64)[source]
        return Rows(
            source=source, q=cq, frontier=cf, reward=reward, accepting=out.new > 0,
            terminated=np.asarray(out.terminated, dtype=np.bool_), next_q=out.q,
            next_frontier=out.frontier,
        )  # fmt: skip

    def potentials(
        self, rows: Rows, left: FloatArray, reached: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """The wrapper's shaping potential (unscaled) of each counterfactual's task state where
        its step started, and of the task state it reached where the step ended (0 where the
        task is decided): ``left[i]`` and ``reached[i]`` are the distances
        (``info["distances_left"]``, ``info["distances"]``) of experienced step ``i``. The
        potential of a task state at a position is the wrapper's, whatever state the episode
        was in, so a counterfactual is shaped as the wrapper would have shaped it."""
        if self.potential is None:
            raise CounterfactualError("shaping counterfactuals needs the wrapper's potential "
                                      "(a TaskWrapper made with potential=REACH)")  # fmt: skip
        i = rows.source
        before = self.potential(rows.q, np.asarray(left, dtype=np.float64)[i])
        after = self.potential(rows.next_q, np.asarray(reached, dtype=np.float64)[i])
        return before, after

    def shaped_reward(
        self,
        rows: Rows,
        gammas: FloatArray,
        left: FloatArray,
        reached: FloatArray,
        scale: float,
    ) -> FloatArray:
        """The counterfactuals' rewards shaped at discounts ``gammas`` with ``scale`` times the
        wrapper's potentials (:meth:`potentials`): what every learner stores."""
        before, after = self.potentials(rows, left, reached)
        return shaped(rows.reward, gammas, scale * before, scale * after)

    def valid(self, q: IntArray) -> BoolArray:
        """The wrapper's valid actions in each automaton state ``q`` (its action masks)."""
        if self.masks is None:
            raise CounterfactualError("action masks need the wrapper's Discrete actions")
        valid: BoolArray = self.masks[q]
        return valid


def task_wrapper(env: Any) -> Any:
    """The :class:`mitlc.gym.TaskWrapper` ``env`` is or wraps (SB3's ``Monitor`` around it)."""
    from mitlc.gym import TaskWrapper

    found = env
    while not isinstance(found, TaskWrapper):
        inner = getattr(found, "env", None)
        if inner is None or inner is found:
            raise CounterfactualError(f"not a task-wrapped env: {env}")
        found = inner
    return found
