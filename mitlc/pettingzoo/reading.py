"""The letters of a team: each agent's labels read on its own ``(obs, info)`` by a
:class:`mitlc.gym.reading.LetterTaker` (the gymnasium wrapper's reading: the moment, the label
checks at the first positions), then composed into each agent's own task's letter and the
team task's letter (``<prop>_<agent>`` for every agent's labels, shared propositions holding
when they hold on any agent's position, and those of ``team_labels``).

An agent's letters are kept when it leaves: a departed agent's propositions stay at their last
values for the team task.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from mitlc.gym.reading import LetterTaker
from mitlc.labels import LabelDeclarationError, LabelFunction, Labeller, Labels
from mitlc.labels.function import check_result, true_names
from mitlc.pettingzoo.labels import TeamLabels, TeamSources

Pairs = tuple[tuple[int, int], ...]
"""``(bit read, bit of the composed letter)`` pairs."""


def _moved(letter: int, pairs: Pairs) -> int:
    out = 0
    for source, target in pairs:
        if letter & source:
            out |= target
    return out


class _AgentReading:
    """One agent's readers: its labels over ``own + team-only`` propositions, and the shared
    labels on its position."""

    def __init__(
        self,
        agent: str,
        labels: Labels | LabelFunction | None,
        own: Sequence[str],
        team: Sequence[tuple[str, str]],
        shared: tuple[Labeller, Sequence[str]] | None,
        team_index: Mapping[str, int],
        env: Any,
    ) -> None:
        self.agent = agent
        names = list(own) + [p for p, _ in team if p not in own]
        self.own_mask = (1 << len(own)) - 1
        self.labels = None if labels is None or not names else LetterTaker(labels, names, env)
        self.team: Pairs = tuple((1 << names.index(p), 1 << team_index[name]) for p, name in team)
        self.shared = None
        self.shared_pairs: Pairs = ()
        if shared is not None and shared[1]:
            labeller, props = shared
            self.shared = LetterTaker(labeller, props, env)
            self.shared_pairs = tuple((1 << i, 1 << team_index[p]) for i, p in enumerate(props))

    def read(
        self, obs: Any, info: dict[str, Any], reward: float | None, ended: bool
    ) -> tuple[int, int]:
        """The letters of the agent's position: its labels', and the shared labels'."""
        letter = shared = 0
        try:
            if self.labels is not None:
                letter = self.labels.take(obs, info, self.labels.moment(reward, ended))
            if self.shared is not None:
                shared = self.shared.take(obs, info, self.shared.moment(reward, ended))
        except LabelDeclarationError as err:  # the probe names paths from ``labels.``
            lines = str(err).splitlines()
            raise LabelDeclarationError(
                "\n".join(f"{self.agent}: {line}" for line in lines)
            ) from None
        return letter, shared


class TeamLetters:
    """The letters a team's tasks read (module docstring)."""

    def __init__(
        self,
        agents: Sequence[str],
        labels: Mapping[str, Labels | LabelFunction],
        own: Mapping[str, Sequence[str]],
        team: Sequence[str],
        sources: TeamSources | None,
        shared: Mapping[str, Labeller],
        team_labels: TeamLabels | None,
        env: Any,
    ) -> None:
        index = {p: i for i, p in enumerate(team)}
        self._readings: dict[str, _AgentReading] = {}
        for agent in agents:
            pairs = sources.agents.get(agent, ()) if sources is not None else ()
            props = sources.shared if sources is not None else ()
            on = (shared[agent], props) if agent in shared else None
            self._readings[agent] = _AgentReading(
                agent, labels.get(agent), own.get(agent, ()), pairs, on, index, env
            )
        self._called = tuple(sources.called) if sources is not None else ()
        self._called_bits = {p: 1 << index[p] for p in self._called}
        self._team_labels = team_labels
        self._checked = False
        self._letters: dict[str, tuple[int, int]] = {}

    def clear(self) -> None:
        """Forget every agent's letter (a reset)."""
        self._letters.clear()

    def read(
        self, agent: str, obs: Any, info: dict[str, Any], reward: float | None, ended: bool
    ) -> None:
        """Read ``agent``'s position: its ``(obs, info)``, reached by a step of ``reward``
        that ``ended`` (terminated) it in the env (``reward`` ``None``: the reset)."""
        self._letters[agent] = self._readings[agent].read(obs, info, reward, ended)

    def own(self, agent: str) -> int:
        """The letter of ``agent``'s own task at its last position read."""
        return self._letters.get(agent, (0, 0))[0] & self._readings[agent].own_mask

    def team(self, observations: dict[str, Any], infos: dict[str, Any]) -> int:
        """The team task's letter: every agent's at its last position read, and
        ``team_labels`` on ``observations`` and ``infos`` (each agent's last)."""
        letter = 0
        for agent, (read, shared) in self._letters.items():
            reading = self._readings[agent]
            letter |= _moved(read, reading.team) | _moved(shared, reading.shared_pairs)
        if self._team_labels is not None:
            result = self._team_labels(observations, infos)
            if not self._checked:
                self._checked = True
                check_result(self._team_labels, result)
            names = true_names(self._team_labels, result)
            for name, bit in self._called_bits.items():
                if name in names:
                    letter |= bit
        return letter
