"""Parameter sharing for a team (``team: shared``, ``algo: dqn``): one DQN for every robot,
the robot's id in its input (see :mod:`mitlc.learn.learners.team`).

:class:`RobotSlots` shows each robot of each joint episode to mitlc's DQN
(:class:`mitlc.learn.learners.dqn.DQNLearner`) as an episode of its own: its observation is a
vector, the one-hot of what the robot sees (:class:`~mitlc.learn.learners.team.RobotView`)
followed by the one-hot of its index; the automaton state and frontier are the team task's;
its valid actions are its own. The DQN's actions of one joint episode's slots are put together
into the joint action and the joint episode steps once; every slot then learns from the team's
reward (shaped, where the run shapes, by the product's potential). The run sees the joint
steps, so its metrics and evaluation are the team's.
"""

from __future__ import annotations

from dataclasses import fields, replace
from typing import Any

import numpy as np
import torch

from mitlc.learn.config import TrainConfig
from mitlc.learn.envs.vec import Step
from mitlc.learn.learners.base import Episodes, Learner, Shaping
from mitlc.learn.learners.dqn import DQNLearner
from mitlc.learn.learners.encoder import Encoder
from mitlc.learn.learners.team import RobotView, TeamPolicy
from mitlc.worlds.model import BoolArray, FloatArray, IntArray


def features(view: RobotView, own: IntArray) -> FloatArray:
    """``x[i, r]``: robot ``r``'s input in episode ``i``: one-hot of what it sees, then one-hot
    of its index."""
    rows, n = own.shape
    x = np.zeros((rows, n, view.max_obs + n), dtype=np.float32)
    i, r = np.meshgrid(np.arange(rows), np.arange(n), indexing="ij")
    x[i, r, own] = 1.0
    x[i, r, view.max_obs + r] = 1.0
    found: FloatArray = x
    return found


class _Space:
    """The slots' observation space as :meth:`Encoder.of_spaces` reads a ``Box``."""

    def __init__(self, width: int) -> None:
        self.low, self.high = np.zeros(width), np.ones(width)


class RobotSlots:
    """The :class:`~mitlc.learn.learners.base.Episodes` of every robot of every joint
    episode (module docstring); :attr:`joint_step` is what the joint episodes did."""

    def __init__(self, env: Episodes, view: RobotView) -> None:
        self.env, self.view = env, view
        self.robots = view.robots
        self.num_envs = env.num_envs * view.robots
        self.joint_step: Step | None = None

    def _slots(self, values: Any) -> Any:
        return np.repeat(np.asarray(values), self.robots, axis=0)

    @property
    def observation(self) -> FloatArray:
        """Each slot's input vector."""
        own = features(self.view, self.view.own(self.env.observation))
        return own.reshape(self.num_envs, -1)

    @property
    def automaton(self) -> IntArray:
        """The team task's automaton state, per slot."""
        found: IntArray = self._slots(self.env.automaton)
        return found

    @property
    def mask(self) -> IntArray:
        """The team task's frontier, per slot."""
        found: IntArray = self._slots(self.env.mask)
        return found

    @property
    def state(self) -> IntArray:
        """The joint product state, per slot."""
        found: IntArray = self._slots(self.env.state)
        return found

    def valid_actions(self) -> BoolArray:
        """Each slot's robot's valid actions."""
        own: BoolArray = self.view.own_valid(self.env.valid_actions())
        return own.reshape(self.num_envs, -1)

    def step(self, actions: IntArray) -> Step:
        """Step the joint episodes with the slots' actions put together; the step per slot."""
        parts = np.asarray(actions, dtype=np.int64).reshape(self.env.num_envs, self.robots)
        joint = self.env.step(self.view.joint(parts))
        self.joint_step = joint
        expanded: dict[str, Any] = {}
        for item in fields(joint):
            value = getattr(joint, item.name)
            if isinstance(value, np.ndarray) and value.shape[:1] == (self.env.num_envs,):
                expanded[item.name] = self._slots(value)
        own = features(self.view, self.view.own(joint.next_observation))
        expanded["next_observation"] = own.reshape(self.num_envs, -1)
        expanded["next_valid"] = self.view.own_valid(joint.next_valid).reshape(self.num_envs, -1)
        return replace(joint, **expanded)


class SharedPolicy(TeamPolicy):
    """Every robot greedy in the shared network's values of its own input."""

    def __init__(self, view: RobotView, encoder: Encoder, net: torch.nn.Module) -> None:
        super().__init__(view)
        self.encoder, self.net = encoder, net

    def values(self, own: IntArray, automaton: IntArray, mask: IntArray) -> FloatArray:
        """The network's values of each robot's input."""
        rows, n = own.shape
        x = features(self.view, own).reshape(rows * n, -1)
        with torch.no_grad():
            values = self.net(self.encoder(x, np.repeat(automaton, n), np.repeat(mask, n)))  # type: ignore[arg-type]
        found: FloatArray = values.cpu().numpy().reshape(rows, n, -1).astype(np.float64)
        return found


class SharedDQNLearner(Learner):
    """One DQN for every robot (module docstring)."""

    def __init__(
        self,
        view: RobotView,
        config: TrainConfig,
        rng: np.random.Generator,
        shaping: Shaping | None = None,
        task_features: Any = None,
    ) -> None:
        self.view = view
        t = view.tables
        encoder = Encoder.of_spaces(
            _Space(view.max_obs + view.robots), max(t.num_automaton_states, 1), t.num_sets,
            view.max_actions, scaled=False, task_features=task_features,
        )  # fmt: skip
        self.dqn = DQNLearner(None, config, rng, shaping, encoder=encoder,
                              num_actions=view.max_actions)  # fmt: skip
        self.num_envs = config.dqn.num_envs

    @property
    def epsilon(self) -> float:
        """The exploration rate of the last step."""
        return self.dqn.epsilon

    def train_step(self, env: Episodes, fraction: float) -> Step:
        """One step of every joint episode, each robot's action the shared DQN's; the joint
        step."""
        slots = RobotSlots(env, self.view)
        self.dqn.train_step(slots, fraction)
        assert slots.joint_step is not None
        return slots.joint_step

    def state_dict(self) -> dict[str, Any]:
        """The DQN's state."""
        return self.dqn.state_dict()

    def load_state_dict(self, saved: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`."""
        self.dqn.load_state_dict(saved)

    def policy(self) -> SharedPolicy:
        """Every robot greedy in a frozen copy of the shared network."""
        policy = self.dqn.policy()
        return SharedPolicy(self.view, self.dqn.encoder, policy.net)
