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

from collections.abc import Mapping, Sequence
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


def _value(
    form: Value, obs: Any, info: Mapping[str, Any], moment: Moment, geodesic: Geodesic | None
) -> float | None:
    test = form.test
    if not isinstance(test, Region | Equals | Bound):
        return None
    value = form.source.read(obs, info, moment)
    if value is MISSING:
        return None
    if isinstance(test, Region):
        straight = _region(test, value)
        if geodesic is None or straight is None:
            return straight
        return geodesic.form_distance(form, test.point(value), straight)
    if isinstance(test, Bound):
        x = vector(value)
        if x is None or x.size != 1:
            return None
        number = float(x.reshape(()))
        gap = 0.0
        if test.below is not None:
            gap = max(gap, number - test.below)
        if test.above is not None:
            gap = max(gap, test.above - number)
        return gap
    target = vector(test.expected)
    found = vector(value)
    if target is None or found is None or target.shape != found.shape:
        return None
    straight = float(np.sqrt(np.sum((found - target) ** 2)))
    return straight if geodesic is None else geodesic.form_distance(form, found, straight)


def _guided(
    form: Guided, obs: Any, info: Mapping[str, Any], moment: Moment, geodesic: Geodesic | None
) -> float | None:
    if form.form.holds(obs, info, moment):
        return 0.0
    origin = vector(form.origin.read(obs, info, moment))
    target = vector(form.target.read(obs, info, moment))
    if origin is None or target is None or origin.shape != target.shape:
        return None
    straight = float(np.sqrt(np.sum((origin - target) ** 2)))
    field = None if geodesic is None or straight == 0.0 else geodesic.toward(form, target)
    return straight if field is None else max(field.at(origin), straight)


def form_distance(
    form: Form,
    obs: Any,
    info: Mapping[str, Any],
    moment: Moment = NO_MOMENT,
    geodesic: Geodesic | None = None,
) -> float | None:
    """How far ``(obs, info)`` at ``moment`` is from where ``form`` holds (module docstring),
    through free space where ``geodesic`` knows the env's occupancy."""
    if isinstance(form, Guided):
        return _guided(form, obs, info, moment, geodesic)
    if isinstance(form, Value):
        return _value(form, obs, info, moment, geodesic)
    if isinstance(form, InBox | InDisc):
        x = np.asarray(obs_part(obs, form.key), dtype=np.float64)[list(form.index)]
        if isinstance(form, InBox):
            straight = _to_box(x, form.low, form.high)
        else:
            straight = _to_disc(x, form.center, form.radius)
        return straight if geodesic is None else geodesic.form_distance(form, x, straight)
    return None


def distances(
    labeller: Labeller,
    propositions: Sequence[str],
    obs: Any,
    info: Mapping[str, Any],
    moment: Moment = NO_MOMENT,
    geodesic: Geodesic | None = None,
) -> list[float | None]:
    """Per proposition of ``propositions``, the least distance among its forms that have one
    (``None`` where none has); through free space where ``geodesic`` is given."""
    index = {p: i for i, p in enumerate(labeller.propositions)}
    found: list[float | None] = []
    for p in propositions:
        known = [
            d
            for form in labeller.forms[index[p]]
            if (d := form_distance(form, obs, info, moment, geodesic)) is not None
        ]
        found.append(min(known) if known else None)
    return found


def has_distance(labeller: Labeller, proposition: str) -> bool:
    """Whether some form of ``proposition`` may have a distance (a region, a value's equals,
    below or above)."""
    forms = labeller.forms[labeller.propositions.index(proposition)]
    return any(
        isinstance(f, InBox | InDisc | Guided)
        or (isinstance(f, Value) and isinstance(f.test, Region | Equals | Bound))
        for f in forms
    )
