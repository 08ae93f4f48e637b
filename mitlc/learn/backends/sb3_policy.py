"""The policy of a Stable-Baselines3 run for ``mitlc eval`` and ``mitlc plot``:
``load_learner(directory, setting)``.

The policy network alone is rebuilt from the run's settings (no algorithm, optimiser or replay
memory) and loaded from the latest checkpoint (:mod:`mitlc.learn.rundir.checkpoint`: safetensors, no
pickle). It acts greedily, as SB3's ``predict(obs, deterministic=True)`` does (the most
probable action, or the largest Q-value), among the valid actions, in mitlc's simulator of the
product (:class:`~mitlc.learn.envs.vec.VecProduct`, the model of the wrapped env the run learned
on),
fed the observation vector of :class:`mitlc.learn.backends.sb3.FlatObservation`. So an sb3 run is
evaluated as mitlc's learners are (:mod:`mitlc.learn.evaluation.evaluate`), and a memoryless policy
on an
MDP also gets its exact success probability (:meth:`SB3Policy.choices`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, cast

import numpy as np
import torch
from gymnasium import spaces

from mitlc.learn.backends.loaded import LoadedLearner
from mitlc.learn.backends.sb3 import algorithm, model_settings, wrapped_env
from mitlc.learn.backends.sb3_team import TeamLearner, load_team_learner
from mitlc.learn.envs.vec import Step
from mitlc.learn.learners.base import Episodes, Policy
from mitlc.learn.learners.encoder import Encoder, task_features
from mitlc.learn.learners.nets import build, configure_torch, greedy
from mitlc.learn.rundir import checkpoint
from mitlc.learn.rundir.files import RunError
from mitlc.learn.rundir.state import Mismatch, conform
from mitlc.learn.setting import Setting, is_team, task_vector_of
from mitlc.worlds.model import BoolArray, IntArray

CHUNK = 4096
"""Observations per forward pass when every product state is evaluated."""


class SB3Policy(Policy):
    """An SB3 policy acting greedily in a batch of :class:`~mitlc.learn.learners.base.Episodes` (see
    the module docstring); memoryless, so :meth:`choices` gives it for exact evaluation on an
    MDP."""

    def __init__(self, net: Any, encoder: Encoder, setting: Setting) -> None:
        self.net, self.encoder = net, encoder
        self.tables = setting.tables if isinstance(setting, Setting) else None
        self.dqn = setting.config.algo == "sb3-dqn"
        self.guide = setting.config.guide
        """The policy reads the way the shaping pulls, last in its input (the wrapper's flat
        observation with ``guide=True``)."""
        self.continuous = isinstance(getattr(net, "action_space", None), spaces.Box)
        """Continuous actions: the policy acts as SB3's ``predict(deterministic=True)`` (the
        mode of PPO's distribution clipped to the bounds; SAC's and TD3's actor, rescaled)."""

    def scores(self, x: torch.Tensor) -> torch.Tensor:
        """Q-values (DQN) or action logits of the observation vectors ``x``."""
        if self.dqn:
            values: torch.Tensor = self.net.q_net(x)
            return values
        logits: torch.Tensor = self.net.get_distribution(x).distribution.logits
        return logits

    def act(self, env: Episodes) -> IntArray:
        """The greedy valid action of each episode (continuous actions: SB3's ``predict``)."""
        x = self.encoder(env.observation, env.automaton, env.mask)
        if self.guide:
            way = getattr(env, "guide", None)
            if way is None:
                raise RunError("guide: the episodes do not show the way the policy reads")
            x = torch.cat([x, torch.as_tensor(way, dtype=x.dtype).reshape(len(x), -1)], dim=1)
        if self.continuous:
            actions, _ = self.net.predict(x.numpy(), deterministic=True)
            return cast("IntArray", actions)
        with torch.no_grad():
            return greedy(self.scores(x), env.valid_actions())

    def choices(self, valid: BoolArray | None = None) -> IntArray:
        """``choices[mask, x]``: the product choice taken in state ``x`` with frontier ``mask``
        (-1 at the absorbing states) among the actions ``valid[mask, x]`` (default: every
        valid one), for :func:`mitlc.learn.evaluation.exact.policy_success` (an MDP, where the
        observation is the cell)."""
        t = self.tables
        assert t is not None, "exact evaluation needs the finite product"
        cells = np.maximum(t.world_state, 0)
        chosen = np.full((t.all_sets + 1, t.num_states), -1, dtype=np.int64)
        for mask in range(t.all_sets + 1):
            for start in range(0, t.num_states, CHUNK):
                states = np.arange(start, min(start + CHUNK, t.num_states))
                x = self.encoder(
                    cells[states], self.encoder.automaton_of(states), np.full(len(states), mask)
                )
                with torch.no_grad():
                    allowed = t.valid[states] if valid is None else valid[mask, states]
                    best = greedy(self.scores(x), allowed)
                chosen[mask, states] = t.choice[states, best]
        chosen[:, t.world_state < 0] = -1
        return chosen


class SB3RecurrentPolicy(Policy):
    """A recurrent PPO policy acting greedily in a batch of
    :class:`~mitlc.learn.learners.base.Episodes`, its LSTM state carried over each episode and
    restarted with the next."""

    def __init__(self, net: Any, encoder: Encoder, setting: Setting) -> None:
        self.net, self.encoder = net, encoder
        self.reset(1)

    def reset(self, num_envs: int) -> None:
        """Fresh LSTM states for ``num_envs`` new episodes."""
        layers, _, hidden = self.net.lstm_hidden_state_shape
        self.lstm = (torch.zeros(layers, num_envs, hidden), torch.zeros(layers, num_envs, hidden))
        self.starts = torch.ones(num_envs)

    def act(self, env: Episodes) -> IntArray:
        """The greedy valid action of each episode."""
        x = self.encoder(env.observation, env.automaton, env.mask)
        with torch.no_grad():
            distribution, self.lstm = self.net.get_distribution(x, self.lstm, self.starts)
        self.starts = torch.zeros(env.num_envs)
        return greedy(distribution.distribution.logits, env.valid_actions())

    def observe(self, step: Step) -> None:
        """Episodes that ended restart their LSTM state on the next action."""
        self.starts[torch.from_numpy(step.done)] = 1.0


class SB3Learner(LoadedLearner):
    """A trained SB3 policy loaded for ``mitlc eval`` and ``mitlc plot`` (it does not train:
    :func:`train` does)."""

    def __init__(self, net: Any, setting: Setting) -> None:
        super().__init__(net, setting)
        # the layout of the wrapper's flat observation, which the network was trained on
        task = task_features(setting.automaton, setting.config.task_obs)
        if setting.tables is None:
            probe = task_vector_of(setting, 1, 0)
            space = probe.observation_space
            self.encoder = Encoder.of_spaces(
                space[probe.env_key], len(setting.automaton.states),
                setting.automaton.num_sets, probe.num_actions, scaled=False,
                task_features=task,
            )  # fmt: skip
        else:
            self.encoder = Encoder(
                setting.tables, num_automaton_states=len(setting.automaton.states),
                task_features=task,
            )  # fmt: skip

    def policy(self) -> Policy:
        """The greedy policy, recurrent or memoryless."""
        if self.setting.config.algo == "sb3-recurrent-ppo":
            return SB3RecurrentPolicy(self.net, self.encoder, self.setting)
        return SB3Policy(self.net, self.encoder, self.setting)


def load_learner(directory: Path, setting: Setting) -> SB3Learner | TeamLearner:
    """The policy of the sb3 run in ``directory`` (its latest checkpoint), rebuilt from the
    settings without its algorithm, optimiser or replay memory."""
    if is_team(setting.world):  # a PettingZoo team's shared policy
        return load_team_learner(directory, setting)
    configure_torch()
    cls, name = algorithm(setting.config.algo)
    env = wrapped_env(setting)
    kwargs = model_settings(setting.config, env)["policy_kwargs"]
    net = build(0, lambda: cls.policy_aliases[name](
        env.observation_space, env.action_space, lambda _: 0.0, **kwargs
    ))  # fmt: skip
    net.set_training_mode(False)
    loaded = checkpoint.load(directory)
    saved = loaded.state.get("model")
    template = {"policy": dict(net.state_dict())}
    try:
        if not isinstance(saved, dict) or "policy" not in saved:
            raise Mismatch("model", "no policy in the checkpoint")
        conform({"policy": saved["policy"]}, template, "model")
    except Mismatch as err:
        raise RunError(f"{loaded.files.get(err.kind, loaded.files['json'])}: {err}") from None
    learner = SB3Learner(net, setting)
    learner.load_state_dict(saved)
    return learner
