"""How far a position is from where a label holds, in the env's own space: for shaping.

A label's form that reads a vector or a number and tests it against a region or a value has a
distance: 0 where the form holds, else the Euclidean distance from the value read to the set
where it would hold.

* ``box`` (over the observation, or a value's ``box``): the distance to the closed box;
* ``disc``: the distance to the disc (to its centre, less the radius);
* a value's ``equals`` a number or a vector of numbers (an attribute position, say): the
  distance to that point;
* a value's ``below`` / ``above``: how far the number is past the threshold.

A form with a guide (``toward: {from: ..., to: ...}``) is 0 where it holds, else the distance
from the ``from`` position to the ``to`` position, both read from the env or its info.

Other forms (a set of discrete observations, a truthy test, an event, a value that cannot be
read) have none: ``None``. :func:`distances` gives, per proposition, the least distance among
its forms that have one (``None`` where none has).

**Through free space.** Given a :class:`~mitlc.labels.geodesic.Geodesic` (an occupancy grid of
the env: a maze's walls, a MiniGrid grid, a plane's obstacles, a declared grid), a form over a
2-D position (a box, a disc, a pair's ``equals``, a guide) measures the geodesic distance
around the obstacles instead (:mod:`mitlc.labels.occupancy`), never less than the straight
one. This is the labels' distance for shaping only; whether a form holds is unchanged.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from mitlc.labels.forms import Form, Guided, InBox, InDisc, Labeller, obs_part
from mitlc.labels.geodesic import Geodesic
from mitlc.labels.values import MISSING, NO_MOMENT, Bound, Equals, Moment, Region, Value, vector


def _to_box(x: np.ndarray[Any, Any], low: Sequence[float], high: Sequence[float]) -> float:
    gap = np.maximum(np.asarray(low) - x, 0.0) + np.maximum(x - np.asarray(high), 0.0)
    return float(np.sqrt(np.sum(gap * gap)))


def _to_disc(x: np.ndarray[Any, Any], center: Sequence[float], radius: float) -> float:
    return max(float(np.sqrt(np.sum((x - np.asarray(center)) ** 2))) - radius, 0.0)


def _region(region: Region, value: Any) -> float | None:
    x = region.point(value)
    if x is None:
        return None
    if region.radius >= 0.0:
        return _to_disc(x, region.center, region.radius)
    return _to_box(x, region.low, region.high)


Point = np.ndarray[Any, Any]
Measure = Callable[[Point], float]
"""A form's distance as a function of the position it reads (the rest of the observation
fixed)."""


def _measure(
    form: Form, obs: Any, info: Mapping[str, Any], moment: Moment, geodesic: Geodesic | None
) -> tuple[Point, Measure] | None:
    """The position ``form`` reads at ``(obs, info)`` and its distance as a function of that
    position (module docstring), for the forms over a position: a box, a disc, a value's
    region or ``equals``, a guide's ``from``; ``None`` for the others."""
    if isinstance(form, InBox | InDisc):
        x = np.asarray(obs_part(obs, form.key), dtype=np.float64)[list(form.index)]
        if isinstance(form, InBox):
            low, high = form.low, form.high
            return x, _through(form, geodesic, lambda y: _to_box(y, low, high))
        center, radius = form.center, form.radius
        return x, _through(form, geodesic, lambda y: _to_disc(y, center, radius))
    if isinstance(form, Guided):
        origin = vector(form.origin.read(obs, info, moment))
        target = vector(form.target.read(obs, info, moment))
        if origin is None or target is None or origin.shape != target.shape:
            return None
        straight = _to_point(target)
        at_target = float(np.sqrt(np.sum((origin - target) ** 2))) == 0.0
        field = None if geodesic is None or at_target else geodesic.toward(form, target)
        if field is None:
            return origin, straight
        return origin, lambda y: max(field.at(y), straight(y))
    if not isinstance(form, Value) or not isinstance(form.test, Region | Equals):
        return None
    value = form.source.read(obs, info, moment)
    if value is MISSING:
        return None
    test = form.test
    if isinstance(test, Region):
        read = test.point(value)
        if read is None:
            return None
        if test.radius >= 0.0:
            center, radius = test.center, test.radius
            return read, _through(form, geodesic, lambda y: _to_disc(y, center, radius))
        low, high = test.low, test.high
        return read, _through(form, geodesic, lambda y: _to_box(y, low, high))
    target, found = vector(test.expected), vector(value)
    if target is None or found is None or target.shape != found.shape:
        return None
    return found, _through(form, geodesic, _to_point(target))


def _to_point(target: Point) -> Measure:
    return lambda y: float(np.sqrt(np.sum((y - target) ** 2)))


def _through(form: Form, geodesic: Geodesic | None, straight: Measure) -> Measure:
    """``straight``, or the distance through free space where ``geodesic`` is given."""
    if geodesic is None:
        return straight
    return lambda y: geodesic.form_distance(form, y, straight(y))


def _bound(form: Value, obs: Any, info: Mapping[str, Any], moment: Moment) -> float | None:
    """How far a value's number is past its ``below`` / ``above``."""
    test = form.test
    assert isinstance(test, Bound)
    value = form.source.read(obs, info, moment)
    x = None if value is MISSING else vector(value)
    if x is None or x.size != 1:
        return None
    number = float(x.reshape(()))
    gap = 0.0
    if test.below is not None:
        gap = max(gap, number - test.below)
    if test.above is not None:
        gap = max(gap, test.above - number)
    return gap


def form_distance(
    form: Form,
    obs: Any,
    info: Mapping[str, Any],
    moment: Moment = NO_MOMENT,
    geodesic: Geodesic | None = None,
) -> float | None:
    """How far ``(obs, info)`` at ``moment`` is from where ``form`` holds (module docstring),
    through free space where ``geodesic`` knows the env's occupancy."""
    if isinstance(form, Guided) and form.form.holds(obs, info, moment):
        return 0.0
    if isinstance(form, Value) and isinstance(form.test, Bound):
        return _bound(form, obs, info, moment)
    measured = _measure(form, obs, info, moment, geodesic)
    if measured is None:
        return None
    point, measure = measured
    return measure(point)


def form_direction(
    form: Form,
    obs: Any,
    info: Mapping[str, Any],
    moment: Moment = NO_MOMENT,
    geodesic: Geodesic | None = None,
) -> Point | None:
    """The unit vector, in the space of the position ``form`` reads, along which its distance
    (:func:`form_distance`) falls fastest: the way toward where it holds, through free space
    where ``geodesic`` is given (central differences of the distance, steps of a thousandth of
    the position's size, at least 0.001); zeros where it holds or the distance is flat;
    ``None`` for a form with no position."""
    measured = _measure(form, obs, info, moment, geodesic)
    if measured is None:
        return None
    point, measure = measured
    point = np.asarray(point, dtype=np.float64).reshape(-1)
    direction = np.zeros(point.size)
    if (isinstance(form, Guided) and form.form.holds(obs, info, moment)) or measure(point) == 0:
        return direction
    step = 1e-3 * max(1.0, float(np.abs(point).max(initial=0.0)))
    for i in range(point.size):
        ahead, behind = point.copy(), point.copy()
        ahead[i] += step
        behind[i] -= step
        direction[i] = measure(behind) - measure(ahead)
    norm = float(np.sqrt(np.sum(direction * direction)))
    return direction / norm if norm > 1e-12 else np.zeros(point.size)


def nearest_forms(
    labeller: Labeller,
    propositions: Sequence[str],
    obs: Any,
    info: Mapping[str, Any],
    moment: Moment = NO_MOMENT,
    geodesic: Geodesic | None = None,
) -> list[tuple[float, Form] | None]:
    """Per proposition of ``propositions``, the least distance among its forms that have one
    and the first form at it (``None`` where none has); through free space where ``geodesic``
    is given."""
    index = {p: i for i, p in enumerate(labeller.propositions)}
    found: list[tuple[float, Form] | None] = []
    for p in propositions:
        best: tuple[float, Form] | None = None
        for form in labeller.forms[index[p]]:
            d = form_distance(form, obs, info, moment, geodesic)
            if d is not None and (best is None or d < best[0]):
                best = (d, form)
        found.append(best)
    return found


def distances(
    labeller: Labeller,
    propositions: Sequence[str],
    obs: Any,
    info: Mapping[str, Any],
    moment: Moment = NO_MOMENT,
    geodesic: Geodesic | None = None,
) -> list[float | None]:
    """Per proposition of ``propositions``, the least distance among its forms that have one
    (``None`` where none has): :func:`nearest_forms`' distances."""
    near = nearest_forms(labeller, propositions, obs, info, moment, geodesic)
    return [None if n is None else n[0] for n in near]


def has_distance(labeller: Labeller, proposition: str) -> bool:
    """Whether some form of ``proposition`` may have a distance (a region, a value's equals,
    below or above)."""
    forms = labeller.forms[labeller.propositions.index(proposition)]
    return any(
        isinstance(f, InBox | InDisc | Guided)
        or (isinstance(f, Value) and isinstance(f.test, Region | Equals | Bound))
        for f in forms
    )
