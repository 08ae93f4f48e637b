"""What a deep learner sees, as one feature vector: :class:`Encoder`.

The world's observation (a one-hot of an id, or a Box's values scaled, with optional tile
coding and image parts), the task's state (a one-hot of the automaton state, or its row of
task features: the clock view of :mod:`mitlc.automata.clocks`), the frontier's bits and,
for a recurrent learner, the previous action.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt
import torch

from mitlc.automata.clocks import clock_view_of, clocks_shown
from mitlc.automata.digital import DigitalAutomaton
from mitlc.gym.observations import ImagePart
from mitlc.learn.envs.vec import Tables
from mitlc.worlds.model import IntArray

FloatArray = npt.NDArray[np.float32]


UNBOUNDED = 1e6
"""A Box bound past this (in absolute value) leaves its axis unscaled."""


class Encoder:
    """One-hot observation, the automaton state (absorbing states: 0) as a one-hot or as a row
    of ``task_features`` (the clock view, :mod:`mitlc.automata.clocks`), the frontier mask's
    bits and, with ``previous_action``, a one-hot of the previous action (an extra slot for
    "none", the first step of an episode)."""

    def __init__(
        self,
        tables: Tables,
        previous_action: bool = False,
        num_automaton_states: int | None = None,
        task_features: FloatArray | None = None,
    ) -> None:
        """``num_automaton_states``: the automaton block's width (default: the states the
        product has; the gymnasium wrapper's flat observation has one for every automaton
        state); ``task_features``: a row per automaton state in its place."""
        self.automaton: IntArray | None = np.maximum(tables.automaton_state, 0)
        width = num_automaton_states or tables.num_automaton_states
        self._layout(
            tables.num_observations, None, width, tables.num_sets, tables.num_actions,
            previous_action, task_features,
        )  # fmt: skip

    @classmethod
    def of_spaces(
        cls,
        observation: Any,
        num_automaton_states: int,
        num_sets: int,
        num_actions: int,
        previous_action: bool = False,
        tiles: int = 0,
        scaled: bool = True,
        images: Sequence[ImagePart] = (),
        task_features: FloatArray | None = None,
    ) -> Encoder:
        """An encoder of a wrapped env's observations: its own part a ``Discrete`` space
        (one-hot) or a ``Box``: the values of its bounded axes scaled to [0, 1] by the bounds,
        those of an unbounded axis (a bound infinite or past 1e6) as they are; with ``tiles``
        (every axis bounded), also a one-hot of the tile the values fall in, each axis cut
        into ``tiles`` (tile coding, Sutton and Barto, *Reinforcement Learning*, 2nd ed.,
        Sect. 9.5.4). ``scaled=False`` reads every axis as it is: the layout of
        :class:`mitlc.gym.TaskWrapper`'s flat observation, which SB3's networks learn on.
        ``images``: the Box's image parts (:attr:`mitlc.learn.envs.envvec.VectorTask.images`),
        which the networks read with a CNN (:mod:`mitlc.learn.learners.images`);
        ``task_features`` as for the constructor."""
        encoder = cls.__new__(cls)
        encoder.automaton = None
        if hasattr(observation, "n"):
            encoder._layout(int(observation.n), None, num_automaton_states, num_sets,
                            num_actions, previous_action, task_features)  # fmt: skip
            return encoder
        low = np.asarray(observation.low, dtype=np.float64).ravel()
        high = np.asarray(observation.high, dtype=np.float64).ravel()
        bounded = (np.abs(low) <= UNBOUNDED) & (np.abs(high) <= UNBOUNDED) & scaled
        if tiles and not bounded.all():
            raise ValueError(f"tiles need a bounded Box, not {observation}")
        low, high = np.where(bounded, low, 0.0), np.where(bounded, high, 1.0)
        low, high = low.astype(np.float32), high.astype(np.float32)
        cells = tiles ** len(low) if tiles else 0
        if cells > 100_000:
            raise ValueError(f"{tiles} tiles an axis over {len(low)} axes: too many tiles")
        encoder._layout(len(low) + cells, (low, np.maximum(high - low, 1e-9)),
                        num_automaton_states, num_sets, num_actions, previous_action,
                        task_features)  # fmt: skip
        encoder.tiles, encoder.box_width = tiles, len(low)
        encoder.images, encoder.image_scale = tuple(images), 1.0 if scaled else 1.0 / 255
        return encoder

    device = torch.device("cpu")
    """Where the features go: the learner's device."""
    tiles = 0
    box_width = 0
    images: tuple[ImagePart, ...] = ()
    image_scale = 1.0
    """What turns an image's values in the features into [0, 1] (scaled: by the bounds)."""

    def _layout(
        self,
        width: int,
        box: tuple[Any, Any] | None,
        num_automaton_states: int,
        num_sets: int,
        num_actions: int,
        previous_action: bool,
        task_features: FloatArray | None,
    ) -> None:
        self.box = box
        self.num_sets = num_sets
        self.previous_action = previous_action
        self.task_features = task_features
        self.obs_offset = 0
        self.aut_offset = width
        task_width = num_automaton_states if task_features is None else task_features.shape[1]
        self.mask_offset = self.aut_offset + task_width
        self.action_offset = self.mask_offset + num_sets
        self.size = self.action_offset + (num_actions + 1 if previous_action else 0)

    @property
    def observation_field(self) -> tuple[tuple[int, ...], Any]:
        """The shape and dtype of one observation in a replay memory: an id, or the Box's
        values."""
        if self.box is None:
            return (), np.int64
        return (self.box_width,), np.float32

    def automaton_of(self, states: IntArray) -> IntArray:
        """The automaton state of product states ``states`` (what the agent may know of them;
        an encoder of a product's tables only)."""
        assert self.automaton is not None, "an encoder of spaces knows no product states"
        automaton: IntArray = self.automaton[states]
        return automaton

    def __call__(
        self,
        observation: IntArray,
        automaton: IntArray,
        mask: IntArray,
        previous: IntArray | None = None,
    ) -> torch.Tensor:
        """The features of each entry (any shape ``S``): a float tensor of shape ``S + (size,)``;
        ``previous`` is the previous action, -1 for none."""
        shape = np.shape(automaton)
        rows = np.arange(int(np.prod(shape)))
        x = np.zeros((len(rows), self.size), dtype=np.float32)
        if self.box is None:
            x[rows, self.obs_offset + np.ravel(observation)] = 1.0
        else:
            low, span = self.box
            values = np.reshape(observation, (len(rows), self.box_width))
            scaled = (values - low) / span
            x[:, : self.box_width] = scaled
            if self.tiles:
                tile = np.clip((scaled * self.tiles).astype(np.int64), 0, self.tiles - 1)
                index = np.ravel_multi_index(tuple(tile.T), (self.tiles,) * self.box_width)
                x[rows, self.box_width + index] = 1.0
        if self.task_features is None:
            x[rows, self.aut_offset + np.ravel(automaton)] = 1.0
        else:
            x[:, self.aut_offset : self.mask_offset] = self.task_features[np.ravel(automaton)]
        if self.num_sets:
            bits = (np.ravel(mask)[:, None] >> np.arange(self.num_sets)) & 1
            x[:, self.mask_offset : self.action_offset] = bits
        if self.previous_action:
            assert previous is not None, "this encoder needs the previous action"
            x[rows, self.action_offset + 1 + np.ravel(previous)] = 1.0
        return torch.from_numpy(x.reshape(*shape, self.size)).to(self.device)


def task_features(automaton: DigitalAutomaton, task_obs: str) -> FloatArray | None:
    """What an :class:`Encoder` shows of each automaton state for the setting ``task_obs``
    (:attr:`mitlc.learn.config.TrainConfig.task_obs`): the clock view's rows where
    :func:`mitlc.automata.clocks.clocks_shown`, else ``None`` (the state's one-hot)."""
    return clock_view_of(automaton).features() if clocks_shown(automaton, task_obs) else None
