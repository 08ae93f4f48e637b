"""The PettingZoo kind: a world file with ``pettingzoo:``, a ``ParallelEnv`` made by an installed
module's ``parallel_env(**kwargs)``, and its team's tasks (the format and the world:
:mod:`mitlc.worlds.pettingzoo_world`).

Reading validates the shape (pydantic, every problem with its field path, line and column);
building imports the module by name (:func:`mitlc.worlds.env_make.import_named`, the trust
model of ``env:`` files), makes the env once (the probe), wraps it with the tasks and labels
(:class:`~mitlc.pettingzoo.TeamTaskWrapper`, whose errors are located at their fields), resets
it and takes one step, and keeps that wrapper for the world's first :meth:`team_env`.
"""

from __future__ import annotations

import difflib
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from mitlc.errors import MitlcError
from mitlc.worlds import trust
from mitlc.worlds.env_make import EnvMakeError, import_named, quiet, reason
from mitlc.worlds.grid import FieldPath
from mitlc.worlds.gym_world import field_problem
from mitlc.worlds.model import World
from mitlc.worlds.pettingzoo_world import PettingZooWorldFile, TeamEnvTask, joint_task
from mitlc.worlds.source import Source, WorldError, from_pydantic, task_of

ENV: FieldPath = ("pettingzoo", "env")


def claims(data: Mapping[str, Any]) -> bool:
    """Whether a world file's mapping names a PettingZoo env (``pettingzoo:``)."""
    return "pettingzoo" in data


def validate(path: Path, source: Source) -> PettingZooWorldFile:
    """The file's shape; a :class:`WorldError` with every problem."""
    try:
        return PettingZooWorldFile.model_validate(source.data)
    except ValidationError as err:
        problems = []
        for p, m, k in from_pydantic(err, env=True):
            if m.startswith("unknown field") and len(p) == 1:
                known = list(PettingZooWorldFile.model_fields)
                close = difflib.get_close_matches(str(p[0]), known, n=1)
                m = "unknown field" + (
                    f"; did you mean {close[0]!r}?" if close else f" (known: {', '.join(known)})"
                )
            problems.append(source.locate(p, m.removeprefix("Value error, "), key=k))
        raise WorldError(str(path), problems) from None


@dataclass(frozen=True, slots=True)
class PettingZooDeclaration:
    """A validated PettingZoo world file (see the module docstring)."""

    path: Path
    source: Source
    file: PettingZooWorldFile
    kind = "pettingzoo"

    @staticmethod
    def read(path: Path, source: Source) -> PettingZooDeclaration:
        """The declaration of the file at ``path`` (its YAML read: ``source``)."""
        return PettingZooDeclaration(path, source, validate(path, source))

    @property
    def name(self) -> str:
        """The world's name: the file's ``name``, else the file's stem."""
        return self.file.name or self.path.stem

    def finite(self, spec: str | None = None) -> World:
        """Never: a PettingZoo env has no transition table here."""
        message = ("a PettingZoo env is not finite: it has no exact model to check; learn it "
                   "with mitlc train (--algo sb3-ppo)")  # fmt: skip
        raise self._fail([(ENV, message)])

    def build(self, spec: str | None = None) -> TeamEnvTask:
        """The world, its team task replaced by ``spec`` when given; the env made once and
        kept under its tasks for the first :meth:`TeamEnvTask.team_env`."""
        file = self.file
        if spec is None and file.spec is None:
            text = joint_task(file.tasks)
            spec = text
        text, spec_source, propositions = task_of(file, self.path, self.source, spec)
        if file.spec is None and spec == text:
            spec_source = "<tasks>"
        if file.reward.move:
            message = "an env's actions have no 'stay': the move term must be 0 here"
            raise WorldError(str(self.path), [self.source.locate(("reward", "move"), message)])
        module = self._module()
        world = TeamEnvTask(
            name=self.name, module=module, kwargs=dict(file.pettingzoo.kwargs),
            labels=dict(file.labels), shared_labels=dict(file.shared_labels),
            tasks=dict(file.tasks), spec=text, spec_source=spec_source,
            propositions=propositions, horizon=file.horizon, discount=file.discount,
            rewards=file.reward.rewards(), training=dict(file.training),
        )  # fmt: skip
        team = self._probe(world)
        built = replace(world, agents=tuple(team.possible_agents))
        built.keep(team)
        return built

    def _fail(self, found: list[tuple[FieldPath, str]]) -> WorldError:
        return WorldError(str(self.path), [self.source.locate(p, m) for p, m in found])

    def _module(self) -> Any:
        """The env's module, imported by name; its ``parallel_env`` checked."""
        settings = self.file.pettingzoo
        refused = trust.path_arguments(settings.kwargs, ("pettingzoo", "kwargs"))
        if refused:
            raise self._fail(refused)
        try:
            module = import_named(settings.env, ENV, self.path.parent)
        except EnvMakeError as err:
            raise self._fail(err.found) from None
        if not callable(getattr(module, "parallel_env", None)):
            message = f"{settings.env} has no parallel_env(): name a PettingZoo env's module"
            raise self._fail([(ENV, message)])
        return module

    def _probe(self, world: TeamEnvTask) -> Any:
        """The env made and wrapped with the tasks, reset and stepped once (labels, tasks and
        the env's arguments checked); a :class:`WorldError` at the field at fault."""
        kwargs: FieldPath = ("pettingzoo", "kwargs") if world.kwargs else ENV
        try:
            with quiet():
                env = world.make_env()
        except Exception as err:  # the env's own constructor may raise anything
            raise self._fail([(kwargs, f"parallel_env cannot be made: {reason(err)}")]) from None
        try:
            team = world.wrap(env)
            with quiet():
                team.reset(seed=0)
                actions = {a: team.action_space(a) for a in team.agents}
                for space in actions.values():
                    space.seed(0)
                team.step({a: space.sample() for a, space in actions.items()})
        except MitlcError as err:
            env.close()
            raise self._fail([self._where(line) for line in str(err).splitlines()]) from None
        return team

    def _where(self, line: str) -> tuple[FieldPath, str]:
        """A wrapper's message at its field: ``team`` is the file's ``spec``."""
        path, message = field_problem(line)
        head = str(path[0]) if path else ""
        if head == "team":
            return ("spec",), message
        if head in ("labels", "shared_labels", "tasks", "horizon", "rewards"):
            return (path if head != "rewards" else ("reward",)), message
        return (), line
