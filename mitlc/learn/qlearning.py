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

from mitlc.learn.base import (
    Learner,
    Policy,
    epsilon_at,
    learning_signal,
    masked_argmax,
    random_valid,
)
from mitlc.learn.config import QConfig, TrainConfig
from mitlc.learn.vec import Step, Tables, VecProduct
from mitlc.worlds.model import FloatArray, IntArray


class TabularPolicy(Policy):
    """Greedy in a Q table: ``argmax_a Q[mask, state, a]`` over the valid actions."""

    def __init__(self, tables: Tables, q_table: FloatArray) -> None:
        self.tables, self.q_table = tables, q_table

    def act(self, env: VecProduct) -> IntArray:
        """The greedy action of each episode."""
        return masked_argmax(self.q_table[env.mask, env.state], self.tables.valid[env.state])

    def choices(self) -> IntArray:
        """``choices[mask, x]``: the product choice the policy takes (-1 where none)."""
        best = masked_argmax(
            self.q_table.reshape(-1, self.q_table.shape[-1]),
            np.tile(self.tables.valid, (self.q_table.shape[0], 1)),
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
    ) -> None:
        self.tables, self.config, self.rng, self.phi = tables, config, rng, phi
        self.settings: QConfig = config.q
        self.num_envs = self.settings.num_envs
        shape = (tables.all_sets + 1, tables.num_states, tables.num_actions)
        self.q_table = np.full(shape, self.settings.initial_value)
        self._epsilon = self.settings.epsilon_start

    @property
    def epsilon(self) -> float:
        """The exploration rate of the last step."""
        return self._epsilon

    def train_step(self, env: VecProduct, fraction: float) -> Step:
        """One epsilon-greedy step of every episode and its update."""
        s = self.settings
        self._epsilon = epsilon_at(fraction, s.epsilon_start, s.epsilon_end, s.epsilon_decay)
        state, mask = env.state, env.mask
        valid = self.tables.valid[state]
        greedy = masked_argmax(self.q_table[mask, state], valid)
        explore = self.rng.random(env.num_envs) < self._epsilon
        actions = np.where(explore, random_valid(self.rng, valid), greedy)
        step = env.step(actions)
        reward, gammas = learning_signal(step, state, self.config, self.phi)
        after = self.q_table[step.next_mask, step.next_state]
        best = np.where(self.tables.valid[step.next_state], after, -np.inf).max(axis=1)
        best = np.where(step.terminated, 0.0, best)
        alpha = s.alpha + (s.alpha_end - s.alpha) * min(1.0, fraction)
        flat = np.ravel_multi_index((mask, state, actions), self.q_table.shape)
        keys, inverse, counts = np.unique(flat, return_inverse=True, return_counts=True)
        targets = np.bincount(inverse, weights=reward + gammas * best) / counts
        table = self.q_table.reshape(-1)
        table[keys] += alpha * (targets - table[keys])
        return step

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
