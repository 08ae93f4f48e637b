"""The task wrapper's parts that are not the task's rules: its observation
(:class:`TaskObservation`; the task's own part of it, :class:`TaskPart`), the env's ``info``
as data a checkpoint holds (:func:`data_only`), and the env's own time limit
(:func:`time_limit`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np
import numpy.typing as npt
from gymnasium import spaces

from mitlc.automata.clocks import ClockView
from mitlc.gym.observations import Readable, readable


@dataclass(frozen=True, slots=True)
class TaskPart:
    """The task's state as parts of a ``Dict`` observation: ``automaton`` (a ``Discrete`` of
    the ``num_q`` states), or, with a clock view, ``location`` (a ``Discrete`` of the
    locations) and ``clocks`` (a ``Box`` in [0, 1], each clock over its bound); then
    ``frontier`` (a ``Discrete`` of the ``2 ** num_sets`` masks)."""

    spaces: dict[str, spaces.Space[Any]]
    clocks: ClockView | None = None
    features: npt.NDArray[np.float32] | None = None
    """The clock view's features, a row per automaton state."""

    @staticmethod
    def of(num_q: int, num_sets: int, clocks: ClockView | None = None) -> TaskPart:
        """The parts of a task with ``num_q`` states and ``num_sets`` acceptance sets."""
        task: dict[str, spaces.Space[Any]] = {"automaton": spaces.Discrete(num_q)}
        if clocks is not None:
            size = (clocks.num_clocks,)
            task = {
                "location": spaces.Discrete(clocks.num_locations),
                "clocks": spaces.Box(0.0, 1.0, size, dtype=np.float32),
            }
        task["frontier"] = spaces.Discrete(1 << num_sets)
        features = None if clocks is None else clocks.features()
        return TaskPart(task, clocks, features)

    def observe(self, q: int, frontier: int) -> dict[str, Any]:
        """The parts in automaton state ``q`` with ``frontier``."""
        if self.clocks is None:
            return {"automaton": q, "frontier": frontier}
        clocks = self.features[q, self.clocks.num_locations :]  # type: ignore[index]
        location = self.clocks.location[q]
        return {"location": location, "clocks": clocks.copy(), "frontier": frontier}


@dataclass(frozen=True, slots=True)
class TaskObservation:
    """The wrapper's observation of the env's observation, the task's state and the frontier.

    The task's state is the digital automaton's state (``task_obs="state"``) or its clock view
    (``"clocks"``: the T-LDGBA's location and clocks, :mod:`mitlc.automata.clocks`). Without
    ``flatten`` a ``Dict``: the env's part named ``env_key``, then ``automaton`` (a
    ``Discrete`` of the states), or ``location`` (a ``Discrete`` of the locations) and
    ``clocks`` (a ``Box`` in [0, 1], each clock over its bound), then ``frontier``. With
    ``flatten``, one float32 ``Box``: the readable part of the env's observation flattened
    (:func:`mitlc.gym.observations.readable`: ``gymnasium.spaces.flatten``'s layout, text and
    other parts without numbers left out), the task's features (a one-hot of the state, or
    :meth:`~mitlc.automata.clocks.ClockView.features`) and the ``num_sets`` frontier bits."""

    env_space: spaces.Space[Any]
    env_key: str
    num_q: int
    num_sets: int
    flatten: bool
    space: spaces.Space[Any]
    env_dim: int = 0
    readable: Readable | None = None
    """The readable part of the env's observation (with ``flatten``)."""
    clocks: ClockView | None = None
    features: npt.NDArray[np.float32] | None = None
    """The clock view's features, a row per automaton state."""
    guide: int = 0
    """The size of the way shown (``guide``: a ``Box`` in [-1, 1], last; 0: none)."""

    @staticmethod
    def of(
        env_space: spaces.Space[Any],
        env_key: str,
        num_q: int,
        num_sets: int,
        flatten: bool,
        clocks: ClockView | None = None,
        guide: int = 0,
    ) -> TaskObservation:
        """The observation of an env with ``env_space`` (an
        :class:`~mitlc.gym.observations.UnreadableObservation`, a ``ValueError``, when it is
        flattened and has nothing a learner can read); ``clocks``: show the task's state by
        its clock view; ``guide``: the size of the way shown (0: none)."""
        features = None if clocks is None else clocks.features()
        if not flatten:
            task = TaskPart.of(num_q, num_sets, clocks).spaces
            if guide:
                task["guide"] = spaces.Box(-1.0, 1.0, (guide,), dtype=np.float32)
            space = spaces.Dict({env_key: env_space, **task})
            return TaskObservation(
                env_space, env_key, num_q, num_sets, False, space, clocks=clocks,
                features=features, guide=guide,
            )  # fmt: skip
        part = readable(env_space)
        flat = part.space
        width = (num_q if features is None else features.shape[1]) + num_sets
        low = np.concatenate([flat.low, np.zeros(width), -np.ones(guide)]).astype(np.float32)
        high = np.concatenate([flat.high, np.ones(width + guide)]).astype(np.float32)
        box = spaces.Box(low, high, dtype=np.float32)
        return TaskObservation(
            env_space, env_key, num_q, num_sets, True, box, part.size, part, clocks, features,
            guide,
        )  # fmt: skip

    def observe(
        self, obs: Any, q: int, frontier: int, way: npt.NDArray[np.float64] | None = None
    ) -> Any:
        """The observation of the env's ``obs`` in automaton state ``q`` with ``frontier``
        (and, where the way is shown, ``way``)."""
        if not self.flatten:
            if self.clocks is None:
                found = {self.env_key: obs, "automaton": q, "frontier": frontier}
            else:
                clocks = self.features[q, self.clocks.num_locations :]  # type: ignore[index]
                location = self.clocks.location[q]
                found = {self.env_key: obs, "location": location, "clocks": clocks.copy(),
                         "frontier": frontier}  # fmt: skip
            if self.guide:
                found["guide"] = self._way(way)
            return found
        dim = self.env_dim
        task = self.num_q if self.features is None else self.features.shape[1]
        flat = np.zeros(dim + task + self.num_sets + self.guide, dtype=np.float32)
        assert self.readable is not None, "a flat observation has its readable part"
        self.readable.write(obs, flat[:dim])
        if self.features is None:
            flat[dim + q] = 1.0
        else:
            flat[dim : dim + task] = self.features[q]
        base = dim + task
        for k in range(self.num_sets):
            if frontier >> k & 1:
                flat[base + k] = 1.0
        if self.guide:
            flat[base + self.num_sets :] = self._way(way)
        return flat

    def _way(self, way: npt.NDArray[np.float64] | None) -> npt.NDArray[np.float32]:
        if way is None:
            return np.zeros(self.guide, dtype=np.float32)
        return np.asarray(way, dtype=np.float32)


def data_only(value: Any) -> Any:
    """``value`` with only what a checkpoint holds (numbers, strings, ``None``, numpy arrays of
    numbers, and lists, tuples and string-keyed dicts of them); anything else is left out
    (:data:`_LEFT_OUT` at the top)."""
    if value is None or isinstance(value, bool | int | float | str | np.generic):
        return value
    if isinstance(value, np.ndarray):
        return _LEFT_OUT if value.dtype.hasobject else value
    if isinstance(value, list | tuple):
        items = [data_only(v) for v in value]
        return _LEFT_OUT if any(v is _LEFT_OUT for v in items) else type(value)(items)
    if isinstance(value, dict):
        kept = {k: data_only(v) for k, v in value.items() if isinstance(k, str)}
        return {k: v for k, v in kept.items() if v is not _LEFT_OUT and not k.startswith("__")}
    return _LEFT_OUT


_LEFT_OUT = object()


def time_limit(env: gym.Env[Any, Any]) -> int | None:
    """The smallest ``TimeLimit`` among ``env``'s wrappers (read from the wrappers themselves:
    asking for ``env.spec`` would cache it before ``gymnasium.make`` sets the whole's)."""
    limits = []
    while isinstance(env, gym.Wrapper):
        if isinstance(env, gym.wrappers.TimeLimit):
            limits.append(int(env._max_episode_steps))
        env = env.env
    return min(limits, default=None)
