"""Tabular Q-learning on what the agent observes: any wrapped env with a discrete observation
(:class:`mitlc.learn.envs.envvec.VectorTask`), and a finite POMDP's product, whose agent does
not see its cell. The table is indexed by ``(frontier, observation, automaton state)`` in place
of the product's states, and the valid actions are the env's masks. On a POMDP its greedy
policy is memoryless, the policy class of the exact lower bound
:func:`mitlc.check.observed.observed_bound` less the step (Q-learning on observations: Jaakkola,
Singh and Jordan, NIPS 1994; Loch and Singh, ICML 1998). The update is
:class:`mitlc.learn.learners.qlearning.QLearner`'s (Watkins and Dayan, 1992), the one
definition of it.

On a wrapped env it takes counterfactual experience (``q.crm``; Toro Icarte et al., JAIR 2022):
each step the env took also updates the same observation, action and next observation in the
task's other states, with the monitor's step over them
(:class:`mitlc.learn.learners.crm_env.EnvCounterfactuals`, at most
:data:`~mitlc.learn.learners.crm_env.LIMIT` of them a step), in the same update as the
experienced step."""

from __future__ import annotations

import numpy as np

from mitlc.learn.config import TrainConfig
from mitlc.learn.envs.vec import Step
from mitlc.learn.learners.base import Episodes, Policy, epsilon_at, masked_argmax, random_valid
from mitlc.learn.learners.crm import Batch, concatenate
from mitlc.learn.learners.crm_env import EnvCounterfactuals
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
        counterfactuals: EnvCounterfactuals | None = None,
    ) -> None:
        """``phi``: on a finite POMDP's product, the potential of each product state (the
        task's shaping, :func:`mitlc.learn.learners.base.product_potential`), read from the
        true states the simulator keeps; ``None``: no shaping. ``counterfactuals``: a wrapped
        env's task states, for counterfactual experience (not with ``phi``)."""
        if counterfactuals is not None and phi is not None:
            raise ValueError("counterfactuals on observations take no product potential")
        self.tables = None  # type: ignore[assignment]
        self.config, self.rng, self.phi, self.counterfactuals = config, rng, phi, None
        self.env_counterfactuals = counterfactuals
        self.settings = config.q
        self.num_envs, self.num_q = self.settings.num_envs, num_q
        shape = (1 << num_sets, num_observations * num_q, num_actions)
        self.q_table = np.full(shape, self.settings.initial_value)
        self._epsilon = self.settings.epsilon_start

    def train_step(self, env: Episodes, fraction: float) -> Step:
        """One epsilon-greedy step of every episode and its update."""
        s = self.settings
        self._epsilon = epsilon_at(fraction, s.epsilon_start, s.epsilon_end, s.epsilon_decay)
        seen, automaton = np.array(env.observation, dtype=np.int64), np.array(env.automaton)
        state = seen * self.num_q + automaton
        mask, valid, before = np.array(env.mask), env.valid_actions(), env.state
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
        crm = self.env_counterfactuals
        if crm is None:
            self._update(batch, alpha, best, (before, step.next_state))
            return step
        extra, extra_best = self._counterfactual(crm, (seen, automaton, mask), actions, step)
        self._update(concatenate(batch, extra), alpha, np.concatenate([best, extra_best]))
        return step

    def _counterfactual(
        self,
        crm: EnvCounterfactuals,
        before: tuple[IntArray, IntArray, IntArray],
        actions: IntArray,
        step: Step,
    ) -> tuple[Batch, FloatArray]:
        """The counterfactual transitions of a step (``before``: the episodes' observation,
        automaton state and frontier before it) and the best value of each one's next state."""
        observation, automaton, frontier = before
        if step.letter is None or step.env_reward is None or step.env_ended is None:
            raise ValueError("counterfactual experience needs the letters the episodes read")
        told = crm.tells(step.letter, step.env_ended)
        rows = crm.rows(automaton, frontier, step.letter, step.env_reward, told, self.rng)
        i = rows.source
        seen = observation[i] * self.num_q
        reached = np.asarray(step.next_observation, dtype=np.int64)[i] * self.num_q
        batch = Batch(rows.frontier, seen + rows.q, actions[i], rows.reward, rows.accepting,
                      rows.terminated, rows.next_frontier, reached + rows.next_q)  # fmt: skip
        return batch, self._best(rows.next_frontier, batch.next_state, crm.valid(rows.next_q))

    def _best(self, mask: IntArray, state: IntArray, valid: BoolArray) -> FloatArray:
        best: FloatArray = np.where(valid, self.q_table[mask, state], -np.inf).max(axis=1)
        return best

    def policy(self) -> ObservedTabularPolicy:  # type: ignore[override]
        """Greedy in the current table."""
        return ObservedTabularPolicy(self.q_table.copy(), self.num_q)
