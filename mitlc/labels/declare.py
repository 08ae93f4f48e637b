"""Label declarations (plain data) compiled into forms, with errors that name the field's
path, and checked against an observation space read by its attributes (no gymnasium import;
see :mod:`mitlc.labels`)."""

from __future__ import annotations

import json
import math
import re
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from mitlc.labels.chance import CERTAIN
from mitlc.labels.declare_values import GUIDE, VALUE_FORMS, guide, value_form
from mitlc.labels.forms import (
    Decoded,
    Form,
    Guided,
    InBox,
    InDisc,
    LabelDeclarationError,
    LabelFunction,
    Labeller,
    Labels,
    ObsIn,
    letter_reader,
)
from mitlc.worlds.model import IntArray

FORMS = ("obs", "decoded", "box", "disc", "info", "attr", "reward", "terminated")
"""The declarative forms (``info``, ``attr``, ``reward`` and ``terminated`` read a value:
:mod:`mitlc.labels.declare_values`)."""

_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")


def as_labels(
    labels: Labels | LabelFunction | Mapping[str, Any], observation_space: Any = None
) -> Labels | LabelFunction:
    """Declarations compiled (:func:`compile_labels`); labels or a callable as they are."""
    if isinstance(labels, Mapping):
        return compile_labels(labels, observation_space)
    if not callable(labels):
        raise LabelDeclarationError(
            f"labels: expected a mapping of declarations or a callable, got {type(labels).__name__}"
        )
    return labels


def letters_of_states(
    labels: Labels | LabelFunction | Mapping[str, Any], n: int, propositions: Sequence[str]
) -> IntArray:
    """The letter over ``propositions`` of every observation ``0 .. n-1`` of a discrete env
    (``info`` is empty), so a finite world made from the env labels its states through the
    same definition."""
    read = letter_reader(as_labels(labels), propositions)
    return np.fromiter((read(s, {}) for s in range(n)), dtype=np.int64, count=n)


# -- parsing -----------------------------------------------------------------------------------


def compile_labels(
    declarations: Mapping[str, Any], observation_space: Any = None, *, path: str = "labels"
) -> Labeller:
    """Compile declarations (their forms: :mod:`mitlc.labels`), checked against
    ``observation_space`` when given (a gymnasium space, read by its attributes)."""
    if not isinstance(declarations, Mapping):
        raise LabelDeclarationError(
            f"{path}: expected a mapping from proposition names to label forms"
        )
    names, forms, probabilities = [], [], []
    for name, declaration in declarations.items():
        if not isinstance(name, str) or not _NAME.match(name):
            raise LabelDeclarationError(f"{path}: {name!r} is not a proposition name")
        where = f"{path}.{name}"
        if isinstance(declaration, Sequence) and not isinstance(declaration, str):
            if not declaration:
                raise LabelDeclarationError(f"{where}: expected at least one form")
            parsed = tuple(
                _perceived(d, f"{where}[{i}]", observation_space) for i, d in enumerate(declaration)
            )
        else:
            parsed = (_perceived(declaration, where, observation_space),)
        names.append(name)
        forms.append(tuple(f for f, _ in parsed))
        probabilities.append(tuple(p for _, p in parsed))
    return Labeller(tuple(names), tuple(forms), tuple(probabilities))


def _fail(path: str, message: str) -> LabelDeclarationError:
    return LabelDeclarationError(f"{path}: {message}")


PROBABILITY = "probability"
"""The key of a form's probability of being perceived (:mod:`mitlc.labels.chance`)."""


def _perceived(declaration: Any, path: str, space: Any) -> tuple[Form, float]:
    """A form and the probability that it is perceived where it holds (1 unless the
    declaration gives ``probability``)."""
    if callable(declaration):
        raise _fail(path, "expected a form, not a labelling function (a function labels every "
                    "proposition at once, labels=f, and takes no probability)")  # fmt: skip
    if not isinstance(declaration, Mapping) or PROBABILITY not in declaration:
        return _form(declaration, path, space), CERTAIN
    where = f"{path}.{PROBABILITY}"
    rest = {k: v for k, v in declaration.items() if k != PROBABILITY}
    if any(callable(v) for v in rest.values()):
        raise _fail(where, "a labelling function takes no probability: declare the label by a "
                    "form (obs, decoded, box, disc, info, attr, reward, terminated)")  # fmt: skip
    return _form(rest, path, space), probability(declaration[PROBABILITY], where)


def probability(value: Any, path: str) -> float:
    """A form's ``probability``: a number in (0, 1]; an error naming ``path`` otherwise."""
    if not _is_number(value) or not 0 < value <= 1:
        shown = json.dumps(value) if isinstance(value, str | bool) or value is None else value
        raise _fail(path, f"expected a probability in (0, 1], got {shown}")
    return float(value)


def _form(declaration: Any, path: str, space: Any) -> Form:
    if not isinstance(declaration, Mapping):
        raise _fail(path, f"expected a mapping with one of the forms {', '.join(FORMS)}")
    if GUIDE in declaration:
        origin, target = guide(declaration[GUIDE], path)
        rest = {k: v for k, v in declaration.items() if k != GUIDE}
        inner = _form(rest, path, space)
        assert not isinstance(inner, Guided), "one guide per form"
        return Guided(inner, origin, target)
    if any(k in declaration for k in VALUE_FORMS):
        return value_form(declaration, path)
    kinds = [k for k in declaration if k in FORMS]
    extra = [k for k in declaration if k not in FORMS and k != "key"]
    if extra:
        raise _fail(path, f"unknown form {extra[0]!r} (expected one of {', '.join(FORMS)})")
    if len(kinds) != 1:
        raise _fail(path, f"expected exactly one of the forms {', '.join(FORMS)}")
    kind = kinds[0]
    if "key" in declaration and kind != "obs":
        raise _fail(f"{path}.key", f"not allowed beside {kind!r} (put it inside)")
    body, where = declaration[kind], f"{path}.{kind}"
    if kind == "obs":
        key = _key(declaration.get("key"), f"{path}.key")
        values = _ints(body, where)
        if not values:
            raise _fail(where, "expected at least one value")
        n = _discrete_size(_subspace(space, key, path), where)
        if n is not None and (bad := [v for v in values if not 0 <= v - n[0] < n[1]]):
            raise _fail(where, f"{bad[0]} is outside the observation space's values")
        return ObsIn(frozenset(values), key)
    fields = _fields(body, where, _ALLOWED[kind])
    key = _key(fields.get("key"), f"{where}.key")
    sub = _subspace(space, key, where)
    if kind == "decoded":
        return _decoded(fields, where, sub, key)
    index = _ints(_required(fields, "index", where), f"{where}.index")
    if not index or any(i < 0 for i in index):
        raise _fail(f"{where}.index", "expected a non-empty list of non-negative integers")
    _check_index(index, sub, f"{where}.index")
    if kind == "box":
        low = _floats(_required(fields, "low", where), f"{where}.low", len(index))
        high = _floats(_required(fields, "high", where), f"{where}.high", len(index))
        if any(lo > hi for lo, hi in zip(low, high, strict=True)):
            raise _fail(where, "low is above high")
        return InBox(tuple(index), low, high, key)
    center = _floats(_required(fields, "center", where), f"{where}.center", len(index))
    radius = _required(fields, "radius", where)
    if not _is_number(radius) or radius < 0:
        raise _fail(f"{where}.radius", "expected a non-negative number")
    return InDisc(tuple(index), center, float(radius), key)


_ALLOWED = {
    "decoded": ("radices", "fields", "where", "key"),
    "box": ("index", "low", "high", "key"),
    "disc": ("index", "center", "radius", "key"),
}


def _decoded(fields: Mapping[str, Any], path: str, space: Any, key: str | None) -> Decoded:
    radices = _ints(_required(fields, "radices", path), f"{path}.radices")
    if not radices or any(r < 1 for r in radices):
        raise _fail(f"{path}.radices", "expected a non-empty list of positive integers")
    names = _list(_required(fields, "fields", path), f"{path}.fields", _is_str, "field names")
    if len(set(names)) != len(names):
        raise _fail(f"{path}.fields", "expected distinct field names")
    if len(names) != len(radices):
        raise _fail(f"{path}.fields", f"expected {len(radices)} names, one per radix")
    n = _discrete_size(space, path)
    if n is not None and math.prod(radices) != n[1]:
        raise _fail(
            f"{path}.radices",
            f"their product {math.prod(radices)} is not the observation space's size {n[1]}",
        )
    wanted = _required(fields, "where", path)
    if not isinstance(wanted, Mapping) or not wanted:
        raise _fail(f"{path}.where", "expected a mapping from field names to lists of values")
    checks, equal = [], []
    for name, values in wanted.items():
        if name not in names:
            raise _fail(f"{path}.where", f"unknown field {name!r} (fields: {list(names)})")
        i = names.index(name)
        field = (math.prod(radices[i + 1 :]), radices[i])
        if isinstance(values, str):  # another field's name: the two are equal
            if values not in names or values == name:
                raise _fail(f"{path}.where.{name}", f"{values!r} is not another field")
            j = names.index(values)
            equal.append((*field, math.prod(radices[j + 1 :]), radices[j]))
            continue
        allowed = _ints(values, f"{path}.where.{name}")
        if bad := [v for v in allowed if not 0 <= v < radices[i]]:
            raise _fail(f"{path}.where.{name}", f"{bad[0]} is not below the radix {radices[i]}")
        checks.append((*field, frozenset(allowed)))
    return Decoded(tuple(checks), key, tuple(equal))


def _fields(body: Any, path: str, allowed: tuple[str, ...]) -> Mapping[str, Any]:
    if not isinstance(body, Mapping):
        raise _fail(path, f"expected a mapping with {', '.join(allowed)}")
    if unknown := [k for k in body if k not in allowed]:
        raise _fail(path, f"unknown field {unknown[0]!r} (expected {', '.join(allowed)})")
    return body


def _required(fields: Mapping[str, Any], name: str, path: str) -> Any:
    if name not in fields:
        raise _fail(path, f"missing field {name!r}")
    return fields[name]


def _is_str(x: Any) -> bool:
    return isinstance(x, str)


def _key(key: Any, path: str) -> str | None:
    if key is not None and not isinstance(key, str):
        raise _fail(path, "expected the name of a part of a Dict observation")
    return key


def _is_int(x: Any) -> bool:
    return isinstance(x, int | np.integer) and not isinstance(x, bool | np.bool_)


def _is_number(x: Any) -> bool:
    return _is_int(x) or (isinstance(x, float | np.floating) and math.isfinite(x))


def _list(values: Any, path: str, ok: Callable[[Any], bool], what: str) -> list[Any]:
    if not isinstance(values, Sequence | np.ndarray) or isinstance(values, str):
        raise _fail(path, f"expected a list of {what}")
    if not all(ok(v) for v in values):
        raise _fail(path, f"expected a list of {what}")
    return list(values)


def _ints(values: Any, path: str) -> list[int]:
    return [int(v) for v in _list(values, path, _is_int, "integers")]


def _floats(values: Any, path: str, length: int) -> tuple[float, ...]:
    found = _list(values, path, _is_number, "finite numbers")
    if len(found) != length:
        raise _fail(path, f"expected {length} numbers, one per index")
    return tuple(float(v) for v in found)


# -- spaces, read by their attributes (no gymnasium import) ------------------------------------


def _subspace(space: Any, key: str | None, path: str) -> Any:
    parts = getattr(space, "spaces", None)
    if not isinstance(parts, Mapping):
        if key is not None and space is not None:
            raise _fail(f"{path}.key", "the observation space is not a Dict")
        return space
    if key is None:
        raise _fail(path, f"the observation is a Dict: name its part with key ({list(parts)})")
    if key not in parts:
        raise _fail(f"{path}.key", f"unknown part {key!r} (parts: {list(parts)})")
    return parts[key]


def _discrete_size(space: Any, path: str) -> tuple[int, int] | None:
    """``(start, n)`` of a Discrete space; an error for a space that is not discrete."""
    if space is None:
        return None
    n: Any = getattr(space, "n", None)
    start: Any = getattr(space, "start", None)
    if _is_int(n) and _is_int(start) and getattr(space, "shape", None) == ():
        return int(start), int(n)
    raise _fail(path, f"needs a Discrete observation, not {space}")


def _check_index(index: Sequence[int], space: Any, path: str) -> None:
    if space is None:
        return
    shape = getattr(space, "shape", None)
    if getattr(space, "low", None) is None or not isinstance(shape, tuple) or len(shape) != 1:
        raise _fail(path, f"needs a one-dimensional Box observation, not {space}")
    if bad := [i for i in index if i >= shape[0]]:
        raise _fail(path, f"index {bad[0]} is out of range for {space}")
