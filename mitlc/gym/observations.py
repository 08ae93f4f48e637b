"""What a learner reads of any gymnasium observation: the *readable part* of a space, as one
flat vector (:func:`readable`), shared by the task wrapper's flat observation
(:class:`mitlc.gym.parts.TaskObservation`, which the SB3 backends learn on) and by mitlc's own
learners' view of a vector env (:class:`mitlc.learn.envs.envvec.VectorTask`), so the two give
the same vector.

* **Read** (the layout of ``gymnasium.spaces.flatten``): a ``Box`` of any rank, its values in C
  order; a ``Discrete``, a one-hot of ``value - start``; a ``MultiBinary``, its bits; a
  ``MultiDiscrete``, a one-hot per entry, concatenated; a ``Dict`` or ``Tuple``, the readable
  parts of its members in order (a ``Dict`` in its key order), nested to any depth.
* **Left out**: parts that carry no numbers a network can read: ``Text``, ``Graph``,
  ``Sequence``, ``OneOf`` and any other space (MiniGrid's ``MissionSpace``). A space with no
  readable part at all is an :class:`UnreadableObservation`.
* **Images**: a ``Box`` part that is an image as Stable-Baselines3 tells one
  (``stable_baselines3.common.preprocessing.is_image_space`` with ``check_channels=True``:
  uint8, rank 3, bounds 0 and 255, 1, 3 or 4 channels, channels first when the first axis is
  the smallest) is listed with its offset in the vector (:class:`ImagePart`), so that a
  network can read it with a CNN (:mod:`mitlc.learn.learners.images`).

A lone ``Box`` keeps its dtype (its values are reshaped, not converted); every other layout is
float32.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
from gymnasium import spaces

from mitlc.errors import MitlcError

Path = tuple[str | int, ...]
"""Where a part lies in an observation: the keys (``Dict``) and indices (``Tuple``) to it."""


class UnreadableObservation(MitlcError, ValueError):
    """An observation space with nothing a learner can read (only text, graphs, sequences)."""


@dataclass(frozen=True, slots=True)
class ImagePart:
    """An image in a flat vector: its first value's ``offset``, its ``shape`` as the env gives
    it, and whether its channels come first (``C, H, W``) or last (``H, W, C``)."""

    offset: int
    shape: tuple[int, int, int]
    channels_first: bool

    @property
    def size(self) -> int:
        """The number of values."""
        return int(np.prod(self.shape))

    @property
    def chw(self) -> tuple[int, int, int]:
        """Channels, height and width."""
        a, b, c = self.shape
        return (a, b, c) if self.channels_first else (c, a, b)


IMAGE_CHANNELS = (1, 3, 4)
"""Grey, RGB and RGBD: the channel counts of an image (SB3's ``check_channels``)."""


def image_part(space: spaces.Space[Any], offset: int) -> ImagePart | None:
    """``space`` as an image at ``offset`` in a vector, or ``None`` when it is not one (SB3's
    ``is_image_space(space, check_channels=True)`` and ``is_image_space_channels_first``)."""
    if not isinstance(space, spaces.Box) or len(space.shape) != 3 or space.dtype != np.uint8:
        return None
    if np.any(space.low != 0) or np.any(space.high != 255):
        return None
    first = int(np.argmin(space.shape)) == 0
    channels = space.shape[0] if first else space.shape[-1]
    if channels not in IMAGE_CHANNELS:
        return None
    a, b, c = (int(n) for n in space.shape)
    return ImagePart(offset, (a, b, c), first)


@dataclass(frozen=True, slots=True)
class _Leaf:
    """A readable part: where it is in the observation and in the vector."""

    path: Path
    space: spaces.Space[Any]
    offset: int
    size: int


LEAVES = (spaces.Box, spaces.Discrete, spaces.MultiBinary, spaces.MultiDiscrete)
"""The spaces read as numbers (``Dict`` and ``Tuple`` are read through their members)."""


@dataclass(frozen=True, slots=True)
class Readable:
    """The readable part of an observation space (see the module docstring): ``space``, the
    flat ``Box`` of the vector; ``images``, its image parts; ``left_out``, the paths of the
    parts not read."""

    source: spaces.Space[Any]
    space: spaces.Box
    leaves: tuple[_Leaf, ...]
    images: tuple[ImagePart, ...]
    left_out: tuple[Path, ...]

    @property
    def size(self) -> int:
        """The length of the vector."""
        return int(self.space.shape[0])

    @property
    def lone_box(self) -> bool:
        """Whether the whole observation is one ``Box`` (read with its own dtype)."""
        return isinstance(self.source, spaces.Box)

    def extract(self, obs: Any) -> npt.NDArray[Any]:
        """The vector of one observation."""
        if self.lone_box:
            return np.asarray(obs).reshape(-1)
        out = np.zeros(self.size, dtype=np.float32)
        self.write(obs, out)
        return out

    def write(self, obs: Any, out: npt.NDArray[Any]) -> None:
        """Write the vector of one observation into ``out`` (1-D, :attr:`size` long)."""
        if isinstance(self.source, spaces.Discrete):  # the commonest case, done fast
            out[:] = 0.0
            out[int(obs) - int(self.source.start)] = 1.0
            return
        if self.lone_box:
            out[:] = np.asarray(obs).reshape(-1)
            return
        out[:] = 0.0
        rows = out[None]
        for leaf in self.leaves:
            _fill(leaf, np.asarray(_at(obs, leaf.path))[None], rows)

    def extract_batch(self, obs: Any, count: int) -> npt.NDArray[Any]:
        """The vectors ``(count, size)`` of a batch of ``count`` observations, batched as a
        gymnasium vector env batches them (``gymnasium.vector.utils.batch_space``: a ``Dict``
        or ``Tuple`` of batches). A lone ``Box``'s may be a view of ``obs``."""
        if self.lone_box:
            return np.asarray(obs).reshape(count, -1)
        out = np.zeros((count, self.size), dtype=np.float32)
        for leaf in self.leaves:
            _fill(leaf, np.asarray(_at(obs, leaf.path)), out)
        return out


def readable(space: spaces.Space[Any]) -> Readable:
    """The readable part of ``space`` (an :class:`UnreadableObservation` when it has none)."""
    leaves: list[_Leaf] = []
    left_out: list[Path] = []
    _walk(space, (), leaves, left_out)
    if not leaves:
        raise UnreadableObservation(
            f"nothing a learner can read in the observation space {space}: it holds no Box, "
            "Discrete, MultiBinary or MultiDiscrete part (text, graphs and sequences are left out)"
        )
    if isinstance(space, spaces.Box):
        low, high = space.low.reshape(-1), space.high.reshape(-1)
        flat = spaces.Box(low, high, dtype=space.dtype)
    else:
        bounds = [_bounds(leaf.space) for leaf in leaves]
        low = np.concatenate([b[0] for b in bounds]).astype(np.float32)
        high = np.concatenate([b[1] for b in bounds]).astype(np.float32)
        flat = spaces.Box(low, high, dtype=np.float32)
    images = [image_part(leaf.space, leaf.offset) for leaf in leaves]
    found = tuple(image for image in images if image is not None)
    return Readable(space, flat, tuple(leaves), found, tuple(left_out))


def _walk(space: spaces.Space[Any], path: Path, leaves: list[_Leaf], left: list[Path]) -> None:
    """Collect the readable leaves of ``space`` (at ``path``) in order, and what is left out."""
    if isinstance(space, spaces.Dict):
        for key, member in space.spaces.items():
            _walk(member, (*path, key), leaves, left)
    elif isinstance(space, spaces.Tuple):
        for index, member in enumerate(space.spaces):
            _walk(member, (*path, index), leaves, left)
    elif isinstance(space, LEAVES):
        size = int(np.prod(spaces.flatten_space(space).shape or ()))
        if size:
            offset = leaves[-1].offset + leaves[-1].size if leaves else 0
            leaves.append(_Leaf(path, space, offset, size))
    else:
        left.append(path)


def _bounds(space: spaces.Space[Any]) -> tuple[npt.NDArray[Any], npt.NDArray[Any]]:
    """The bounds of a leaf's values in the vector (0 and 1 for a one-hot or bits)."""
    flat = spaces.flatten_space(space)
    assert isinstance(flat, spaces.Box)
    if isinstance(space, spaces.Box):
        return flat.low.astype(np.float64), flat.high.astype(np.float64)
    return np.zeros(flat.shape), np.ones(flat.shape)


def _at(obs: Any, path: Path) -> Any:
    for key in path:
        obs = obs[key]
    return obs


def _fill(leaf: _Leaf, values: npt.NDArray[Any], out: npt.NDArray[Any]) -> None:
    """Write a leaf's batch of ``values`` (the batch first) into its columns of ``out``."""
    count = out.shape[0]
    space, start = leaf.space, leaf.offset
    if isinstance(space, spaces.Box | spaces.MultiBinary):
        out[:, start : start + leaf.size] = values.reshape(count, -1)
    elif isinstance(space, spaces.Discrete):
        rows = np.arange(count)
        out[rows, start + values.reshape(count) - int(space.start)] = 1.0
    else:
        assert isinstance(space, spaces.MultiDiscrete)
        nvec = space.nvec.reshape(-1).astype(np.int64)
        first = start + np.concatenate([[0], np.cumsum(nvec)[:-1]])
        index = values.reshape(count, -1).astype(np.int64) - space.start.reshape(-1)
        out[np.arange(count)[:, None], first + index] = 1.0
