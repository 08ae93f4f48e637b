"""A continuous world (:class:`~mitlc.worlds.plane.PlaneWorld`) as a gymnasium environment, its
labels, and the two joined with the world's task.

* :class:`PlaneEnv` is the world alone, with no task (the semantics: :mod:`mitlc.worlds.plane`):
  a ``Box`` observation of the position (or of a noisy reading of it), ``Discrete`` actions,
  ``info["position"]`` the true position, ``reward.move`` for every action but ``stay``, and no
  end of its own. ``reset(options={"position": [x, y]})`` starts at a given free point.
* :class:`PositionLabels` are the world's declared labels (compiled by :mod:`mitlc.labels`, its
  ``box`` and ``disc`` forms) read at ``info["position"]``: labels are observable, so even a
  POMDP's letters are those of the true position. Nothing in :mod:`mitlc.labels` changes: the
  compiled forms are applied to the position instead of the observation.
* :func:`make_plane_env` is ``TaskWrapper(PlaneEnv(world), world.spec, PositionLabels.of(world),
  rewards=world.rewards, horizon=world.horizon, reward_mode="add")``.

This module imports gymnasium; :mod:`mitlc.worlds` does not import it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import numpy.typing as npt
from gymnasium import spaces

from mitlc.automata import translate
from mitlc.gym.wrapper import TaskWrapper
from mitlc.labels import Labeller, LetterReader, compile_labels
from mitlc.labels.distance import distances
from mitlc.labels.geodesic import Geodesic
from mitlc.labels.values import Moment
from mitlc.syntax import parse
from mitlc.worlds.plane import PlaneWorld, Vec

Observation = npt.NDArray[np.float32]


class PlaneEnv(gym.Env[Any, Any]):
    """A plane world as a gymnasium environment (see the module docstring)."""

    metadata: dict[str, Any] = {"render_modes": ["ansi"], "render_fps": 4}  # noqa: RUF012
    observation_space: spaces.Box
    action_space: spaces.Discrete

    def __init__(self, world: PlaneWorld, *, render_mode: str | None = None) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode {render_mode!r} is not one of 'ansi' or None")
        self.world, self.render_mode = world, render_mode
        high = np.array([world.width, world.height], dtype=np.float32)
        self.observation_space = spaces.Box(np.zeros(2, dtype=np.float32), high, dtype=np.float32)
        self.action_space = spaces.Discrete(world.num_actions)
        self._moves = [m is not None for m in world.moves]
        self._move = world.rewards.move
        self._p: Vec = (0.0, 0.0)

    @property
    def position(self) -> Vec:
        """The robot's true position."""
        return self._p

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Observation, dict[str, Any]]:
        """Start at the world's start (a draw from a start region), or at
        ``options["position"]``, which must be free."""
        super().reset(seed=seed)
        if options and options.get("position") is not None:
            x, y = (float(v) for v in options["position"])
            if not self.world.free((x, y)):
                raise ValueError(f"options['position'] ({x}, {y}) is not a free point of the room")
            self._p = (x, y)
        else:
            self._p = self.world.sample_start(self.np_random)
        return self._observe(), self._info()

    def step(self, action: int) -> tuple[Observation, float, bool, bool, dict[str, Any]]:
        """One action of the world."""
        a = int(action)
        if not 0 <= a < len(self._moves):
            raise ValueError(f"action {action!r} is not in {self.action_space}")
        self._p = self.world.move(self._p, a, self.np_random)
        reward = self._move if self._moves[a] else 0.0
        return self._observe(), reward, False, False, self._info()

    def state_dict(self) -> dict[str, Any]:
        """The robot's position and the env's random state (for checkpoints)."""
        return {"position": [float(v) for v in self._p], "rng": self.np_random.bit_generator.state}

    def load_state_dict(self, saved: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`."""
        x, y = (float(v) for v in saved["position"])
        self._p = (x, y)
        self.np_random.bit_generator.state = saved["rng"]

    def render(self) -> str | None:
        """With ``render_mode="ansi"``: the position and the labels holding there."""
        if self.render_mode != "ansi":
            return None
        x, y = self._p
        labels = self.world.labels.items()
        here = [p for p, regions in labels if any(r.contains(self._p) for r in regions)]
        return f"({x:.3f}, {y:.3f})" + (f" in {', '.join(sorted(here))}" if here else "")

    def _observe(self) -> Observation:
        return np.asarray(self.world.sense(self._p, self.np_random), dtype=np.float32)

    def _info(self) -> dict[str, Any]:
        return {"position": np.array(self._p, dtype=np.float64)}


@dataclass(frozen=True, slots=True)
class PositionLetters:
    """A letter reader applied to ``info["position"]`` in place of the observation."""

    read: LetterReader

    def __call__(self, obs: Any, info: dict[str, Any]) -> int:
        """The letter of the true position."""
        return self.read(info["position"], info)


@dataclass(frozen=True, slots=True)
class PositionLabels:
    """Compiled declarative labels read at the true position ``info["position"]``."""

    labeller: Labeller

    @staticmethod
    def of(world: PlaneWorld) -> PositionLabels:
        """The labels of ``world`` (its ``box`` and ``disc`` regions)."""
        space = spaces.Box(-np.inf, np.inf, shape=(2,), dtype=np.float64)
        return PositionLabels(compile_labels(world.label_declarations(), space))

    @property
    def propositions(self) -> tuple[str, ...]:
        """The declared propositions."""
        return self.labeller.propositions

    def __call__(self, obs: Any, info: Mapping[str, Any]) -> frozenset[str]:
        """The propositions true at the true position."""
        return self.labeller(info["position"], info)

    def letter_reader(self, propositions: Sequence[str]) -> PositionLetters:
        """Letters over ``propositions`` (each must be declared)."""
        return PositionLetters(self.labeller.letter_reader(propositions))

    def distances(
        self,
        propositions: Sequence[str],
        obs: Any,
        info: Mapping[str, Any],
        moment: Moment,
        geodesic: Geodesic | None = None,
    ) -> list[float | None]:
        """How far the true position is from each region (:mod:`mitlc.labels.distance`;
        around the obstacles with ``geodesic``)."""
        return distances(self.labeller, propositions, info["position"], info, moment, geodesic)


def plane_task(
    world: PlaneWorld,
    *,
    flatten: bool = False,
    render_mode: str | None = None,
    automaton: Any = None,
    **options: Any,
) -> TaskWrapper:
    """``world`` with its task: ``TaskWrapper(PlaneEnv(world), world.spec, its labels,
    rewards=world.rewards, horizon=world.horizon, reward_mode="add")``; ``automaton``, when
    given, is the task's (compiled once for many envs)."""
    return TaskWrapper(
        PlaneEnv(world, render_mode=render_mode),
        automaton if automaton is not None else translate(parse(world.spec, world.spec_source)),
        PositionLabels.of(world),
        rewards=world.rewards,
        horizon=world.horizon,
        reward_mode="add",
        flatten=flatten,
        **options,
    )


def make_plane_env(
    path: str | Path,
    spec: str | None = None,
    *,
    flatten: bool = False,
    render_mode: str | None = None,
) -> TaskWrapper:
    """The plane world file at ``path`` with its task (or ``spec``, a formula's text, in its
    place) as a :class:`~mitlc.gym.TaskWrapper`; a :class:`mitlc.worlds.WorldError` if the file
    is bad."""
    from mitlc.worlds.door import load_plane_world

    return plane_task(load_plane_world(path, spec), flatten=flatten, render_mode=render_mode)


__all__ = ["PlaneEnv", "PositionLabels", "PositionLetters", "make_plane_env", "plane_task"]
