"""Declarations of the forms that read a value (:mod:`mitlc.labels.values`), compiled with
errors that name the field's path::

    has_key:  {attr: carrying.type, equals: key}        # an attribute of env.unwrapped
    at_door:  {attr: agent_pos, in: [[2, 1], [2, 2]]}
    near:     {attr: agent_pos, box: {low: [1, 1], high: [2, 2]}}
    arrived:  {info: rewards.arrived_reward}             # truthy
    fast:     {info: speed, above: 8}
    cliff:    {reward: {below: -50}}                     # an event of the step just taken
    ended:    {terminated: true}

``attr`` and ``info`` take a dotted path and at most one test: none (truthy), ``equals: v``,
``in: [v, ...]``, ``below: x`` and/or ``above: x`` (strict), ``box: {low, high}`` or ``disc:
{center, radius}`` over the value read as a vector (``index`` picks its entries, default all).
``reward`` takes a mapping of the tests of a number (``below``, ``above``, ``equals``, ``in``);
``terminated`` takes ``true``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from mitlc.labels.forms import LabelDeclarationError
from mitlc.labels.values import (
    PUBLIC,
    AttrPath,
    Bound,
    Equals,
    InfoPath,
    OneOf,
    Region,
    Step,
    StepReward,
    StepTerminated,
    Test,
    Truthy,
    Value,
    parse_path,
)

PATHS = ("attr", "info")
EVENTS = ("reward", "terminated")
VALUE_FORMS = PATHS + EVENTS
"""The keys that make a declaration a form reading a value."""
TESTS = ("equals", "in", "below", "above", "box", "disc")
"""The tests of a value read from a path."""
NUMBER_TESTS = ("below", "above", "equals", "in")
"""The tests of the step's reward."""


def _fail(path: str, message: str) -> LabelDeclarationError:
    return LabelDeclarationError(f"{path}: {message}")


def value_form(declaration: Mapping[str, Any], path: str) -> Value:
    """A declaration with ``attr``, ``info``, ``reward`` or ``terminated`` compiled."""
    kinds = [k for k in declaration if k in VALUE_FORMS]
    if len(kinds) != 1:
        raise _fail(path, f"expected one of {', '.join(VALUE_FORMS)}, got {', '.join(kinds)}")
    kind = kinds[0]
    where = f"{path}.{kind}"
    rest = {k: v for k, v in declaration.items() if k != kind}
    if any(k in rest for k in ("obs", "decoded", "key")):
        raise _fail(path, f"expected exactly one of the forms (got {', '.join(declaration)})")
    if kind == "terminated":
        if rest:
            raise _fail(f"{path}.{next(iter(rest))}", "terminated takes no test")
        if declaration[kind] is not True:
            raise _fail(where, "expected true (write !p in the task for its negation)")
        return Value(StepTerminated(), Truthy())
    if kind == "reward":
        if rest:
            raise _fail(f"{path}.{next(iter(rest))}", "put the reward's tests inside: "
                        "{reward: {below: -50}}")  # fmt: skip
        body = declaration[kind]
        if not isinstance(body, Mapping) or not body:
            raise _fail(where, f"expected a mapping of tests ({', '.join(NUMBER_TESTS)})")
        if unknown := [k for k in body if k not in NUMBER_TESTS]:
            raise _fail(where, f"unknown test {unknown[0]!r} (expected {', '.join(NUMBER_TESTS)})")
        return Value(StepReward(), _test(body, where, NUMBER_TESTS))
    steps = _path(declaration[kind], where, kind == "attr")
    if unknown := [k for k in rest if k not in TESTS]:
        raise _fail(f"{path}.{unknown[0]}",
                    f"unknown test (expected one of {', '.join(TESTS)})")  # fmt: skip
    source = AttrPath(steps) if kind == "attr" else InfoPath(steps)
    return Value(source, _test(rest, path, TESTS))


def _path(text: Any, where: str, attributes: bool) -> tuple[Step, ...]:
    if not isinstance(text, str):
        raise _fail(where, "expected a dotted path such as agent_pos or rewards.arrived_reward")
    try:
        steps = parse_path(text)
    except ValueError as err:
        raise _fail(where, str(err)) from None
    if attributes:
        for step in steps:
            if isinstance(step, str) and not PUBLIC.match(step):
                raise _fail(where, f"{step!r} is not a public attribute name (letters, digits "
                            "and _, not starting with _)")  # fmt: skip
    return steps


def _test(tests: Mapping[str, Any], path: str, allowed: Sequence[str]) -> Test:
    """The one test of ``tests`` (truthy when there is none; ``below`` with ``above`` is one)."""
    given = [k for k in allowed if k in tests]
    if not given:
        return Truthy()
    if set(given) == {"below", "above"} or (len(given) == 1 and given[0] in ("below", "above")):
        bounds = {k: _number(tests[k], f"{path}.{k}") for k in given}
        return Bound(bounds.get("below"), bounds.get("above"))
    if len(given) > 1:
        raise _fail(path, f"give one test, not {' and '.join(given)}")
    kind = given[0]
    body, where = tests[kind], f"{path}.{kind}"
    if kind == "equals":
        return Equals(_yaml_value(body, where))
    if kind == "in":
        if not isinstance(body, list) or not body:
            raise _fail(where, "expected a non-empty list of values")
        return OneOf(tuple(_yaml_value(v, f"{where}[{i}]") for i, v in enumerate(body)))
    return _region(body, where, kind)


def _region(body: Any, where: str, kind: str) -> Region:
    fields = ("low", "high") if kind == "box" else ("center", "radius")
    if not isinstance(body, Mapping):
        raise _fail(where, f"expected a mapping with {', '.join(fields)} (and index)")
    if unknown := [k for k in body if k not in (*fields, "index")]:
        raise _fail(where, f"unknown field {unknown[0]!r} (expected {', '.join(fields)}, index)")
    for name in fields:
        if name not in body:
            raise _fail(where, f"missing field {name!r}")
    index: tuple[int, ...] = ()
    if "index" in body:
        raw = body["index"]
        if (not isinstance(raw, list) or not raw
                or not all(_is_int(i) and i >= 0 for i in raw)):  # fmt: skip
            raise _fail(f"{where}.index", "expected a non-empty list of non-negative integers")
        index = tuple(int(i) for i in raw)
    first = _numbers(body[fields[0]], f"{where}.{fields[0]}")
    if index and len(first) != len(index):
        raise _fail(f"{where}.{fields[0]}", f"expected {len(index)} numbers, one per index")
    if kind == "box":
        high = _numbers(body["high"], f"{where}.high")
        if len(high) != len(first):
            raise _fail(f"{where}.high", f"expected {len(first)} numbers, as low has")
        if any(lo > hi for lo, hi in zip(first, high, strict=True)):
            raise _fail(where, "low is above high")
        return Region(index, low=first, high=high)
    radius = _number(body["radius"], f"{where}.radius")
    if radius < 0:
        raise _fail(f"{where}.radius", "expected a non-negative number")
    return Region(index, center=first, radius=radius)


def _is_int(x: Any) -> bool:
    return isinstance(x, int | np.integer) and not isinstance(x, bool | np.bool_)


def _number(x: Any, where: str) -> float:
    if isinstance(x, bool) or not isinstance(x, int | float) or not math.isfinite(x):
        raise _fail(where, "expected a finite number")
    return float(x)


def _numbers(values: Any, where: str) -> tuple[float, ...]:
    if not isinstance(values, list) or not values:
        raise _fail(where, "expected a non-empty list of finite numbers")
    return tuple(_number(v, where) for v in values)


def _yaml_value(value: Any, where: str) -> Any:
    """A value to compare with: a YAML scalar or a list of them (as :func:`plain` spells a
    value read from the env)."""
    if value is None or isinstance(value, bool | int | str):
        return value
    if isinstance(value, float):
        if math.isnan(value):
            raise _fail(where, "nan equals nothing")
        return value
    if isinstance(value, list | tuple):
        return [_yaml_value(v, where) for v in value]
    raise _fail(where, f"expected a number, a string, a bool or a list of them, got "
                f"{type(value).__name__}")  # fmt: skip


__all__ = ["VALUE_FORMS", "value_form"]


GUIDE = "toward"
"""The key of a form's guide for shaping: ``toward: {from: {attr: ...}, to: {attr: ...}}``."""


def guide(body: Any, path: str) -> tuple[AttrPath | InfoPath, AttrPath | InfoPath]:
    """A form's ``toward`` compiled: the source of where the agent is (``from``) and of where
    the form's proposition can be made true (``to``), each an ``attr`` or ``info`` path."""
    where = f"{path}.{GUIDE}"
    if not isinstance(body, Mapping) or set(body) != {"from", "to"}:
        raise _fail(where, "expected {from: {attr: PATH}, to: {attr: PATH}} (or info: PATH)")
    ends = []
    for end in ("from", "to"):
        source, at = body[end], f"{where}.{end}"
        if not isinstance(source, Mapping) or len(source) != 1 or next(iter(source)) not in PATHS:
            raise _fail(at, "expected {attr: PATH} or {info: PATH}")
        kind = next(iter(source))
        steps = _path(source[kind], f"{at}.{kind}", kind == "attr")
        ends.append(AttrPath(steps) if kind == "attr" else InfoPath(steps))
    return ends[0], ends[1]
