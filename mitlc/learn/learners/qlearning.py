"""Tabular Q-learning (Watkins and Dayan, Machine Learning 8, 1992) on the product, vectorised
over a batch of episodes.

The table is indexed by ``(frontier mask, product state, action)``: the product state holds the
world state and the automaton state (with its clocks), and the frontier of acceptance sets seen
in this round decides which marks still pay, so together they are a Markov state of the
rewarded process. Each vector step updates the pair every episode visited toward
``r + gamma * max_a' Q(next, a')`` (0 after a terminal step; a truncated episode still
bootstraps, as the horizon is not part of the state). When several episodes take the same
action in the same state at once, the pair moves once, toward the mean of their targets.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from mitlc.learn.config import QConfig, TrainConfig
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
from mitlc.learn.learners.crm import Batch, Counterfactuals, concatenate, select
from mitlc.worlds.model import BoolArray, FloatArray, IntArray


class TabularPolicy(Policy):
    """Greedy in a Q table: ``argmax_a Q[mask, state, a]`` over the valid actions."""

    def __init__(self, tables: Tables, q_table: FloatArray) -> None:
        self.tables, self.q_table = tables, q_table

    def act(self, env: Episodes) -> IntArray:
        """The greedy action of each episode."""
        return masked_argmax(self.q_table[env.mask, env.state], env.valid_actions())

    def choices(self, valid: BoolArray | None = None) -> IntArray:
        """``choices[mask, x]``: the product choice the policy takes (-1 where none), among
        the actions ``valid[mask, x]`` (default: every valid one)."""
        allowed = np.broadcast_to(self.tables.valid, self.q_table.shape) if valid is None else valid
        best = masked_argmax(
            self.q_table.reshape(-1, self.q_table.shape[-1]),
            allowed.reshape(-1, self.q_table.shape[-1]),
        ).reshape(self.q_table.shape[:2])
        states = np.arange(self.tables.num_states)
        chosen: IntArray = self.tables.choice[states[None, :], best]
        return chosen


class QLearner(Learner):
    """Epsilon-greedy tabular Q-learning (see the module docstring)."""

    def __init__(
        self,
        tables: Tables,
        config: TrainConfig,
        rng: np.random.Generator,
        phi: FloatArray | None = None,
        counterfactuals: Counterfactuals | None = None,
    ) -> None:
        self.tables, self.config, self.rng, self.phi = tables, config, rng, phi
        self.counterfactuals = counterfactuals
        """With them (``q.crm``), counterfactual experience (:mod:`mitlc.learn.learners.crm`)."""
        self.settings: QConfig = config.q
        self.num_envs = self.settings.num_envs
        shape = (tables.all_sets + 1, tables.num_states, tables.num_actions)
        self.q_table = np.full(shape, self.settings.initial_value)
        self._epsilon = self.settings.epsilon_start

    @property
    def epsilon(self) -> float:
        """The exploration rate of the last step."""
        return self._epsilon

    def train_step(self, env: Episodes, fraction: float) -> Step:
        """One epsilon-greedy step of every episode and its update (with counterfactual
        experience on: the update of every automaton state and frontier the world steps
        tell about, :mod:`mitlc.learn.learners.crm`)."""
        s = self.settings
        self._epsilon = epsilon_at(fraction, s.epsilon_start, s.epsilon_end, s.epsilon_decay)
        state, mask = env.state, env.mask
        valid = env.valid_actions()  # a shield's, where the run has one
        greedy = masked_argmax(self.q_table[mask, state], valid)
        explore = self.rng.random(env.num_envs) < self._epsilon
        actions = np.where(explore, random_valid(self.rng, valid), greedy)
        step = env.step(actions)
        batch = Batch(
            mask, state, actions, step.reward, step.accepting, step.terminated, step.next_mask,
            step.next_state,
        )  # fmt: skip
        if self.counterfactuals is not None:
            extra = self.counterfactuals.of(state, actions, step.next_state)
            world = actions < self.tables.num_world_actions
            told = world & (self.tables.world_state[step.next_state] >= 0)
            batch = concatenate(select(batch, ~told), extra)
        alpha = s.alpha + (s.alpha_end - s.alpha) * min(1.0, fraction)
        self._update(batch, alpha, self._values(batch.next_mask, batch.next_state))
        return step

    def _update(
        self,
        batch: Batch,
        alpha: float,
        after: FloatArray,
        states: tuple[IntArray, IntArray] | None = None,
    ) -> None:
        """Move each (mask, state, action) of ``batch`` toward the mean of its targets
        ``r + gamma * max_a' Q(next)`` (``after``; 0 after a terminal step). ``states``: the
        product states before and after, which the shaping reads, where the table's rows are
        not product states."""
        before, reached = (batch.state, batch.next_state) if states is None else states
        reward, gammas = transition_signal(
            batch.reward, batch.accepting, before, reached, self.config, self.phi
        )
        best = np.where(batch.terminated, 0.0, after)
        flat = np.ravel_multi_index((batch.mask, batch.state, batch.action), self.q_table.shape)
        table = self.q_table.reshape(-1)
        if table.size <= 4 * len(flat):  # many updates (counterfactuals): count in place
            counts = np.bincount(flat, minlength=table.size)
            sums = np.bincount(flat, weights=reward + gammas * best, minlength=table.size)
            keys = np.flatnonzero(counts)
            targets = sums[keys] / counts[keys]
        else:
            keys, inverse, counted = np.unique(flat, return_inverse=True, return_counts=True)
            targets = np.bincount(inverse, weights=reward + gammas * best) / counted
        table[keys] += alpha * (targets - table[keys])

    def _values(self, mask: IntArray, state: IntArray) -> FloatArray:
        """``max_a Q[mask, state, a]`` over the valid actions: gathered row by row, or, for a
        batch about as large as the table (counterfactuals), from the whole table at once."""
        if self.q_table.size <= 4 * len(state) * self.q_table.shape[-1]:
            valid = self.tables.valid[None, :, :]
            values: FloatArray = np.where(valid, self.q_table, -np.inf).max(axis=-1)
            found: FloatArray = values[mask, state]
            return found
        after = self.q_table[mask, state]
        best: FloatArray = np.where(self.tables.valid[state], after, -np.inf).max(axis=1)
        return best

    def state_dict(self) -> dict[str, Any]:
        """The table and the random state."""
        return {"q_table": self.q_table.copy(), "rng": self.rng.bit_generator.state}

    def load_state_dict(self, saved: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`."""
        self.q_table = np.array(saved["q_table"])
        self.rng.bit_generator.state = saved["rng"]

    def policy(self) -> TabularPolicy:
        """Greedy in the current table."""
        return TabularPolicy(self.tables, self.q_table.copy())
