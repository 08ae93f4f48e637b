"""A PettingZoo env as a world (``pettingzoo:`` files): the file's shape
(:class:`PettingZooWorldFile`, pydantic, ``extra="forbid"``) and the world it builds
(:class:`TeamEnvTask`, not finite), read through the one door by
:mod:`mitlc.worlds.kinds.pettingzoo`.

```yaml
name: spread
pettingzoo: {env: mpe2.simple_spread_v3, kwargs: {N: 2, max_cycles: 50}}
labels: {at_0: {disc: {index: [4, 5], center: [0, 0], radius: 0.2}}}   # every agent's
shared_labels: {collide: {disc: {index: [8, 9], center: [0, 0], radius: 0.3}}}
tasks: {agent_0: "F[0,40] at_0"}     # optional per-agent tasks
spec: {formula: "F[0,40] (at_0_agent_0 & at_1_agent_1)"}   # the team task
horizon: 50
training: {algo: sb3-ppo, sb3: {steps: 20000}}
```

* ``pettingzoo.env`` is an installed module's dotted name, imported by name under the trust
  model of ``env:`` files (:func:`mitlc.worlds.env_make.import_named`); its
  ``parallel_env(**kwargs)`` is called, and nothing else runs code. ``kwargs`` are YAML data
  that name no file (:func:`mitlc.worlds.trust.path_arguments`).
* ``labels``, ``shared_labels``, ``tasks`` are :class:`~mitlc.pettingzoo.TeamTaskWrapper`'s: the
  same forms for every agent, or a mapping from agents to forms; the team task reads
  ``<prop>_<agent>`` and the shared propositions.
* ``spec`` is the team task. Without it, the team task is the conjunction of the agents' tasks,
  each read on its agent's labels (``at_0`` of ``agent_0`` as ``at_0_agent_0``), so that a team
  episode always has one success. ``--spec`` replaces the team task.
* The world is learned by Stable-Baselines3 with one policy shared by the agents
  (:data:`LEARNED_BY`, through :class:`mitlc.pettingzoo.vector.TeamVecEnv`); it is not finite
  (no exact optimum) and has no map.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

from pydantic import Field, model_validator

from mitlc.errors import MitlcError
from mitlc.syntax import ast, parse, to_text
from mitlc.worlds.env_schema import KwargName, ModuleName
from mitlc.worlds.model import Rewards
from mitlc.worlds.schema import Discount, Horizon, Proposition, Reward, SpecRef, WorldName, _Model

LEARNED_BY = ("sb3-ppo", "sb3-dqn")
"""The learners of a PettingZoo world: SB3's, one policy shared by every agent."""


class TeamWorldError(MitlcError, ValueError):
    """A PettingZoo world asked for what it does not give (a single-agent env under the task
    wrapper)."""


class PettingZooEnv(_Model):
    """The PettingZoo env: an installed module with ``parallel_env(**kwargs)``."""

    env: ModuleName = Field(
        description="The installed module whose parallel_env(**kwargs) makes the env, by dotted "
        "name (e.g. mpe2.simple_spread_v3)."
    )
    kwargs: dict[KwargName, Any] = Field(
        default_factory=dict,
        description="Keyword arguments of parallel_env: YAML scalars, lists and mappings only.",
    )


class PettingZooWorldFile(_Model):
    """A world file naming a PettingZoo ``ParallelEnv`` and the team's tasks."""

    name: WorldName | None = Field(
        default=None, description="The world's name (default: the file's stem)."
    )
    pettingzoo: PettingZooEnv = Field(description="The env: {env: module, kwargs: {...}}.")
    labels: dict[str, Any] = Field(
        default_factory=dict,
        description="Every agent's labels ({prop: form}), or a mapping agent -> {prop: form}; "
        "the forms of env: files (box, disc, info, attr, key, ...).",
    )
    shared_labels: dict[Proposition, Any] = Field(
        default_factory=dict,
        description="Propositions that hold when they hold on any agent's (obs, info).",
    )
    tasks: dict[str, str] = Field(
        default_factory=dict, description="Per-agent tasks: agent -> MITL formula (its labels)."
    )
    spec: SpecRef | None = Field(
        default=None,
        description="The team task, over <prop>_<agent> and the shared propositions: a spec "
        "file's path or {formula: ...} (default: the conjunction of the agents' tasks).",
    )
    reward: Reward = Field(default=Reward(), description="The reward terms (move must be 0).")
    horizon: Horizon = Field(description="The number of steps of an episode.")
    discount: Discount = Field(default=0.99, description="The discount factor, in (0, 1].")
    training: dict[Any, Any] = Field(
        default_factory=dict, description="Settings for the learners: a mapping, free-form."
    )

    @model_validator(mode="after")
    def _a_task(self) -> PettingZooWorldFile:
        if self.spec is None and not self.tasks:
            raise ValueError("give the team task (spec:), per-agent tasks (tasks:) or both")
        return self


def renamed(formula: ast.Formula, agent: str) -> ast.Formula:
    """``formula`` with each proposition ``p`` read as ``p_<agent>``."""
    if isinstance(formula, ast.Atom):
        return replace(formula, name=f"{formula.name}_{agent}")
    changes = {
        name: renamed(getattr(formula, name), agent)
        for name in ("operand", "left", "right")
        if hasattr(formula, name)
    }
    return replace(formula, **changes)  # type: ignore[arg-type]


def joint_task(tasks: Mapping[str, str]) -> str:
    """The conjunction of the agents' ``tasks``, each over its agent's propositions."""
    parts = [to_text(renamed(parse(text, f"<tasks.{a}>"), a)) for a, text in tasks.items()]
    return " & ".join(f"({p})" for p in parts)


@dataclass(frozen=True, slots=True)
class TeamEnvTask:
    """A PettingZoo env and its team's tasks, learned by SB3 through
    :class:`~mitlc.pettingzoo.vector.TeamVecEnv` (module docstring)."""

    name: str
    module: Any
    """The imported module whose ``parallel_env`` makes the env."""
    kwargs: dict[str, Any]
    labels: dict[str, Any]
    shared_labels: dict[str, Any]
    tasks: dict[str, str]
    spec: str
    """The team task."""
    spec_source: str
    propositions: tuple[str, ...]
    horizon: int
    discount: float
    rewards: Rewards
    training: Mapping[str, Any] = field(default_factory=dict)
    agents: tuple[str, ...] = ()
    _spare: list[Any] = field(default_factory=list, compare=False, repr=False)
    """The team wrapper made to check the file (at most one), handed to the first
    :meth:`team_env`."""

    kind = "pettingzoo"
    is_pomdp = False
    default_algo = "sb3-ppo"
    learned_by = LEARNED_BY
    drawing = None
    """A PettingZoo env has no map to draw."""

    def keep(self, team: Any) -> None:
        """Keep ``team`` (made to check the file) for the first :meth:`team_env`."""
        self._spare[:] = [team]

    def make_env(self) -> Any:
        """A fresh ``module.parallel_env(**kwargs)``."""
        return self.module.parallel_env(**self.kwargs)

    def team_env(self) -> Any:
        """A fresh :class:`~mitlc.pettingzoo.TeamTaskWrapper` of the env and the tasks."""
        return self._spare.pop() if self._spare else self.wrap(self.make_env())

    def wrap(self, env: Any) -> Any:
        """``env`` under the team's tasks, labels, horizon and rewards."""
        from mitlc.pettingzoo import TeamTaskWrapper

        return TeamTaskWrapper(
            env,
            self.tasks or None,
            team=self.spec,
            labels=self.labels or None,
            shared_labels=self.shared_labels or None,
            horizon=self.horizon,
            rewards=self.rewards,
        )

    def vec_env(self, teams: int) -> Any:
        """``teams`` fresh teams as one SB3 ``VecEnv``, a slot per agent."""
        from mitlc.pettingzoo.vector import TeamVecEnv

        return TeamVecEnv([self.team_env() for _ in range(teams)])

    def task_env(self, automaton: Any, *, flatten: bool = False, **options: Any) -> Any:
        """Refused: a team is not one gymnasium env (:meth:`team_env` is the ParallelEnv,
        :meth:`vec_env` the vector env SB3 learns on)."""
        raise TeamWorldError(
            f"{self.name}: a PettingZoo team world is no single gymnasium env; it is learned "
            f"with --algo {' or '.join(LEARNED_BY)} (one policy shared by the agents, "
            "mitlc.pettingzoo.vector.TeamVecEnv)"
        )
