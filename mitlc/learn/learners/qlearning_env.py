"""Tabular Q-learning on what the agent observes: any wrapped env with a discrete observation
(:class:`mitlc.learn.envs.envvec.VectorTask`), and a finite POMDP's product, whose agent does
not see its cell. The table is indexed by ``(frontier, observation, automaton state)`` in place
of the product's states, and the valid actions are the env's masks. On a POMDP its greedy
policy is memoryless, the policy class of the exact lower bound
:func:`mitlc.check.observed.observed_bound` less the step (Q-learning on observations: Jaakkola,
Singh and Jordan, NIPS 1994; Loch and Singh, ICML 1998). The update is
:class:`mitlc.learn.learners.qlearning.QLearner`'s (Watkins and Dayan, 1992), the one
definition of it."""

from __future__ import annotations

import numpy as np

from mitlc.learn.config import TrainConfig
from mitlc.learn.envs.vec import Step
from mitlc.learn.learners.base import Episodes, Policy, epsilon_at, masked_argmax, random_valid
from mitlc.learn.learners.crm import Batch
from mitlc.learn.learners.qlearning import QLearner
from mitlc.worlds.model import BoolArray, FloatArray, IntArray


class ObservedTabularPolicy(Policy):
    """Greedy in a table over ``(frontier, observation * Q + automaton state)``."""

    def __init__(self, q_table: FloatArray, num_q: int) -> None:
        self.q_table, self.num_q = q_table, num_q

    def act(self, env: Episodes) -> IntArray:
        """The greedy valid action of each episode."""
        index = np.asarray(env.observation, dtype=np.int64) * self.num_q + env.automaton
        return masked_argmax(self.q_table[env.mask, index], env.valid_actions())


class ObservedQLearner(QLearner):
    """Epsilon-greedy tabular Q-learning over what the agent observes (module docstring)."""

    def __init__(
        self,
        num_observations: int,
        num_q: int,
        num_sets: int,
        num_actions: int,
        config: TrainConfig,
        rng: np.random.Generator,
        phi: FloatArray | None = None,
    ) -> None:
        """``phi``: on a finite POMDP's product, the potential of each product state (the
        task's shaping, :func:`mitlc.learn.learners.base.product_potential`), read from the
        true states the simulator keeps; ``None``: no shaping."""
        self.tables = None  # type: ignore[assignment]
        self.config, self.rng, self.phi, self.counterfactuals = config, rng, phi, None
        self.settings = config.q
        self.num_envs, self.num_q = self.settings.num_envs, num_q
        shape = (1 << num_sets, num_observations * num_q, num_actions)
        self.q_table = np.full(shape, self.settings.initial_value)
        self._epsilon = self.settings.epsilon_start

    def train_step(self, env: Episodes, fraction: float) -> Step:
        """One epsilon-greedy step of every episode and its update."""
        s = self.settings
        self._epsilon = epsilon_at(fraction, s.epsilon_start, s.epsilon_end, s.epsilon_decay)
        state = np.asarray(env.observation, dtype=np.int64) * self.num_q + env.automaton
        mask, valid, before = env.mask, env.valid_actions(), env.state
        greedy = masked_argmax(self.q_table[mask, state], valid)
        explore = self.rng.random(env.num_envs) < self._epsilon
        actions = np.where(explore, random_valid(self.rng, valid), greedy)
        step = env.step(actions)
        after = np.asarray(step.next_observation, dtype=np.int64) * self.num_q
        after = after + step.next_automaton
        batch = Batch(mask, state, actions, step.reward, step.accepting, step.terminated,
                      step.next_mask, after)  # fmt: skip
        alpha = s.alpha + (s.alpha_end - s.alpha) * min(1.0, fraction)
        best = self._best(step.next_mask, after, step.next_valid)
        self._update(batch, alpha, best, (before, step.next_state))
        return step

    def _best(self, mask: IntArray, state: IntArray, valid: BoolArray) -> FloatArray:
        best: FloatArray = np.where(valid, self.q_table[mask, state], -np.inf).max(axis=1)
        return best

    def policy(self) -> ObservedTabularPolicy:  # type: ignore[override]
        """Greedy in the current table."""
        return ObservedTabularPolicy(self.q_table.copy(), self.num_q)
