"""Learners for teams of robots on a team world's joint product (``training.team``).

A team world (:mod:`mitlc.worlds.team`) is a finite world whose actions are joint actions, so
every learner of mitlc learns it *jointly* (``team: joint``: one learner over the joint state
and the joint action). The two decentralised forms here let each robot choose its own action
from what it sees, :class:`RobotView`: its own cell (or, where it has a sensor, its own noisy
observation of it), the team task's automaton state and the frontier of acceptance sets.

* ``team: independent`` with ``algo: q``: independent Q-learners (Tan, "Multi-agent
  reinforcement learning: independent vs. cooperative agents", ICML 1993; Claus and Boutilier,
  AAAI 1998), :class:`IndependentQLearner`: one table per robot over (frontier, automaton
  state, own observation, own action), each updated toward the team's reward (the task's) plus
  its own greedy value of what it sees next. Updates of one entry by several episodes at once
  move it toward their mean target, as :mod:`mitlc.learn.learners.qlearning` does.
* ``team: shared`` with ``algo: dqn``: parameter sharing (Gupta, Egorov and Kochenderfer,
  "Cooperative multi-agent control using deep reinforcement learning", AAMAS 2017 workshops),
  :class:`SharedDQNLearner`: mitlc's DQN (:mod:`mitlc.learn.learners.dqn`) over every robot's
  experience, the robot's id one-hot in its input beside its observation (:class:`RobotSlots`
  shows each robot of each episode to the DQN as one episode of its own).

Exploration is each robot's own (an epsilon draw per robot). Actions invalid for a robot are
those no valid joint action gives it; under a per-robot shield
(:mod:`mitlc.check.team_shield`) the valid joint actions are a rectangle, so every combination
of the robots' choices is valid. Epsilon jumps are the task's, not a robot's: a task whose
automaton has them is learned jointly. A decentralised policy on an MDP team is a function of
the joint product state, so it is evaluated exactly (:meth:`TeamPolicy.choices`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from mitlc.learn.config import TrainConfig
from mitlc.learn.envs.vec import Step, Tables
from mitlc.learn.learners.base import (
    Episodes,
    Learner,
    Policy,
    epsilon_at,
    masked_argmax,
    random_valid,
    transition_signal,
)
from mitlc.worlds.model import BoolArray, FloatArray, IntArray
from mitlc.worlds.team_model import Team, radix_weights


class TeamLearnerError(ValueError):
    """A decentralised learner cannot learn this task on this world."""


class RobotView:
    """How each robot sees the joint product (see the module docstring)."""

    def __init__(self, team: Team, tables: Tables, pomdp: bool) -> None:
        self.team, self.tables, self.pomdp = team, tables, pomdp
        self.robots = team.num_robots
        self.radices = tuple(len(a) for a in team.actions)
        self.weights = radix_weights(self.radices)
        if int(np.prod(self.radices)) != tables.num_world_actions:
            raise TeamLearnerError("the world's actions are not the robots' joint actions")
        if tables.num_actions != tables.num_world_actions:
            raise TeamLearnerError(
                "the task has epsilon jumps (a choice of the task, not of a robot): learn it "
                "jointly (team: joint)"
            )
        self.counts = team.observation_counts() if pomdp else (len(team.cells),) * self.robots
        self.max_obs, self.max_actions = max(self.counts), max(self.radices)
        self._obs_weights = radix_weights(self.counts)
        self._cells = np.asarray(team.positions, dtype=np.int64)

    def own(self, observation: IntArray) -> IntArray:
        """``own[i, r]``: what robot ``r`` sees in episode ``i``, from the joint observation
        (the world state of an MDP, the joint observation id of a POMDP)."""
        observation = np.asarray(observation, dtype=np.int64)
        if not self.pomdp:
            found: IntArray = self._cells[observation]
            return found
        parts: IntArray = (observation[:, None] // self._obs_weights) % np.asarray(self.counts)
        return parts

    def own_valid(self, valid: BoolArray) -> BoolArray:
        """``own[i, r, k]``: robot ``r`` has action ``k`` in some valid joint action
        (``valid[i, a]`` over the joint actions; padded with ``False`` to the most actions)."""
        rows = valid.shape[0]
        table = valid[:, : self.tables.num_world_actions].reshape((rows, *self.radices))
        own = np.zeros((rows, self.robots, self.max_actions), dtype=np.bool_)
        for r, k in enumerate(self.radices):
            axes = tuple(1 + j for j in range(self.robots) if j != r)
            own[:, r, :k] = table.any(axis=axes) if axes else table
        return own

    def joint(self, parts: IntArray) -> IntArray:
        """The joint action of per-robot actions ``parts[i, r]``."""
        joint: IntArray = parts @ self.weights
        return joint


class TeamPolicy(Policy):
    """Each robot greedy in its own values (:meth:`values`), the joint action their
    combination."""

    def __init__(self, view: RobotView) -> None:
        self.view = view

    def values(self, own: IntArray, automaton: IntArray, mask: IntArray) -> FloatArray:
        """``values[i, r, k]``: robot ``r``'s value of its action ``k`` in episode ``i``."""
        raise NotImplementedError

    def parts(
        self, own: IntArray, automaton: IntArray, mask: IntArray, valid: BoolArray
    ) -> IntArray:
        """Each robot's greedy valid action."""
        values = self.values(own, automaton, mask)
        own_valid = self.view.own_valid(valid)
        rows, n, k = own_valid.shape
        best = masked_argmax(values.reshape(rows * n, k), own_valid.reshape(rows * n, k))
        return best.reshape(rows, n)

    def act(self, env: Episodes) -> IntArray:
        """The joint action of the robots' greedy actions."""
        own = self.view.own(env.observation)
        return self.view.joint(self.parts(own, env.automaton, env.mask, env.valid_actions()))

    def choices(self, valid: BoolArray | None = None) -> IntArray:
        """``choices[mask, x]``: the product choice the robots take in product state ``x``
        with frontier ``mask`` (-1 at the absorbing states) among ``valid[mask, x]`` (default:
        every valid one); an MDP team only (each robot sees its cell, a function of ``x``)."""
        t, view = self.view.tables, self.view
        if view.pomdp:
            raise TeamLearnerError("a policy over noisy observations is not memoryless in x")
        states = np.arange(t.num_states)
        live = t.world_state >= 0
        own = view.own(np.maximum(t.world_state, 0))
        automaton = np.maximum(t.automaton_state, 0)
        chosen = np.full((t.all_sets + 1, t.num_states), -1, dtype=np.int64)
        for mask in range(t.all_sets + 1):
            allowed = t.valid if valid is None else valid[mask]
            parts = self.parts(own, automaton, np.full(t.num_states, mask), allowed)
            chosen[mask] = t.choice[states, view.joint(parts)]
        chosen[:, ~live] = -1
        return chosen


class TablePolicy(TeamPolicy):
    """Greedy in the robots' Q tables ``q[r, mask, automaton, own, k]``."""

    def __init__(self, view: RobotView, q_table: FloatArray) -> None:
        super().__init__(view)
        self.q_table = q_table

    def values(self, own: IntArray, automaton: IntArray, mask: IntArray) -> FloatArray:
        """Each robot's row of its table."""
        robots = np.arange(self.view.robots)[None, :]
        found: FloatArray = self.q_table[robots, mask[:, None], automaton[:, None], own]
        return found


class IndependentQLearner(Learner):
    """Independent tabular Q-learners, one per robot (see the module docstring)."""

    def __init__(
        self,
        view: RobotView,
        config: TrainConfig,
        rng: np.random.Generator,
        phi: FloatArray | None = None,
    ) -> None:
        self.view, self.config, self.rng, self.phi = view, config, rng, phi
        self.settings = config.q
        self.num_envs = self.settings.num_envs
        t = view.tables
        shape = (view.robots, t.all_sets + 1, max(t.num_automaton_states, 1), view.max_obs,
                 view.max_actions)  # fmt: skip
        self.q_table = np.full(shape, self.settings.initial_value)
        self._epsilon = self.settings.epsilon_start

    @property
    def epsilon(self) -> float:
        """The exploration rate of the last step."""
        return self._epsilon

    def train_step(self, env: Episodes, fraction: float) -> Step:
        """One step of every episode, each robot epsilon-greedy on its own; every robot's
        table updated toward the team's reward and its own view of what follows."""
        s, view = self.settings, self.view
        self._epsilon = epsilon_at(fraction, s.epsilon_start, s.epsilon_end, s.epsilon_decay)
        own, automaton, mask, state = view.own(env.observation), env.automaton, env.mask, env.state
        valid = view.own_valid(env.valid_actions())
        policy = TablePolicy(view, self.q_table)
        parts = policy.parts(own, automaton, mask, env.valid_actions())
        rows, n, k = valid.shape
        explore = self.rng.random((rows, n)) < self._epsilon
        randoms = random_valid(self.rng, valid.reshape(rows * n, k)).reshape(rows, n)
        parts = np.where(explore, randoms, parts)
        step = env.step(view.joint(parts))
        reward, gammas = transition_signal(
            step.reward, step.accepting, state, step.next_state, self.config, self.phi
        )
        after = policy.values(view.own(step.next_observation), step.next_automaton,
                              step.next_mask)  # fmt: skip
        next_valid = view.own_valid(step.next_valid)
        best = np.where(next_valid, after, -np.inf).max(axis=2)
        best = np.where(step.terminated[:, None] | ~next_valid.any(axis=2), 0.0, best)
        targets = reward[:, None] + gammas[:, None] * best
        alpha = s.alpha + (s.alpha_end - s.alpha) * min(1.0, fraction)
        robots = np.broadcast_to(np.arange(n)[None, :], (rows, n))
        index = (robots, np.broadcast_to(mask[:, None], (rows, n)),
                 np.broadcast_to(automaton[:, None], (rows, n)), own, parts)  # fmt: skip
        flat = np.ravel_multi_index(tuple(np.ravel(i) for i in index), self.q_table.shape)
        keys, inverse, counted = np.unique(flat, return_inverse=True, return_counts=True)
        means = np.bincount(inverse, weights=np.ravel(targets)) / counted
        table = self.q_table.reshape(-1)
        table[keys] += alpha * (means - table[keys])
        return step

    def state_dict(self) -> dict[str, Any]:
        """The tables and the random state."""
        return {"q_table": self.q_table.copy(), "rng": self.rng.bit_generator.state}

    def load_state_dict(self, saved: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`."""
        q_table = np.array(saved["q_table"])
        if q_table.shape != self.q_table.shape:
            raise ValueError(f"q_table: shape {q_table.shape}, not {self.q_table.shape}")
        self.q_table = q_table
        self.rng.bit_generator.state = saved["rng"]

    def policy(self) -> TablePolicy:
        """Every robot greedy in its current table."""
        return TablePolicy(self.view, self.q_table.copy())
