"""The env kind: a world file with ``env:``, a gymnasium env named by its registered id
(:mod:`mitlc.worlds.gym_world` converts a finite one; :mod:`mitlc.worlds.env_task` learns any
other through the task wrapper).

Building it makes the env once (the probe): an env with a transition table and a start
distribution, whose labels read only its states, becomes a finite
:class:`~mitlc.worlds.model.World`; any other an :class:`~mitlc.worlds.env_task.EnvTask`,
checked by a reset and a step under its task, which keeps the probe for its first env.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from mitlc.labels.geodesic import declared_occupancy
from mitlc.worlds import gym_world
from mitlc.worlds.costs import action_problems
from mitlc.worlds.env_make import quiet
from mitlc.worlds.env_schema import Env, EnvWorldFile
from mitlc.worlds.env_task import EnvTask
from mitlc.worlds.grid import Found
from mitlc.worlds.model import World
from mitlc.worlds.source import (
    Source,
    WorldError,
    from_pydantic,
    require_labelled,
    task_of,
    world_costs,
)


def claims(data: Mapping[str, Any]) -> bool:
    """Whether a world file's mapping names a gymnasium env (``env:``)."""
    return "env" in data


def validate(path: Path, source: Source) -> EnvWorldFile:
    """An env world file's shape and whole-file checks (:func:`gym_world.check_file`)."""
    filename = str(path)
    try:
        world = EnvWorldFile.model_validate(source.data)
    except ValidationError as err:
        problems = []
        for p, m, k in from_pydantic(err, env=True):
            if p == ("grid",) and m.startswith("unknown field"):
                m = "a world has either grid: or env:, not both"
            problems.append(source.locate(p, m, key=k))
        raise WorldError(filename, problems) from None
    found = gym_world.check_file(world)
    if found:
        raise WorldError(filename, [source.locate(p, m) for p, m in found])
    return world


@dataclass(frozen=True, slots=True)
class EnvDeclaration:
    """A validated env world file (see the module docstring)."""

    path: Path
    source: Source
    file: EnvWorldFile
    kind = "env"

    @staticmethod
    def read(path: Path, source: Source) -> EnvDeclaration:
        """The declaration of the env world file at ``path`` (its YAML read: ``source``)."""
        return EnvDeclaration(path, source, validate(path, source))

    @property
    def name(self) -> str:
        """The world's name: the file's ``name``, else the file's stem."""
        return self.file.name or self.path.stem

    def build(self, spec: str | None = None) -> World | EnvTask:
        """The world, its task replaced by ``spec`` (a formula's text) when given: finite or
        learned through the wrapper (module docstring), the env made once."""
        task = task_of(self.file, self.path, self.source, spec)
        env = self._made(self.file.env)
        if gym_world.reads_env(self.file.labels) is None and _finite(env):
            try:
                return self._finite(env, task)
            finally:
                env.close()
        try:
            return self._open(env, task)  # the env is kept as the task's first
        except BaseException:
            env.close()
            raise

    def learned(self, spec: str | None = None) -> EnvTask:
        """The world as an env learned through the task wrapper, finite or not."""
        task = task_of(self.file, self.path, self.source, spec)
        env = self._made(self.file.env)
        try:
            made = self._open(env, task)
        except BaseException:
            env.close()
            raise
        return made

    def finite(self, spec: str | None = None) -> World:
        """The finite world (a :class:`WorldError` saying why where the env is not finite)."""
        task = task_of(self.file, self.path, self.source, spec)
        env = self._made(self.file.env)
        try:
            return self._finite(env, task)
        finally:
            env.close()

    def _fail(self, found: Found, detail: str = "") -> WorldError:
        return WorldError(str(self.path), [self.source.locate(p, m, detail) for p, m in found])

    def _made(self, settings: Env) -> Any:
        """The env the file names, made (a :class:`WorldError` if it cannot be)."""
        try:
            return gym_world.make_env(settings, self.path.parent)
        except gym_world.GymWorldError as err:
            raise self._fail(err.found) from None

    def _finite(self, env: Any, task: tuple[str, str, tuple[str, ...]]) -> World:
        """The finite world converted from the env's transition table."""
        path, source, file = self.path, self.source, self.file
        text, text_source, propositions = task
        missing = [p for p in propositions if p not in file.labels]
        told = (text, text_source)
        require_labelled(path, source, told, missing, file.labels, "holds in no state")
        costs, propositions = world_costs(file, path, source, propositions, None)
        try:
            built = gym_world.build_world(
                file, env, name=self.name, spec=text, spec_source=text_source,
                propositions=propositions,
            )  # fmt: skip
        except gym_world.GymWorldError as err:
            raise self._fail(err.found) from None
        built = replace(built, training=dict(file.training))
        if costs is None:
            return built
        found = action_problems(costs, built.actions)
        if found:
            raise WorldError(str(path), [source.locate(p, m, d) for p, m, d in found])
        return replace(built, costs=costs)

    def _open(self, env: Any, task: tuple[str, str, tuple[str, ...]]) -> EnvTask:
        """The env learned through the task wrapper, checked by a reset and a step with its
        labels (the probe, kept as the task's first env)."""
        from mitlc.gym import TaskWrapperError
        from mitlc.labels import LabelDeclarationError

        path, source, file = self.path, self.source, self.file
        text, text_source, propositions = task
        missing = [p for p in propositions if p not in file.labels]
        told = (text, text_source)
        require_labelled(path, source, told, missing, file.labels, "is not labelled")
        if file.reward.move:
            message = "an env's actions have no 'stay': the move term must be 0 here"
            raise WorldError(str(path), [source.locate(("reward", "move"), message)])
        made = EnvTask(
            name=self.name,
            env=file.env,
            labels=gym_world.declarations(file.labels),
            propositions=propositions,
            spec=text,
            spec_source=text_source,
            horizon=file.horizon,
            discount=file.discount,
            rewards=file.reward.rewards(),
            folder=path.parent,
            training=dict(file.training),
            occupancy=declared_occupancy(file.occupancy),
        )
        try:
            found = gym_world.form_problems(file.labels, env.observation_space)
            if found:
                raise self._fail(found)
            _probe(made, env, text, text_source)
        except TaskWrapperError as err:
            where = ("horizon",) if "horizon" in str(err) else ("env", "id")
            raise WorldError(str(path), [source.locate(where, str(err))]) from None
        except LabelDeclarationError as err:
            found = [gym_world.field_problem(line) for line in str(err).splitlines()]
            raise self._fail(found) from None
        made.keep(env)
        return made


def _finite(env: Any) -> bool:
    """Whether a made env is finite: a transition table and a start distribution."""
    has_start = getattr(env.unwrapped, "initial_state_distrib", None) is not None
    return gym_world.is_finite(env) and has_start


def _probe(task: EnvTask, env: Any, text: str, text_source: str) -> None:
    """Reset the env under its task and take one step, so that the labels' ``attr`` and
    ``info`` paths are checked against it (:mod:`mitlc.labels.probe`; a
    :class:`~mitlc.labels.LabelDeclarationError` if one is not there)."""
    from mitlc.automata import translate
    from mitlc.gym import TaskWrapper
    from mitlc.labels import Labeller
    from mitlc.syntax import parse

    automaton = translate(parse(text, text_source))
    wrapped = TaskWrapper(env, automaton, task.labels, rewards=task.rewards, horizon=task.horizon)
    if not isinstance(wrapped.labels, Labeller) or not wrapped.labels.values():
        return
    wrapped.action_space.seed(0)
    with quiet():
        wrapped.reset(seed=0)
        wrapped.step(wrapped.action_space.sample())
