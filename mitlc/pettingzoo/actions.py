"""The team wrapper's actions beside the tasks: the action of an agent that the wrapper has
ended while the inner env has not (:func:`idle_action`), and the shield's masks in PettingZoo's
convention (an int8 ``action_mask`` of a ``Discrete`` action space, :func:`mask_of`) and the
check of each action against its mask (:func:`checked`)."""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt
from gymnasium import spaces

from mitlc.pettingzoo.tasks import TeamTaskError

Mask = npt.NDArray[np.int8]


def idle_action(agent: str, space: spaces.Space[Any]) -> Any:
    """The default action of an agent the wrapper has ended but the inner env has not: the
    first action of a ``Discrete`` or ``MultiDiscrete``, zeros (clipped into a ``Box``)."""
    if isinstance(space, spaces.Discrete):
        return int(space.start)
    if isinstance(space, spaces.Box):
        return np.clip(np.zeros(space.shape), space.low, space.high).astype(space.dtype)
    if isinstance(space, spaces.MultiDiscrete):
        return np.asarray(space.start, dtype=space.dtype).copy()
    if isinstance(space, spaces.MultiBinary):
        return np.zeros(space.shape, dtype=space.dtype)
    raise TeamTaskError(
        f"idle_actions: give {agent}'s action (the inner env still has it after the wrapper "
        f"ended it, and {space} has no default)"
    )


def mask_of(agent: str, allowed: Any, n: int) -> Mask:
    """The ``action_mask`` of what a shield returned for ``agent`` (``n`` actions)."""
    array = np.asarray(allowed)
    if array.shape != (n,):
        raise TeamTaskError(
            f"shield: returned an array of shape {array.shape} for {agent}, expected ({n},)"
        )
    mask: Mask = (array != 0).astype(np.int8)
    return mask


def checked(action: Any, mask: Mask, start: int, block: bool) -> tuple[Any, bool]:
    """The action the env takes for ``action`` under ``mask`` (of actions from ``start``), and
    whether ``action`` was not allowed; with ``block`` such an action is replaced by the first
    allowed one (where there is one)."""
    index = int(action) - start
    if 0 <= index < len(mask) and mask[index]:
        return action, False
    allowed = np.flatnonzero(mask)
    if block and len(allowed):
        return int(allowed[0]) + start, True
    return action, True
