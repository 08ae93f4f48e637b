"""Deep Q-learning on the product of an MDP (Mnih et al., "Human-level control through deep
reinforcement learning", Nature 2015), optionally Double DQN (van Hasselt, Guez and Silver,
"Deep reinforcement learning with double Q-learning", AAAI 2016).

The network maps what the agent sees (the cell, the automaton state and the frontier mask, see
:class:`mitlc.learn.learners.nets.Encoder`) to a value per action (an MLP, after a CNN of each
image in the observation: :func:`mitlc.learn.learners.images.q_network`). Acting is
epsilon-greedy over the valid actions of each episode (the automaton state decides which epsilon
jumps exist). Every transition of the batch goes to a uniform replay memory; every
``train_every`` vector steps a minibatch moves the network toward ``r + gamma * Q_target(next,
best valid action)`` (0 after a terminal step; a truncated episode still bootstraps, as the
horizon is not part of the state) under the Huber loss, with the gradient norm clipped; the
target network copies the online one every ``target_update`` gradient steps. ``r`` and
``gamma`` are the learning signal of :func:`mitlc.learn.learners.base.learning_signal`
(discount per transition, optional shaping), times ``reward_scale``. With ``dqn.crm`` the
memory also gets the counterfactual transitions of each world step (Toro Icarte et al., JAIR
2022): every other product state it tells about on a finite product
(:mod:`mitlc.learn.learners.crm`), every other task state on an env
(:mod:`mitlc.learn.learners.crm_env`).
"""

from __future__ import annotations

import copy
from typing import Any

import numpy as np
import torch

from mitlc.learn.config import DQNConfig, TrainConfig
from mitlc.learn.device import resolve_device
from mitlc.learn.envs.vec import Step, Tables
from mitlc.learn.learners.base import (
    EnvShaping,
    Episodes,
    Learner,
    Policy,
    ProductShaping,
    Shaping,
    epsilon_at,
    learning_signal,
    random_valid,
    step_discounts,
    transition_signal,
)
from mitlc.learn.learners.crm import Batch, Counterfactuals
from mitlc.learn.learners.crm_env import EnvCounterfactuals
from mitlc.learn.learners.encoder import Encoder
from mitlc.learn.learners.images import q_network
from mitlc.learn.learners.nets import (
    Ring,
    anneal,
    bootstrap,
    build,
    check_indices,
    configure_torch,
    deep_state,
    gradient_step,
    greedy,
    huber,
    load_deep_state,
    optimistic,
    tensors,
    torch_seed,
)
from mitlc.worlds.model import BoolArray, IntArray


class DQNPolicy(Policy):
    """Greedy in a frozen copy of the Q network, over the valid actions."""

    def __init__(self, tables: Tables | None, encoder: Encoder, net: torch.nn.Module) -> None:
        self.tables, self.encoder, self.net = tables, encoder, net

    def values(self, observation: IntArray, automaton: IntArray, mask: IntArray) -> torch.Tensor:
        """The network's action values for these inputs."""
        with torch.no_grad():
            values: torch.Tensor = self.net(self.encoder(observation, automaton, mask))
        return values

    def act(self, env: Episodes) -> IntArray:
        """The greedy valid action of each episode."""
        return greedy(self.values(env.observation, env.automaton, env.mask), env.valid_actions())

    def choices(self, valid: BoolArray | None = None) -> IntArray:
        """``choices[mask, x]``: the product choice taken in state ``x`` with frontier ``mask``
        (-1 at the absorbing states) among the actions ``valid[mask, x]`` (default: every
        valid one), for :func:`mitlc.learn.evaluation.exact.policy_success`. The policy is
        memoryless over (mask, product state) on an MDP, where the observation is the cell."""
        t = self.tables
        assert t is not None, "exact evaluation needs the finite product"
        states = np.arange(t.num_states)
        cells = np.maximum(t.world_state, 0)
        automaton = self.encoder.automaton_of(states)
        chosen = np.full((t.all_sets + 1, t.num_states), -1, dtype=np.int64)
        for mask in range(t.all_sets + 1):
            masks = np.full(t.num_states, mask)
            allowed = t.valid if valid is None else valid[mask]
            best = greedy(self.values(cells, automaton, masks), allowed)
            chosen[mask] = t.choice[states, best]
        chosen[:, t.world_state < 0] = -1
        return chosen


class DQNLearner(Learner):
    """Epsilon-greedy DQN with replay and a target network (see the module docstring)."""

    def __init__(
        self,
        tables: Tables | None,
        config: TrainConfig,
        rng: np.random.Generator,
        shaping: Shaping | None = None,
        counterfactuals: Counterfactuals | EnvCounterfactuals | None = None,
        *,
        encoder: Encoder | None = None,
        num_actions: int | None = None,
    ) -> None:
        """``tables``: the finite product it learns on; ``None`` for any wrapped env
        (:class:`mitlc.learn.envs.envvec.VectorTask`), with the ``encoder`` of its observations
        (:meth:`Encoder.of_spaces`) and its ``num_actions``."""
        configure_torch()
        self.tables, self.config, self.rng, self.shaping = tables, config, rng, shaping
        self.counterfactuals = counterfactuals
        """With them (``dqn.crm``), every world step also stores the transitions of every
        other automaton state and frontier it tells about: of a finite product's tables
        (:mod:`mitlc.learn.learners.crm`), or of a wrapped env's task
        (:mod:`mitlc.learn.learners.crm_env`), shaped with the wrapper's potential of their
        own task states."""
        self.settings: DQNConfig = config.dqn
        s = self.settings
        self.num_envs = s.num_envs
        if tables is not None:
            encoder = encoder or Encoder(tables)
            num_actions = num_actions or tables.num_actions
        if encoder is None or num_actions is None:
            raise ValueError("a learner of any env needs the encoder and number of its actions")
        self.encoder, self.num_actions = encoder, num_actions
        self.device = encoder.device = resolve_device(config.device)
        self.net: torch.nn.Sequential = build(
            torch_seed(rng), lambda: q_network(self.encoder, s.hidden, s.layers, self.num_actions)
        ).to(self.device)
        if s.initial_value:
            optimistic(self.net[-1], s.initial_value * s.reward_scale)
        self.target = copy.deepcopy(self.net)
        self.target.requires_grad_(False)
        self.optimizer = torch.optim.Adam(self.net.parameters(), lr=s.lr)
        observation = self.encoder.observation_field
        self.replay = Ring(
            s.replay_size,
            {
                "observation": observation,
                "automaton": ((), np.int64),
                "mask": ((), np.int64),
                "action": ((), np.int64),
                "reward": ((), np.float32),
                "gamma": ((), np.float32),
                "terminated": ((), np.bool_),
                "next_observation": observation,
                "next_automaton": ((), np.int64),
                "next_mask": ((), np.int64),
                "next_valid": ((self.num_actions,), np.bool_),
            },
        )
        self.vector_steps = self.gradient_steps = 0
        self._epsilon = s.epsilon_start

    @property
    def epsilon(self) -> float:
        """The exploration rate of the last step."""
        return self._epsilon

    def _act(self, env: Episodes, automaton: IntArray) -> IntArray:
        """Epsilon-greedy valid actions (the network runs only when some episode exploits)."""
        valid = env.valid_actions()
        explore = self.rng.random(env.num_envs) < self._epsilon
        actions = random_valid(self.rng, valid)
        if not explore.all():
            with torch.no_grad():
                values = self.net(self.encoder(env.observation, automaton, env.mask))
            actions = np.where(explore, actions, greedy(values, valid))
        return actions

    def train_step(self, env: Episodes, fraction: float) -> Step:
        """One epsilon-greedy step of every episode; store it; learn every ``train_every``."""
        s = self.settings
        self._epsilon = epsilon_at(fraction, s.epsilon_start, s.epsilon_end, s.epsilon_decay)
        anneal(self.optimizer, s.lr, s.lr_end_ratio, fraction)
        state, observation, mask = env.state, env.observation, env.mask
        automaton = env.automaton
        actions = self._act(env, automaton)
        before = self.shaping.before(env) if self.shaping is not None else None
        step = env.step(actions)
        reward, gammas = learning_signal(step, before, self.config, self.shaping)
        entries = {
            "observation": observation,
            "automaton": automaton,
            "mask": mask,
            "action": actions,
            "reward": reward * s.reward_scale,
            "gamma": gammas,
            "terminated": step.terminated,
            "next_observation": step.next_observation,
            "next_automaton": step.next_automaton,
            "next_mask": step.next_mask,
            "next_valid": step.next_valid,
        }
        if isinstance(self.counterfactuals, EnvCounterfactuals):
            self.replay.add(self._env_entries(self.counterfactuals, entries, step))
        elif self.counterfactuals is not None:
            tables = self.tables
            assert tables is not None, "counterfactuals come from a finite product"
            told = (actions < tables.num_world_actions) & (tables.world_state[step.next_state] >= 0)
            entries = {name: values[~told] for name, values in entries.items()}
            self.replay.add(self._entries(self.counterfactuals.of(state, actions, step.next_state)))
        self.replay.add(entries)
        self.vector_steps += 1
        if self.replay.size >= s.warmup_steps and self.vector_steps % s.train_every == 0:
            self._learn()
        return step

    def _entries(self, batch: Batch) -> dict[str, Any]:
        """Replay entries of transitions between product states (an MDP: the observation is
        the cell)."""
        automaton = self.encoder.automaton_of(batch.state)
        reached = self.encoder.automaton_of(batch.next_state)
        phi = self.shaping.phi if isinstance(self.shaping, ProductShaping) else None
        reward, gammas = transition_signal(
            batch.reward, batch.accepting, batch.state, batch.next_state, self.config, phi
        )
        tables = self.tables
        assert tables is not None, "counterfactuals come from a finite product"
        world = tables.world_state
        return {
            "observation": np.maximum(world[batch.state], 0),
            "automaton": automaton,
            "mask": batch.mask,
            "action": batch.action,
            "reward": reward * self.settings.reward_scale,
            "gamma": gammas,
            "terminated": batch.terminated,
            "next_observation": np.maximum(world[batch.next_state], 0),
            "next_automaton": reached,
            "next_mask": batch.next_mask,
            "next_valid": tables.valid[batch.next_state],
        }

    def _env_entries(
        self, crm: EnvCounterfactuals, entries: dict[str, Any], step: Step
    ) -> dict[str, Any]:
        """Replay entries of the counterfactuals of a wrapped env's step (``entries``: its
        experienced ones): the same observations and actions, the task's part replaced."""
        if step.letter is None or step.env_reward is None or step.env_ended is None:
            raise ValueError("counterfactual experience needs the letters the episodes read")
        told = crm.tells(step.letter, step.env_ended)
        rows = crm.rows(entries["automaton"], entries["mask"], step.letter, step.env_reward,
                        told, self.rng)  # fmt: skip
        i = rows.source
        reward, gammas = rows.reward, step_discounts(rows.accepting, self.config.discount)
        if isinstance(self.shaping, EnvShaping):
            if step.distances is None or step.distances_left is None:
                raise ValueError("shaped counterfactuals need the distances the episodes report")
            reward = crm.shaped_reward(rows, gammas, step.distances_left, step.distances,
                                       self.shaping.scale)  # fmt: skip
        return {
            "observation": entries["observation"][i],
            "automaton": rows.q,
            "mask": rows.frontier,
            "action": entries["action"][i],
            "reward": reward * self.settings.reward_scale,
            "gamma": gammas,
            "terminated": rows.terminated,
            "next_observation": entries["next_observation"][i],
            "next_automaton": rows.next_q,
            "next_mask": rows.next_frontier,
            "next_valid": crm.valid(rows.next_q),
        }

    def _learn(self) -> None:
        """One gradient step on a replayed minibatch; copy to the target when it is due."""
        s = self.settings
        batch = self.replay.sample(self.rng, s.batch_size)
        inputs = self.encoder(batch["observation"], batch["automaton"], batch["mask"])
        after = self.encoder(batch["next_observation"], batch["next_automaton"], batch["next_mask"])
        action, reward, gamma, terminated, next_valid = tensors(
            batch, "action", "reward", "gamma", "terminated", "next_valid", device=self.device
        )
        with torch.no_grad():
            online_next = self.net(after) if s.double else None
            target_next = self.target(after)
            value = bootstrap(
                online_next if online_next is not None else target_next,
                target_next,
                next_valid,
                terminated,
                s.double,
            )
            goal = reward + gamma * value
        taken = self.net(inputs).gather(1, action[:, None]).squeeze(1)
        loss = huber(taken - goal, torch.ones_like(goal))
        gradient_step(loss, self.optimizer, list(self.net.parameters()), s.grad_clip)
        self.gradient_steps += 1
        if self.gradient_steps % s.target_update == 0:
            self.target.load_state_dict(self.net.state_dict())

    def state_dict(self) -> dict[str, Any]:
        """Networks, optimiser, replay memory, counters and the random state."""
        return deep_state(self)

    def load_state_dict(self, saved: dict[str, Any]) -> None:
        """Restore :meth:`state_dict` (``ValueError`` or ``RuntimeError`` if it does not fit)."""
        if self.tables is not None:
            check_indices(saved["replay"]["data"], self.tables, "replay.")
        load_deep_state(self, saved)

    def policy(self) -> DQNPolicy:
        """Greedy in a frozen copy of the current network."""
        net = copy.deepcopy(self.net)
        net.requires_grad_(False)
        return DQNPolicy(self.tables, self.encoder, net)
