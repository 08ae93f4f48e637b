"""Any world a file declares, loaded once, and what it offers.

:func:`open_world` reads a world file once and loads the world it declares:

* a finite :class:`~mitlc.worlds.model.World`: a grid, or a gymnasium env with a transition
  table (toy-text's ``P``), whose model the checker, the vectorised simulator of the product
  and the exact evaluation read (:func:`is_finite`);
* a continuous :class:`~mitlc.worlds.plane.PlaneWorld`;
* an :class:`~mitlc.worlds.env_task.EnvTask`: a gymnasium env without a transition table.

Every world makes its gymnasium env under the task wrapper (:func:`task_env`:
:class:`mitlc.gym.TaskWrapper`, the one definition of an episode). What a caller does next is
decided by asking the loaded world (:func:`is_finite`, ``isinstance``), never the file again.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeAlias, TypeGuard

from mitlc.worlds.env_task import EnvTask
from mitlc.worlds.model import World
from mitlc.worlds.plane import PlaneWorld

if TYPE_CHECKING:
    from mitlc.automata import DigitalAutomaton
    from mitlc.gym import TaskWrapper

AnyWorld: TypeAlias = World | PlaneWorld | EnvTask
"""A world of any kind (see the module docstring)."""


def open_world(path: str | Path, spec: str | None = None) -> AnyWorld:
    """The world the file at ``path`` declares, its task replaced by ``spec`` (a formula's
    text) when given; a :class:`mitlc.worlds.WorldError` naming the field if it is bad. An env
    world is finite when its env has a transition table and a start distribution (the env is
    made to tell)."""
    from mitlc.worlds.env_task import finite_env, load_env_task
    from mitlc.worlds.load import kind_of, load_plane_world, load_world

    path = Path(path)
    kind = kind_of(path)
    if kind == "plane":
        return load_plane_world(path, spec)
    if kind == "env" and not finite_env(path):
        return load_env_task(path, spec)
    return load_world(path, spec)


def is_finite(world: AnyWorld) -> TypeGuard[World]:
    """Whether ``world`` is finite: its model can be checked, simulated and evaluated
    exactly."""
    return isinstance(world, World)


def task_env(
    world: AnyWorld, automaton: DigitalAutomaton, *, flatten: bool = False, **options: Any
) -> TaskWrapper:
    """A fresh gymnasium env of ``world`` under the task wrapper, with the task ``automaton``
    (compiled once for many envs); ``flatten``: the wrapper's flat observation; ``options``:
    the wrapper's ``task_obs`` and ``potential``."""
    made: Any
    if isinstance(world, World):
        from mitlc.product.env import ProductEnv

        made = ProductEnv(world, automaton, flatten=flatten, **options)
    elif isinstance(world, PlaneWorld):
        from mitlc.worlds.plane_env import plane_task

        made = plane_task(world, automaton=automaton, flatten=flatten, **options)
    else:
        made = world.make(automaton, flatten=flatten, **options)
    wrapper: TaskWrapper = made
    return wrapper
