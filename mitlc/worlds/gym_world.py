"""Finite gymnasium environments as worlds: a world file with ``env:`` in place of ``grid:``.

A world file may name a registered gymnasium environment and label its discrete observations::

    name: frozenlake-4x4
    env: {id: FrozenLake-v1, kwargs: {is_slippery: true, map_name: 4x4}}
    labels:
      goal: {obs: [15]}
      hole: {obs: [5, 7, 11, 12]}
    spec: {formula: "!hole U[0,30] goal"}
    horizon: 40

An environment is *finite* when its ``env.unwrapped`` exposes the toy-text transition table
``P[s][a]``, a list of ``(probability, next_state, reward, terminated)``, and the distribution
of its first state, ``initial_state_distrib`` (FrozenLake, Taxi and CliffWalking do). Such an
environment becomes a :class:`~mitlc.worlds.model.World`, so that the exact checker and the
tabular learner read it as they read a grid:

* the states are the env's discrete observations ``0 .. n-1``; the actions its ``Discrete``
  actions, named by the file's ``actions:`` list, else by :data:`ACTION_NAMES` (FrozenLake:
  left, down, right, up; Taxi: south, north, east, west, pickup, dropoff), else ``a0, a1, ...``;
* the transitions are ``P``'s, with the probabilities of a repeated next state summed (the
  env's rewards are not used: the task's rewards come from the world file);
* **an ending is absorbing.** A state that a step flagged ``terminated`` enters is where
  toy-text ends the episode; here every action of such a state loops to it with probability
  1, so the task monitor keeps reading that state's letter for the rest of the episode (a
  FrozenLake hole stays a hole, a Taxi drop-off stays delivered). The conversion refuses an
  env in which a reachable state is entered both with and without the episode ending;
* the start is ``initial_state_distrib``: ``start`` is its most probable state (the lowest id
  on ties) and ``start_distribution`` lists its states of positive probability (empty when
  there is only one, as for FrozenLake);
* ``rows``, ``cols`` and ``cells`` place the states for rendering and plots: on the env's map
  when its ``desc`` has one character per state (FrozenLake), else on one row of ``n`` cells.

Labels are declarative; nothing read from the file runs code but the import of installed
modules by name (:mod:`mitlc.worlds.env_make`: ``env.import``, ``module:EnvId``, ``wrappers``),
and only registered ids are made (``gymnasium.make(id, **kwargs)``, the arguments YAML scalars,
lists and mappings naming no file: :mod:`mitlc.worlds.trust`). The labels of a finite world:

* ``{obs: [5, 7]}`` holds in the listed observations;
* ``{decoded: {radices: [5, 5, 5, 4], fields: [row, col, passenger, destination], where:
  {passenger: [4]}}}`` reads the state id as a mixed-radix number, the first field most
  significant (as Taxi's ``decode``), and holds where every field named under ``where`` has one
  of the listed values; a field's entry may instead name another field, and then holds where the
  two are equal (``{passenger: destination}``).

gymnasium is imported only for a file with ``env:``, and its warnings are silenced while the
env is made. gymnasium 1.x registers ``Taxi-v4`` (``Taxi-v3`` is gone) and ``CliffWalking-v1``.
An env without ``P`` (CartPole, Blackjack) cannot be converted: :func:`require_finite` says it
is not a finite world (it can be learned through :class:`mitlc.gym.TaskWrapper`).
"""

from __future__ import annotations

import math
import operator
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from mitlc.errors import MitlcError
from mitlc.labels.values import Moment
from mitlc.limits import MAX_GRID_CELLS
from mitlc.worlds import env_make
from mitlc.worlds.env_make import ENV_ID
from mitlc.worlds.env_schema import DecodedLabel, Decoding, Env, EnvWorldFile, ObsLabel
from mitlc.worlds.grid import FieldPath, Found, render
from mitlc.worlds.gym_events import EventStates, split_by_events
from mitlc.worlds.gym_uncertain import Interned, chance_read, drawn_states, observation_kinds
from mitlc.worlds.model import IntArray, Sparse, World
from mitlc.worlds.schema import show

ACTION_NAMES: dict[str, tuple[str, ...]] = {
    "FrozenLake": ("left", "down", "right", "up"),
    "Taxi": ("south", "north", "east", "west", "pickup", "dropoff"),
}
"""The names of the actions of known environments, by the env's name (its id without the
version)."""

MAX_ENV_STATES = MAX_GRID_CELLS
"""The most observations of an env converted to a world (as many as a grid's cells)."""

TOLERANCE = 1e-9
"""How far from 1 a distribution of the env (a row of ``P``, the start) may sum."""


class GymWorldError(MitlcError):
    """What is wrong with an env world: each problem as (the field's path, a message). The
    loader (:func:`mitlc.worlds.load.load_world`) shows them at their lines in the file."""

    def __init__(self, found: Found) -> None:
        self.found = list(found)
        super().__init__("\n".join(f"{render(p)}: {m}" if p else m for p, m in self.found))


class NotFiniteError(GymWorldError):
    """The env has no transition table (or no start distribution): it cannot be checked."""


# --- checks of the file alone ---------------------------------------------------------------


def check_file(file: EnvWorldFile) -> Found:
    """What is wrong with an env world file, short of making the env: the ``kwargs`` values,
    repeated action names and observations, and each decoding (as many fields as radices,
    fields named once, ``where`` naming known fields with values in range), and the rows of an
    ``occupancy:`` grid."""
    found: Found = []
    for key, value in file.env.kwargs.items():
        _yaml_value(value, ("env", "kwargs", key), found)
    for i, entry in enumerate(file.env.wrappers):
        for key, value in getattr(entry, "kwargs", {}).items():
            _yaml_value(value, ("env", "wrappers", i, "kwargs", key), found)
    if file.actions is not None:
        _once(("actions",), "action", file.actions, found)
    for name, label in file.labels.items():
        where: FieldPath = ("labels", name)
        if isinstance(label, ObsLabel):
            _once((*where, "obs"), "observation", label.obs, found)
        elif isinstance(label, DecodedLabel):
            _check_decoding((*where, "decoded"), label.decoded, found)
        else:
            found.extend(form_problems({name: label}, None))
    if file.occupancy is not None:
        _check_occupancy(file.occupancy.cells, found)
    return found


def _check_occupancy(cells: Sequence[Sequence[int]], found: Found) -> None:
    """The rows of an ``occupancy:`` grid: each as long as the first, at most
    :data:`~mitlc.limits.MAX_GRID_CELLS` cells."""
    for i, row in enumerate(cells):
        if len(row) != len(cells[0]):
            found.append((("occupancy", "cells", i), f"a row of {len(row)} cells, where the "
                          f"first has {len(cells[0])}: the rows must be as long"))  # fmt: skip
    if len(cells) * len(cells[0]) > MAX_GRID_CELLS:
        found.append((("occupancy", "cells"), f"more than {MAX_GRID_CELLS} cells"))


def declarations(labels: Mapping[str, Any]) -> dict[str, Any]:
    """An env world file's labels as :mod:`mitlc.labels` declarations (plain data)."""
    return {p: v.model_dump() if isinstance(v, ObsLabel | DecodedLabel) else v
            for p, v in labels.items()}  # fmt: skip


def form_problems(labels: Mapping[str, Any], space: Any) -> Found:
    """What :func:`mitlc.labels.compile_labels` finds wrong with ``labels`` (checked against
    ``space`` when given), as the field path and the message (its first problem)."""
    from mitlc.labels import LabelDeclarationError, compile_labels

    try:
        compile_labels(declarations(labels), space)
    except LabelDeclarationError as err:
        return [field_problem(str(err))]
    return []


_STEP = re.compile(r"\.([A-Za-z_][A-Za-z0-9_]*)|\[(\d+)\]")


def field_problem(message: str) -> tuple[FieldPath, str]:
    """``"labels.goal[0].box: expected ..."`` as ``(("labels", "goal", 0, "box"), "expected
    ...")``."""
    where, _, text = message.partition(": ")
    head, _, rest = where.partition(".")
    path: list[str | int] = [head]
    for name, index in _STEP.findall("." + rest if rest else ""):
        path.append(int(index) if index else name)
    return tuple(path), text


def _yaml_value(value: object, path: FieldPath, found: Found) -> None:
    """A problem unless ``value`` is a YAML scalar (null, bool, number, string), a list or a
    mapping with string keys of such values."""
    if value is None or isinstance(value, bool | int | str):
        return
    if isinstance(value, float):
        if not math.isfinite(value):
            found.append((path, f"expected a finite number, got {show(value)}"))
    elif isinstance(value, list):
        for i, item in enumerate(value):
            _yaml_value(item, (*path, i), found)
    elif isinstance(value, dict):
        for key, item in value.items():
            if not isinstance(key, str):
                found.append((path, f"expected string keys, got {show(key)}"))
            else:
                _yaml_value(item, (*path, key), found)
    else:
        found.append((path, f"expected a YAML scalar, list or mapping, got {show(value)}"))


def _once(path: FieldPath, noun: str, items: Sequence[object], found: Found) -> None:
    """A problem for each item listed again."""
    first: dict[object, int] = {}
    for i, item in enumerate(items):
        if item in first:
            also = render((*path, first[item]))
            found.append(((*path, i), f"{noun} {show(item)} is listed twice (also {also})"))
        first.setdefault(item, i)


def _check_decoding(path: FieldPath, decoding: Decoding, found: Found) -> None:
    radices, fields = decoding.radices, decoding.fields
    if len(fields) != len(radices):
        found.append(
            ((*path, "fields"), f"{len(fields)} fields for {len(radices)} radices: give one each")
        )
    _once((*path, "fields"), "field", fields, found)
    radix = dict(zip(fields, radices, strict=False))
    known = ", ".join(fields)
    for field, condition in decoding.where.items():
        at: FieldPath = (*path, "where", field)
        if field not in radix:
            found.append((at, f"unknown field {show(field)} (fields: {known})"))
        elif isinstance(condition, str):
            if condition not in radix:
                found.append((at, f"unknown field {show(condition)} (fields: {known})"))
            elif condition == field:
                found.append((at, "a field equal to itself: name another field or list values"))
        else:
            for i, value in enumerate(condition):
                if value >= radix[field]:
                    found.append(
                        (
                            (*at, i),
                            f"value {value} is outside the field's {radix[field]} values "
                            f"(0 to {radix[field] - 1})",
                        )
                    )


# --- making the env --------------------------------------------------------------------------


def make_env(settings: Env, folder: Path | None = None) -> Any:
    """The env ``settings`` names, made (:func:`mitlc.worlds.env_make.make_env`: installed
    modules imported by name, none from the current directory or the world file's ``folder``,
    registered ids only, the listed wrappers applied); a :class:`GymWorldError` at the field at
    fault if it cannot be."""
    try:
        return env_make.make_env(settings, folder)
    except env_make.EnvMakeError as err:
        raise GymWorldError(err.found) from None


_reason = env_make.reason


def is_finite(env: Any) -> bool:
    """Whether ``env`` (a gymnasium env) exposes a transition table ``env.unwrapped.P``."""
    return isinstance(getattr(env.unwrapped, "P", None), Mapping | Sequence)


def require_finite(env: Any, env_id: str) -> None:
    """A :class:`NotFiniteError` unless ``env`` has a transition table (``env.unwrapped.P``)
    and a start distribution (``initial_state_distrib``), which the exact checker needs."""
    missing = None
    if not is_finite(env):
        missing = "transition table (env.unwrapped.P)"
    elif getattr(env.unwrapped, "initial_state_distrib", None) is None:
        missing = "start distribution (env.unwrapped.initial_state_distrib)"
    if missing is not None:
        message = (
            f"{env_id} has no {missing}: not a finite world, so there is no exact optimum to "
            "check; mitlc train learns it through the task wrapper"
        )
        raise NotFiniteError([(ENV_ID, message)])


# --- labels ---------------------------------------------------------------------------------


def _check_labels(labels: Mapping[str, Any], space: Any, found: Found) -> None:
    """The labels against the env's observation space (``n`` discrete observations)."""
    n = int(space.n)
    for name, label in labels.items():
        where: FieldPath = ("labels", name)
        if not isinstance(label, ObsLabel | DecodedLabel):
            found.extend(form_problems({name: label}, space))
            continue
        if isinstance(label, ObsLabel):
            for i, s in enumerate(label.obs):
                if s >= n:
                    found.append(
                        (
                            (*where, "obs", i),
                            f"observation {s} is outside the env's {n} (0 to {n - 1})",
                        )
                    )
            continue
        radices = label.decoded.radices
        size = math.prod(radices)
        if size != n:
            found.append(
                (
                    (*where, "decoded", "radices"),
                    f"the radices {show(radices)} encode {size:,} states, the env has {n:,} "
                    "observations",
                )
            )


def letters_of(labels: Mapping[str, Any], propositions: Sequence[str], n: int) -> IntArray:
    """``letters[s]``: the letter of state ``s`` over ``propositions`` (bit ``i`` for
    ``propositions[i]``; a proposition without a label holds nowhere), read through the one
    definition of declarative labels (:mod:`mitlc.labels`), the gymnasium wrapper's."""
    from mitlc.labels import compile_labels, letters_of_states

    declared = declarations({p: labels[p] for p in propositions if p in labels})
    letters = np.zeros(n, dtype=np.int64)
    if declared:
        named = tuple(declared)
        partial = letters_of_states(compile_labels(declared), n, named)
        for i, p in enumerate(propositions):
            if p in declared:
                letters |= ((partial >> named.index(p)) & 1) << i
    return letters


# --- the world -------------------------------------------------------------------------------


def _sources(labels: Mapping[str, Any]) -> list[tuple[str, Any]]:
    """Each label form that reads a value, as (its proposition, its source); none for labels
    that do not compile (reported where the labels are checked)."""
    from mitlc.labels import LabelDeclarationError, compile_labels

    try:
        compiled = compile_labels(declarations(labels))
    except LabelDeclarationError:
        return []
    return [(p, f.source) for p, _, f in compiled.values()]


def reads_env(labels: Mapping[str, Any]) -> str | None:
    """The first label that reads more than the observation and the step's events (an
    ``attr`` or ``info`` path), or ``None``: such labels cannot be tabulated over the states of
    a finite env, so its world is learned through the task wrapper."""
    from mitlc.labels.values import AttrPath, InfoPath

    return next((p for p, src in _sources(labels) if isinstance(src, AttrPath | InfoPath)), None)


def has_events(labels: Mapping[str, Any]) -> bool:
    """Whether any label reads the step's events (its reward, its termination)."""
    from mitlc.labels.values import StepReward, StepTerminated

    return any(isinstance(src, StepReward | StepTerminated) for _, src in _sources(labels))


def _split(
    file: EnvWorldFile,
    table: Any,
    m: int,
    propositions: Sequence[str],
    starts: Sequence[tuple[int, float]],
    drawn: Interned | None,
) -> EventStates:
    """The env's states split by the events of the steps into them (:mod:`gym_events`), each
    keeping its letter, or the number of its chances where a label is ``drawn``."""
    from mitlc.labels import compile_labels

    declared = declarations({p: file.labels[p] for p in propositions if p in file.labels})
    named = tuple(declared)
    reader = compile_labels(declared).letter_reader(named) if drawn is None else None
    bits = [(named.index(p), i) for i, p in enumerate(propositions) if p in declared]

    def read(obs: int, moment: Moment) -> int:
        if drawn is not None:
            return drawn(obs, moment)
        assert reader is not None
        partial = reader(obs, {}, moment)
        return sum(((partial >> j) & 1) << i for j, i in bits)

    def entry(item: Any) -> tuple[float, int, float, bool]:
        return float(item[0]), operator.index(item[1]), float(item[2]), bool(item[3])

    try:
        return split_by_events(table, m, read, starts, entry, MAX_ENV_STATES)
    except ValueError as err:
        raise GymWorldError([(ENV_ID, f"{file.env.id}: {err}")]) from None


def _discrete(space: Any, what: str, env_id: str) -> int:
    """The size of a ``Discrete`` space that starts at 0; a :class:`GymWorldError` if not."""
    n = getattr(space, "n", None)
    start = getattr(space, "start", 0)
    if type(space).__name__ != "Discrete" or n is None or int(start) != 0:
        raise GymWorldError(
            [(ENV_ID, f"{env_id}'s {what} space is {space}: mitlc needs Discrete(n) from 0")]
        )
    return int(n)


def action_names(file: EnvWorldFile, env: Any, m: int) -> tuple[str, ...]:
    """The names of the env's ``m`` actions: the file's, else the known ones, else ``a0 ...``;
    a :class:`GymWorldError` if the file lists another number of them."""
    if file.actions is not None:
        if len(file.actions) != m:
            raise GymWorldError(
                [
                    (
                        ("actions",),
                        f"{len(file.actions)} names for {file.env.id}'s {m} actions: give one each",
                    )
                ]
            )
        return tuple(file.actions)
    known = ACTION_NAMES.get(str(getattr(getattr(env, "spec", None), "name", "")), ())
    return known if len(known) == m else tuple(f"a{i}" for i in range(m))


def _entry(entry: Any, n: int) -> tuple[float, int, bool]:
    """A toy-text ``(probability, next_state, reward, terminated)``, checked."""
    prob, target, terminated = float(entry[0]), operator.index(entry[1]), bool(entry[3])
    if not (math.isfinite(prob) and prob >= 0.0 and 0 <= target < n):
        raise ValueError(f"({prob}, {target}, ...) is not a probability and a state below {n}")
    return prob, target, terminated


def transition_rows(
    table: Any, n: int, m: int, env_id: str
) -> tuple[list[dict[int, float]], set[int], list[set[int]]]:
    """``P`` as rows ``s * m + a`` of next-state distributions (repeated next states summed);
    the states that a step ending the episode enters; and, per row, the states it enters
    without ending the episode. A :class:`GymWorldError` for a malformed table."""
    rows: list[dict[int, float]] = []
    ending: set[int] = set()
    plain: list[set[int]] = []
    for s in range(n):
        for a in range(m):
            row: dict[int, float] = {}
            quiet: set[int] = set()
            try:
                for entry in table[s][a]:
                    prob, target, terminated = _entry(entry, n)
                    if prob > 0.0:
                        row[target] = row.get(target, 0.0) + prob
                        (ending.add if terminated else quiet.add)(target)
            except (KeyError, IndexError, TypeError, ValueError) as err:
                message = f"{env_id}'s transition table P[{s}][{a}] is malformed: {_reason(err)}"
                raise GymWorldError([(ENV_ID, message)]) from None
            total = sum(row.values())
            if abs(total - 1.0) > TOLERANCE:
                message = f"{env_id}'s transition table P[{s}][{a}] sums to {total:g}, not 1"
                raise GymWorldError([(ENV_ID, message)])
            rows.append(row)
            plain.append(quiet)
    return rows, ending, plain


def start_of(unwrapped: Any, n: int, env_id: str) -> tuple[int, tuple[tuple[int, float], ...]]:
    """The start state and the start distribution (empty for a single start state) from
    ``initial_state_distrib``."""
    try:
        dist = np.asarray(unwrapped.initial_state_distrib, dtype=np.float64)
    except (TypeError, ValueError) as err:
        message = f"{env_id}'s initial_state_distrib is not a list of numbers: {_reason(err)}"
        raise GymWorldError([(ENV_ID, message)]) from None
    if (
        dist.shape != (n,)
        or not np.all(np.isfinite(dist))
        or np.any(dist < 0)
        or abs(float(dist.sum()) - 1.0) > TOLERANCE
    ):
        message = f"{env_id}'s initial_state_distrib is not a distribution over its {n} states"
        raise GymWorldError([(ENV_ID, message)])
    pairs = tuple((s, float(dist[s])) for s in range(n) if dist[s] > 0.0)
    start = min(pairs, key=lambda pair: (-pair[1], pair[0]))[0]
    return start, pairs if len(pairs) > 1 else ()


def _absorb(
    rows: list[dict[int, float]],
    ending: set[int],
    plain: list[set[int]],
    starts: Sequence[int],
    m: int,
    env_id: str,
) -> None:
    """Make every ending state absorbing, then refuse an env in which a state reachable from
    the start is entered both with and without the episode ending."""
    for s in ending:
        for a in range(m):
            rows[s * m + a] = {s: 1.0}
    seen, todo = set(starts), list(starts)
    while todo:
        s = todo.pop()
        if s in ending:
            continue
        for a in range(m):
            both = plain[s * m + a] & ending
            if both:
                t = min(both)
                message = (
                    f"{env_id}: action {a} in state {s} enters state {t} without ending the "
                    "episode, while other steps end it there; mitlc makes a state where the "
                    "episode ends absorbing, so it cannot convert this env"
                )
                raise GymWorldError([(ENV_ID, message)])
            for t in rows[s * m + a]:
                if t not in seen:
                    seen.add(t)
                    todo.append(t)


def _layout(unwrapped: Any, n: int) -> tuple[int, int, tuple[tuple[int, int], ...]]:
    """Rows, columns and the cell of each state: the env's map (``desc``) when it has one
    character per state, else one row of ``n`` cells."""
    desc = getattr(unwrapped, "desc", None)
    if desc is not None:
        shape = np.shape(desc)
        if len(shape) == 2 and shape[0] * shape[1] == n:
            rows, cols = int(shape[0]), int(shape[1])
            return rows, cols, tuple((r, c) for r in range(rows) for c in range(cols))
    return 1, n, tuple((0, s) for s in range(n))


def build_world(
    file: EnvWorldFile,
    env: Any,
    *,
    name: str,
    spec: str,
    spec_source: str,
    propositions: tuple[str, ...],
) -> World:
    """The world of a checked env world file and its made env (see the module docstring); a
    :class:`GymWorldError` (a :class:`NotFiniteError` for an env without ``P``) if it cannot
    be converted."""
    env_id = file.env.id
    require_finite(env, env_id)
    reader = reads_env(file.labels)
    if reader is not None:
        message = ("reads the env's attributes or info, which the states of its transition "
                   "table do not have: not a finite world, so there is no exact "
                   "optimum to check; mitlc train learns it through the task wrapper")  # fmt: skip
        raise NotFiniteError([(("labels", reader), message)])
    unwrapped = env.unwrapped
    n = _discrete(env.observation_space, "observation", env_id)
    m = _discrete(env.action_space, "action", env_id)
    if n > MAX_ENV_STATES:
        raise GymWorldError(
            [(ENV_ID, f"{env_id} has {n:,} states (at most {MAX_ENV_STATES:,}, mitlc's limit)")]
        )
    found: Found = []
    _check_labels(file.labels, env.observation_space, found)
    if found:
        raise GymWorldError(found)
    if file.env.wrappers:
        message = ("a finite env is converted from its transition table, which its wrappers do "
                   "not change: list no wrappers to check it (or learn it with them through "
                   "the task wrapper: mitlc train)")  # fmt: skip
        raise GymWorldError([(("env", "wrappers"), message)])
    actions = action_names(file, env, m)
    rows, ending, plain = transition_rows(unwrapped.P, n, m, env_id)
    start, distribution = start_of(unwrapped, n, env_id)
    starts = [s for s, _ in distribution] or [start]
    grid_rows, grid_cols, cells = _layout(unwrapped, n)
    declared = declarations({p: file.labels[p] for p in propositions if p in file.labels})
    chances = chance_read(declared, propositions)
    drawn = None if chances is None else Interned(chances)  # labels with a probability
    if has_events(file.labels):
        split = _split(file, unwrapped.P, m, propositions, distribution or ((start, 1.0),), drawn)
        letters = np.asarray(split.letters, dtype=np.int64)
        rows, start, distribution = split.rows, split.start, split.start_distribution
        cells = tuple(cells[o] for o in split.observation)
    else:
        _absorb(rows, ending, plain, starts, m, env_id)
        letters = (letters_of(file.labels, propositions, n) if drawn is None
                   else np.asarray(observation_kinds(drawn, n, ending)))  # fmt: skip
    transitions = Sparse.from_rows(rows)
    if drawn is not None:  # the outcomes go into the states (mitlc.worlds.gym_uncertain)
        states = drawn_states(drawn, letters.tolist(), rows, distribution or ((start, 1.0),), m)
        letters, transitions, start = states.letters, states.transitions, states.start
        distribution, cells = states.start_distribution, tuple(cells[b] for b in states.base)
    empty = [p for i, p in enumerate(propositions) if not np.any((letters >> i) & 1)]
    if empty:
        known = ", ".join(sorted(file.labels)) or "none"
        raise GymWorldError(
            [(("spec",), f"proposition {p!r} holds in no state (labels: {known})") for p in empty]
        )
    reward = file.reward
    return World(
        name=name,
        rows=grid_rows,
        cols=grid_cols,
        cells=cells,
        actions=actions,
        start=start,
        transitions=transitions,
        propositions=propositions,
        letters=letters,
        spec=spec,
        spec_source=spec_source,
        horizon=file.horizon,
        discount=file.discount,
        rewards=reward.rewards(),
        start_distribution=distribution,
    )
