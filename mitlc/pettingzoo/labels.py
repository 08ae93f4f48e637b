"""The labels of a team, compiled and checked when the wrapper is made, and where each
proposition of a task is read.

* ``labels``: one mapping of declarations per agent (``{agent: {prop: form}}``), or one mapping
  (or labels, or a labelling function) for every agent; declarations are compiled by
  :func:`mitlc.labels.compile_labels` against the agent's observation space, so a bad one
  raises a :class:`~mitlc.labels.LabelDeclarationError` naming its field's path
  (``labels.robot_0.goal.box.index: ...``).
* ``shared_labels``: declarations of propositions that hold when they hold on *any* agent's
  ``(obs, info)``, compiled for each agent's space (``shared_labels.collide.info: ...``).
* A per-agent task reads its agent's own propositions; the team task reads ``<prop>_<agent>``
  (``prop`` of ``agent``'s labels), the shared propositions, and, when a ``team_labels``
  callable is given, any other name (which it must return when true).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from mitlc.labels import LabelFunction, Labeller, Labels, compile_labels
from mitlc.labels.function import check_signature
from mitlc.pettingzoo.tasks import TeamTaskError, TeamTaskTypeError

AgentLabels = Labels | LabelFunction | Mapping[str, Any]
"""What ``labels`` may give an agent: declarations, compiled labels, or a labelling function."""

TeamLabels = Callable[[dict[str, Any], dict[str, Any]], Any]
"""``team_labels(observations, infos)``: the shared propositions true now."""


def _shown(names: Sequence[str]) -> str:
    return ", ".join(names) if names else "none"


def agent_labels(
    labels: AgentLabels | Mapping[str, AgentLabels] | None,
    agents: Sequence[str],
    spaces: Mapping[str, Any],
) -> dict[str, Labels | LabelFunction]:
    """Each agent's labels (an agent ``labels`` gives none is left out)."""
    if labels is None:
        return {}
    if not isinstance(labels, Mapping):
        one = _one(labels, "labels")
        return dict.fromkeys(agents, one)
    keys = list(labels)
    named = [k for k in keys if k in agents]
    if not named:  # one mapping of declarations for every agent
        return {a: compile_labels(labels, spaces[a], path="labels") for a in agents}
    odd = [k for k in keys if k not in agents]
    if odd:
        raise TeamTaskError(
            f"labels: {odd[0]!r} is not an agent (agents: {_shown(agents)}); a mapping whose "
            "keys are agents gives each agent's labels, one whose keys are propositions gives "
            "every agent the same"
        )
    found: dict[str, Labels | LabelFunction] = {}
    for agent in named:
        given, where = labels[agent], f"labels.{agent}"
        if isinstance(given, Mapping):
            found[agent] = compile_labels(given, spaces[agent], path=where)
        else:
            found[agent] = _one(given, where)
    return found


def _one(labels: Any, where: str) -> Labels | LabelFunction:
    """Compiled labels or a labelling function, as given."""
    if isinstance(labels, Labels):
        return labels
    if not callable(labels):
        raise TeamTaskTypeError(
            f"{where}: expected a mapping of declarations, labels or a callable (obs, info) -> "
            f"set of true propositions, got {type(labels).__name__}"
        )
    check_signature(labels)
    return labels  # type: ignore[no-any-return]


def shared_labellers(
    shared: Mapping[str, Any] | None, agents: Sequence[str], spaces: Mapping[str, Any]
) -> dict[str, Labeller]:
    """``shared_labels`` compiled for each agent's observation space."""
    if shared is None:
        return {}
    if not isinstance(shared, Mapping):
        raise TeamTaskTypeError(
            "shared_labels: expected a mapping from proposition names to label forms, got "
            f"{type(shared).__name__}"
        )
    return {a: compile_labels(shared, spaces[a], path="shared_labels") for a in agents}


def declared(labels: Labels | LabelFunction | None) -> tuple[str, ...] | None:
    """The propositions ``labels`` declare; ``None`` where they are not known (a function)."""
    if isinstance(labels, Labeller):
        return labels.propositions
    return () if labels is None else None


def check_own(
    agent: str, propositions: Sequence[str], labels: Labels | LabelFunction | None
) -> None:
    """An agent's task may read only what its labels declare."""
    if labels is None:
        raise TeamTaskError(f"tasks.{agent}: {agent} has no labels (give labels.{agent})")
    names = declared(labels)
    missing = [p for p in propositions if names is not None and p not in names]
    if missing:
        raise TeamTaskError(
            f"tasks.{agent}: the task's propositions {missing} are not declared by {agent}'s "
            f"labels (declared: {_shown(sorted(names or ()))})"
        )


@dataclass(frozen=True, slots=True)
class TeamSources:
    """Where the team task reads each of its propositions: ``agents[agent]``, the pairs
    ``(prop, team proposition)`` read on that agent's labels; ``shared``, those of
    ``shared_labels``; ``called``, those ``team_labels`` gives."""

    agents: dict[str, tuple[tuple[str, str], ...]]
    shared: tuple[str, ...]
    called: tuple[str, ...]


def team_sources(
    propositions: Sequence[str],
    agents: Sequence[str],
    labels: Mapping[str, Labels | LabelFunction],
    shared: Sequence[str],
    calls: bool,
) -> TeamSources:
    """Where each of the team task's ``propositions`` is read (module docstring); a
    :class:`TeamTaskError` for one that nothing gives."""
    by_agent: dict[str, list[tuple[str, str]]] = {}
    on_shared: list[str] = []
    called: list[str] = []
    for name in propositions:
        owner = _owner(name, agents)
        prop = name[: -len(owner) - 1] if owner is not None else ""
        known = declared(labels.get(owner)) if owner is not None else ()
        own = owner is not None and (known is None or prop in known)
        if own and name in shared:
            raise TeamTaskError(
                f"team: {name!r} is both {owner}'s {prop!r} and a shared label: rename one"
            )
        if own:
            assert owner is not None
            by_agent.setdefault(owner, []).append((prop, name))
        elif name in shared:
            on_shared.append(name)
        elif calls:
            called.append(name)
        elif owner is not None:
            raise TeamTaskError(
                f"team: proposition {name!r}: {owner}'s labels declare no {prop!r} "
                f"(declared: {_shown(sorted(known or ()))}), and it is no shared label"
            )
        else:
            raise TeamTaskError(
                f"team: proposition {name!r} is neither an agent's label, written "
                f"<prop>_<agent> (agents: {_shown(agents)}), nor a shared label (shared_labels: "
                f"{_shown(sorted(shared))}); declare it there or give team_labels"
            )
    pairs = {a: tuple(found) for a, found in by_agent.items()}
    return TeamSources(pairs, tuple(on_shared), tuple(called))


def _owner(name: str, agents: Sequence[str]) -> str | None:
    """The agent whose id ends ``name`` after an underscore (the longest such id)."""
    found = [a for a in agents if name.endswith(f"_{a}") and len(name) > len(a) + 1]
    return max(found, key=len, default=None)
