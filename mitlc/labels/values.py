"""Labels over what the env *is* and what its last step *did*, not only what it shows: a value
read from a dotted path (an attribute of ``env.unwrapped``, a key of nested ``info``) or from
the step just taken (its reward, whether it terminated), then tested (truthy, ``equals``,
``in``, ``below``/``above``, a ``box`` or ``disc`` over a vector value).

A form here is a :class:`Value`: a *source* and a *test*. Each source reads from the
:class:`Moment` of a position, what the task wrapper knows beside ``(obs, info)``: the env
(``env.unwrapped``), and, for a position reached by a step, that step's reward and whether it
terminated the env (``None`` and ``False`` at the position ``reset`` gives). A value that cannot
be read at run time (a missing key, an attribute of ``None``, an index past the end) makes the
form false, as a missing ``info`` key always has; at set-up the paths are checked against the
env (:mod:`mitlc.labels.probe`).

Paths are data, never code: each step is a public attribute name (no leading ``_``), a mapping
key, or an ``[index]``; nothing is called. An attribute is read as
:func:`inspect.getattr_static` finds it, never through ``getattr``: a value in the object's
``__dict__`` or a ``__slots__`` field, or a plain class attribute (data); a property, a method
or any other descriptor (whose reading would run code: a generator seeded on first read, an
import) is not read (:func:`attribute`), and :mod:`mitlc.labels.probe` names it at set-up.
"""

from __future__ import annotations

import inspect
import math
import re
import types
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np


class Moment(NamedTuple):
    """What labels may read at a position beside ``(obs, info)``."""

    env: Any = None
    """The env itself (``env.unwrapped``), for ``attr`` paths."""
    reward: float | None = None
    """The reward of the step that reached the position (``None``: no step, the first
    position)."""
    terminated: bool = False
    """Whether that step terminated the env."""


NO_MOMENT = Moment()
"""A position known only by ``(obs, info)``: every ``attr`` and event form is false there."""

MISSING: Any = object()
"""What a source gives when its value cannot be read."""

_STEP = re.compile(r"([^.\[\]]+)|\[(-?\d+)\]|(\.)|\[([A-Za-z][A-Za-z0-9_]*)=([^\[\]=]+)\]")
PUBLIC = re.compile(r"[A-Za-z][A-Za-z0-9_]*\Z")


class Select(NamedTuple):
    """A step ``[name=value]``: the first entry of a list or tuple whose ``name`` (an attribute
    or a key) reads as ``value`` (MiniGrid's ``grid.grid[type=key]``: the key on the grid)."""

    name: str
    value: str


Step = str | int | Select
"""A step of a path: a name (an attribute or a mapping key), an index or a selection."""

MAX_SELECT = 1 << 20
"""A selection looks at no more entries than this (a bound on its time)."""


def parse_path(text: str) -> tuple[Step, ...]:
    """``"grid.grid[23].is_open"`` as ``("grid", "grid", 23, "is_open")`` (and
    ``grid.grid[type=key]`` with a :class:`Select`); a ``ValueError`` saying what is wrong
    with a malformed path."""
    if not isinstance(text, str) or not text:
        raise ValueError("expected a dotted path such as rewards.arrived_reward")
    steps: list[Step] = []
    position, dot = 0, True  # a name may follow the start or a dot
    while position < len(text):
        match = _STEP.match(text, position)
        if match is None:
            raise ValueError(f"cannot read {text!r} at character {position + 1}")
        name, index, sep, field, wanted = match.groups()
        if field is not None:
            if dot and steps:
                raise ValueError(f"a '.' before '[' in {text!r}")
            steps.append(Select(field, wanted.strip()))
            dot = False
        elif sep:
            if dot:
                raise ValueError(f"an empty step in {text!r}")
            dot = True
        elif index is not None:
            if dot and steps:
                raise ValueError(f"a '.' before '[' in {text!r}")
            steps.append(int(index))
            dot = False
        else:
            if not dot:
                raise ValueError(f"expected '.' before {name!r} in {text!r}")
            steps.append(name)
            dot = False
        position = match.end()
    if dot:
        raise ValueError(f"{text!r} ends with '.'")
    if not steps or not isinstance(steps[0], str):
        raise ValueError(f"{text!r} must start with a name")
    return tuple(steps)


def show_path(steps: Sequence[Step]) -> str:
    """A path as written: names joined by dots, indices and selections in brackets."""
    out = ""
    for step in steps:
        if isinstance(step, Select):
            out += f"[{step.name}={step.value}]"
        else:
            out += f"[{step}]" if isinstance(step, int) else (f".{step}" if out else step)
    return out


class Code(NamedTuple):
    """What an attribute holds where reading it would run code: its kind (``property``,
    ``method``, ``descriptor``)."""

    kind: str


_METHODS = (types.FunctionType, types.BuiltinFunctionType, types.MethodType,
            types.MethodDescriptorType, types.WrapperDescriptorType,
            types.ClassMethodDescriptorType, staticmethod, classmethod)  # fmt: skip


def attribute(value: Any, name: str) -> Any:
    """The attribute ``name`` of ``value`` if it is data (:data:`MISSING` if there is none, a
    :class:`Code` if reading it would run code), found without running any
    (:func:`inspect.getattr_static`): a value of the instance (its ``__dict__``, a ``__slots__``
    field), or a class attribute that is not a descriptor."""
    if not PUBLIC.match(name):
        return MISSING
    try:
        found = inspect.getattr_static(value, name, MISSING)
    except Exception:  # an odd object (a class whose __dict__ is itself code)
        return MISSING
    if found is MISSING:
        return MISSING
    if isinstance(found, types.MemberDescriptorType):  # a __slots__ field: the C getter
        try:
            return found.__get__(value, type(value))
        except Exception:  # a slot not set, or read on the class
            return MISSING
    if isinstance(found, property | types.GetSetDescriptorType):
        return Code("property")
    if isinstance(found, _METHODS):
        return Code("method")
    if _in_instance(value, name):
        return found  # data the instance holds, whatever it is
    if hasattr(type(found), "__get__"):
        return Code("descriptor")
    return found


def _in_instance(value: Any, name: str) -> bool:
    """Whether ``name`` is a key of the instance's own ``__dict__``."""
    try:
        own = object.__getattribute__(value, "__dict__")
    except AttributeError:
        return False
    return isinstance(own, dict) and name in own


def step_into(value: Any, step: Step, attributes: bool) -> Any:
    """One step of a path from ``value`` (:data:`MISSING` where there is nothing, or where
    it cannot be read as data): a mapping's key, a sequence's index, or (``attributes``) a
    public attribute that holds data (:func:`attribute`)."""
    if value is None:
        return MISSING
    if isinstance(step, Select):
        return _select(value, step, attributes)
    try:
        if isinstance(step, int):
            if isinstance(value, Mapping | Sequence | np.ndarray) and not isinstance(value, str):
                return value[step]
            return MISSING
        if isinstance(value, Mapping):
            return value.get(step, MISSING)
    except Exception:  # an index out of range, a key missing, a container's own error
        return MISSING
    if attributes:
        found = attribute(value, step)
        return MISSING if isinstance(found, Code) else found
    return MISSING


def _select(value: Any, step: Select, attributes: bool) -> Any:
    """The first entry of ``value`` (a list or a tuple) whose ``step.name`` reads as
    ``step.value`` (compared as text), among its first :data:`MAX_SELECT`."""
    if not isinstance(value, list | tuple):
        return MISSING
    for entry in value[:MAX_SELECT]:
        found = step_into(entry, step.name, attributes)
        if found is not MISSING and str(plain(found)) == step.value:
            return entry
    return MISSING


def follow(root: Any, steps: Sequence[Step], attributes: bool) -> Any:
    """The value at ``steps`` from ``root`` (:data:`MISSING` if any step finds nothing)."""
    value = root
    for step in steps:
        value = step_into(value, step, attributes)
        if value is MISSING:
            return MISSING
    return value


# -- sources -----------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class AttrPath:
    """A value on the env: ``env.unwrapped`` then each step of ``steps``."""

    steps: tuple[Step, ...]

    def read(self, obs: Any, info: Mapping[str, Any], moment: Moment) -> Any:
        """The value, or :data:`MISSING`."""
        return MISSING if moment.env is None else follow(moment.env, self.steps, True)


@dataclass(frozen=True, slots=True)
class InfoPath:
    """A value in nested ``info``: each step a key (or an index into a list)."""

    steps: tuple[Step, ...]

    def read(self, obs: Any, info: Mapping[str, Any], moment: Moment) -> Any:
        """The value, or :data:`MISSING`."""
        return follow(info, self.steps, False)


@dataclass(frozen=True, slots=True)
class StepReward:
    """The reward of the step that reached the position (an event of the transition)."""

    def read(self, obs: Any, info: Mapping[str, Any], moment: Moment) -> Any:
        """The reward, or :data:`MISSING` at the first position."""
        return MISSING if moment.reward is None else moment.reward


@dataclass(frozen=True, slots=True)
class StepTerminated:
    """Whether the step that reached the position terminated the env."""

    def read(self, obs: Any, info: Mapping[str, Any], moment: Moment) -> Any:
        """True or False."""
        return moment.terminated


Source = AttrPath | InfoPath | StepReward | StepTerminated


# -- tests -------------------------------------------------------------------------------------


def plain(value: Any) -> Any:
    """``value`` as YAML would spell it: numpy scalars as numbers, arrays and tuples as lists."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, tuple | list):
        return [plain(v) for v in value]
    return value


def vector(value: Any) -> np.ndarray[Any, Any] | None:
    """A finite float vector of ``value`` (flattened), or ``None`` if it is not numbers."""
    try:
        array = np.asarray(value, dtype=np.float64).ravel()
    except (TypeError, ValueError):
        return None
    return array if np.all(np.isfinite(array)) else None


def number(value: Any) -> float | None:
    """``value`` as a float if it is one real number (a bool is not), else ``None``."""
    if isinstance(value, bool | np.bool_):
        return None
    if isinstance(value, int | float | np.integer | np.floating):
        x = float(value)
        return x if not math.isnan(x) else None
    if isinstance(value, np.ndarray) and value.size == 1 and value.dtype.kind in "iuf":
        return float(value.reshape(()))
    return None


@dataclass(frozen=True, slots=True)
class Truthy:
    """The value is true: Python's truth, and for an array, any entry nonzero."""

    def __call__(self, value: Any) -> bool:
        """Whether it holds."""
        if isinstance(value, np.ndarray):
            return bool(np.any(value))
        return bool(value)


@dataclass(frozen=True, slots=True)
class Equals:
    """The value equals ``expected`` (numbers by value, vectors entry by entry)."""

    expected: Any

    def __call__(self, value: Any) -> bool:
        """Whether it holds."""
        return bool(plain(value) == self.expected)


@dataclass(frozen=True, slots=True)
class OneOf:
    """The value equals one of ``options``."""

    options: tuple[Any, ...]

    def __call__(self, value: Any) -> bool:
        """Whether it holds."""
        found = plain(value)
        return any(found == option for option in self.options)


@dataclass(frozen=True, slots=True)
class Bound:
    """A number strictly ``below`` or ``above`` a threshold (both when both are given)."""

    below: float | None = None
    above: float | None = None

    def __call__(self, value: Any) -> bool:
        """Whether it holds."""
        x = number(value)
        if x is None:
            return False
        return (self.below is None or x < self.below) and (self.above is None or x > self.above)


@dataclass(frozen=True, slots=True)
class Region:
    """The vector value (flattened) at ``index`` (every entry when empty) lies in a closed box
    (``low``/``high``) or a closed disc (``center``/``radius``)."""

    index: tuple[int, ...]
    low: tuple[float, ...] = ()
    high: tuple[float, ...] = ()
    center: tuple[float, ...] = ()
    radius: float = -1.0

    @property
    def size(self) -> int:
        """How many entries the region reads."""
        return len(self.low or self.center)

    def point(self, value: Any) -> np.ndarray[Any, Any] | None:
        """The entries of ``value`` the region reads (``None`` where it has too few)."""
        x = vector(value)
        if x is None:
            return None
        if self.index:
            return x[list(self.index)] if max(self.index) < len(x) else None
        return x if len(x) == self.size else None

    def __call__(self, value: Any) -> bool:
        """Whether it holds."""
        x = self.point(value)
        if x is None:
            return False
        if self.radius >= 0.0:
            return float(np.sum((x - np.asarray(self.center)) ** 2)) <= self.radius**2
        return bool(np.all((np.asarray(self.low) <= x) & (x <= np.asarray(self.high))))


Test = Truthy | Equals | OneOf | Bound | Region


@dataclass(frozen=True, slots=True)
class Value:
    """A form: the ``source``'s value passes ``test`` (false where it cannot be read)."""

    source: Source
    test: Test

    def holds(self, obs: Any, info: Mapping[str, Any], moment: Moment = NO_MOMENT) -> bool:
        """Whether the form holds."""
        value = self.source.read(obs, info, moment)
        return value is not MISSING and self.test(value)
