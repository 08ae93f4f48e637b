"""A finite env whose labels read the step's events (``{reward: {below: -50}}``,
``{terminated: true}``), as a world: its states split by what the step into them did.

In CliffWalking a step into the cliff returns the agent to the start with reward -100: the
cliff is never a state the env is in, only an event of a transition. A world's letters are
per state, so each state of the world here is a triple ``(observation, letter, ended)``: the
env's observation, the letter read there after the step that reached it (the labels of the
observation and of the step's reward and termination: :mod:`mitlc.labels.values`, the same
definition the task wrapper reads), and whether that step terminated the env. The start states
are the env's start observations with the letter of no step (an event form is false there).

The triples are found from the start by breadth-first search over the transition table, in
the order of the table's rows and entries, so the numbering is deterministic. As everywhere in
:mod:`mitlc.worlds.gym_world`, *an ending is absorbing*: every action of an ended state loops
to it, and the world keeps reading its letter, as the wrapper keeps reading the last letter of
an env that has ended. Splitting by ``ended`` also removes the conversion's one refusal (a
state entered both with and without the episode ending).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from mitlc.labels.values import Moment


@dataclass(frozen=True, slots=True)
class EventStates:
    """The split world's parts: per state its observation, letter and next-state
    distributions (row ``s * m + a``), and the start."""

    observation: tuple[int, ...]
    letters: tuple[int, ...]
    rows: list[dict[int, float]]
    start: int
    start_distribution: tuple[tuple[int, float], ...]


def split_by_events(
    table: Any,
    m: int,
    read: Callable[[int, Moment], int],
    starts: Sequence[tuple[int, float]],
    entry: Callable[[Any], tuple[float, int, float, bool]],
    limit: int,
) -> EventStates:
    """The states ``(observation, letter, ended)`` reachable from ``starts`` (observations and
    their probabilities) through ``table[s][a]`` (toy-text's ``P``, each entry read by
    ``entry`` as ``(probability, next, reward, terminated)``); ``read(obs, moment)`` is the
    letter. A ``ValueError`` past ``limit`` states."""
    index: dict[tuple[int, int, bool], int] = {}
    keys: list[tuple[int, int, bool]] = []

    def state(key: tuple[int, int, bool]) -> int:
        found = index.get(key)
        if found is None:
            if len(keys) >= limit:
                raise ValueError(f"more than {limit:,} states once split by the step's events")
            found = index[key] = len(keys)
            keys.append(key)
        return found

    first = [(state((s, read(s, Moment()), False)), p) for s, p in starts]
    rows: list[dict[int, float]] = []
    done = 0
    while done < len(keys):
        s, _, ended = keys[done]
        here = done
        done += 1
        for a in range(m):
            if ended:
                rows.append({here: 1.0})
                continue
            row: dict[int, float] = {}
            for item in table[s][a]:
                prob, target, reward, terminated = entry(item)
                if prob > 0.0:
                    letter = read(target, Moment(None, reward, terminated))
                    t = state((target, letter, terminated))
                    row[t] = row.get(t, 0.0) + prob
            rows.append(row)
    distribution = tuple(first) if len(first) > 1 else ()
    start = min(first, key=lambda pair: (-pair[1], pair[0]))[0]
    return EventStates(
        observation=tuple(k[0] for k in keys),
        letters=tuple(k[1] for k in keys),
        rows=rows,
        start=start,
        start_distribution=distribution,
    )
