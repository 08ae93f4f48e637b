"""Gymnasium environments that are not finite, as worlds to learn: an env world file (``env:``,
:mod:`mitlc.worlds.gym_world`) whose env has no transition table (CartPole, MountainCar, a
user's own registered simulator).

Such a world cannot be checked (there is no exact optimum), but it is learned from the command
line as a continuous world is: ``mitlc train`` wraps the env in :class:`mitlc.gym.TaskWrapper`
with the file's labels, task, rewards and horizon, and the learners read a vector of those
wrapped envs (:mod:`mitlc.learn.envs.envvec`). Its labels may use every form of
:mod:`mitlc.labels`: ``obs`` and ``decoded`` for a discrete observation, ``box`` and ``disc``
for a position in a ``Box`` observation, ``info`` for an info key, ``key`` for a part of a
``Dict`` observation, or a list of forms. They are checked against the env's observation space
and reported with their field paths.

The reward terms ``satisfied``, ``accept`` and ``violated`` are the task's and replace the
env's reward; ``move`` has no meaning here (an env's actions have no ``stay``) and must stay 0.

:mod:`mitlc.worlds.kinds.env` builds such a file into an :class:`EnvTask` (through the one
door, :func:`mitlc.worlds.door.open_world`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mitlc.worlds import gym_world
from mitlc.worlds.env_schema import Env
from mitlc.worlds.model import Rewards


@dataclass(frozen=True, slots=True)
class EnvTask:
    """A validated env world file whose env is learned through the task wrapper."""

    name: str
    env: Env
    """The registered id and the arguments the env is made with."""
    labels: dict[str, Any]
    """The labels as :mod:`mitlc.labels` declarations."""
    propositions: tuple[str, ...]
    spec: str
    spec_source: str
    horizon: int
    discount: float
    rewards: Rewards
    is_pomdp: bool = False
    """Unknown for an env: the learner named in the file or on the command line decides."""
    folder: Path | None = None
    """The world file's folder, from which no module is imported."""
    training: Mapping[str, Any] = field(default_factory=dict)
    """The file's ``training`` settings."""
    occupancy: Any = None
    """The file's ``occupancy:`` grid (a :class:`mitlc.labels.occupancy.Occupancy`; ``None``:
    the env's own where it has one), for the shaping's distances."""
    _spare: list[Any] = field(default_factory=list, compare=False, repr=False)
    """The env made to check the file (at most one), handed to the first :meth:`task_env`."""

    default_algo = "dqn"
    """The learner a run takes unless told: DQN reads any observation."""
    drawing = None
    """An env has no map to draw."""

    def keep(self, env: Any) -> None:
        """Keep ``env`` (made to check the file) for the first :meth:`task_env`."""
        self._spare[:] = [env]

    def task_env(self, automaton: Any, *, flatten: bool = False, **options: Any) -> Any:
        """A fresh env wrapped with the task (``automaton``: the task compiled once;
        ``flatten``: the wrapper's flat observation; ``options``: the wrapper's others)."""
        from mitlc.gym import TaskWrapper

        env = self._spare.pop() if self._spare else gym_world.make_env(self.env, self.folder)
        if self.occupancy is not None:
            options.setdefault("occupancy", self.occupancy)
        return TaskWrapper(
            env,
            automaton,
            self.labels,
            rewards=self.rewards,
            horizon=self.horizon,
            flatten=flatten,
            **options,
        )
