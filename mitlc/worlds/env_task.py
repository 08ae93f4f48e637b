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

:func:`load_env_task` loads such a file into an :class:`EnvTask`; :func:`is_open_world` says
whether a world file is learned this way (a continuous world, or an env that is not finite).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mitlc.worlds import gym_world
from mitlc.worlds.env_make import quiet
from mitlc.worlds.model import Rewards
from mitlc.worlds.schema import Env


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

    def make(self, automaton: Any, *, flatten: bool = False, **options: Any) -> Any:
        """A fresh env wrapped with the task (``automaton``: the task compiled once;
        ``flatten``: the wrapper's flat observation; ``options``: the wrapper's others)."""
        from mitlc.gym import TaskWrapper

        return TaskWrapper(
            gym_world.make_env(self.env, self.folder),
            automaton,
            self.labels,
            rewards=self.rewards,
            horizon=self.horizon,
            flatten=flatten,
            **options,
        )


def is_open_world(path: str | Path) -> bool:
    """Whether the world file at ``path`` is learned through the task wrapper: a continuous
    world, or an env world whose env is not finite (the env is made to tell)."""
    from mitlc.worlds.load import kind_of

    kind = kind_of(path)
    return kind == "plane" or (kind == "env" and not finite_env(path))


def finite_env(path: str | Path) -> bool:
    """Whether the env world file at ``path`` names a finite env: one with a transition table
    and a start distribution (the env is made to tell)."""
    from mitlc.worlds.load import _mapping, _read_env

    path = Path(path)
    source = _mapping(path)
    world = _read_env(path, source)
    if gym_world.reads_env(world.labels):
        return False
    env = _made(path, source, world.env)
    try:
        return gym_world.is_finite(env) and _has_start(env)
    finally:
        env.close()


def _has_start(env: Any) -> bool:
    return getattr(env.unwrapped, "initial_state_distrib", None) is not None


def load_env_task(path: str | Path, spec: str | None = None) -> EnvTask:
    """Load and validate the env world file at ``path`` as an env to learn through the task
    wrapper (``spec``, a formula's text, in place of the file's task); a
    :class:`mitlc.worlds.WorldError` naming the field if it is bad."""
    from mitlc.gym import TaskWrapperError
    from mitlc.labels import LabelDeclarationError
    from mitlc.worlds.load import (
        WorldError,
        _load_spec,
        _mapping,
        _read_env,
        _require_labelled,
    )

    path = Path(path)
    source = _mapping(path)
    world = _read_env(path, source)
    text, text_source, propositions = _load_spec(world, path, source, spec)
    missing = [p for p in propositions if p not in world.labels]
    _require_labelled(path, source, (text, text_source), missing, world.labels, "is not labelled")
    if world.reward.move:
        message = "an env's actions have no 'stay': the move term must be 0 here"
        raise WorldError(str(path), [source.locate(("reward", "move"), message)])
    env = _made(path, source, world.env)
    labels = gym_world.declarations(world.labels)
    task = EnvTask(
        name=world.name or path.stem,
        env=world.env,
        labels=labels,
        propositions=propositions,
        spec=text,
        spec_source=text_source,
        horizon=world.horizon,
        discount=world.discount,
        rewards=world.reward.rewards(),
        folder=path.parent,
    )
    try:
        found = gym_world.form_problems(world.labels, env.observation_space)
        if found:
            raise WorldError(str(path), [source.locate(p, m) for p, m in found])
        from mitlc.automata import translate
        from mitlc.gym import TaskWrapper
        from mitlc.syntax import parse

        automaton = translate(parse(text, text_source))
        wrapped = TaskWrapper(env, automaton, labels, rewards=task.rewards, horizon=task.horizon)
        _probe(wrapped)
    except TaskWrapperError as err:
        where = ("horizon",) if "horizon" in str(err) else ("env", "id")
        raise WorldError(str(path), [source.locate(where, str(err))]) from None
    except LabelDeclarationError as err:
        found = [gym_world.field_problem(line) for line in str(err).splitlines()]
        raise WorldError(str(path), [source.locate(p, m) for p, m in found]) from None
    finally:
        env.close()
    return task


def _probe(wrapped: Any) -> None:
    """Reset the wrapped env and take one step, so that the labels' ``attr`` and ``info``
    paths are checked against it (:mod:`mitlc.labels.probe`; a
    :class:`~mitlc.labels.LabelDeclarationError` if one is not there)."""
    if not wrapped.labels.values():
        return
    wrapped.action_space.seed(0)
    with quiet():
        wrapped.reset(seed=0)
        wrapped.step(wrapped.action_space.sample())


def _made(path: Path, source: Any, settings: Env) -> Any:
    """The env the file names, made (a :class:`~mitlc.worlds.WorldError` if it cannot be)."""
    from mitlc.worlds.load import WorldError

    try:
        return gym_world.make_env(settings, path.parent)
    except gym_world.GymWorldError as err:
        raise WorldError(str(path), [source.locate(p, m) for p, m in err.found]) from None
