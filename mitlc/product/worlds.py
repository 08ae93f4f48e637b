"""Any world a file declares, as the learners and the checker see it: the names of the one
door (:mod:`mitlc.worlds.door`) and :func:`task_env`, a world's env under the task wrapper.

What a caller does next is decided by asking the loaded world (:func:`is_finite`, its
``drawing``, ``default_algo``, ``is_pomdp``), never the file again.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from mitlc.worlds.door import AnyWorld, is_finite, open_world

if TYPE_CHECKING:
    from mitlc.automata import DigitalAutomaton
    from mitlc.gym import TaskWrapper


def task_env(
    world: AnyWorld, automaton: DigitalAutomaton, *, flatten: bool = False, **options: Any
) -> TaskWrapper:
    """A fresh gymnasium env of ``world`` under the task wrapper, with the task ``automaton``
    (compiled once for many envs); ``flatten``: the wrapper's flat observation; ``options``:
    the wrapper's ``task_obs`` and ``potential``."""
    wrapper: TaskWrapper = world.task_env(automaton, flatten=flatten, **options)
    return wrapper


__all__ = ["AnyWorld", "is_finite", "open_world", "task_env"]
