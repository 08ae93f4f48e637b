"""Clock guards: partitioning the valuations of a location into boxes of equal behaviour."""

from __future__ import annotations

from collections.abc import Hashable, Mapping
from typing import TypeAlias, TypeVar

B = TypeVar("B", bound=Hashable)
Box: TypeAlias = tuple[tuple[int, int], ...]
"""One closed interval ``(lo, hi)`` per clock."""


def partition(
    points: Mapping[tuple[int, ...], B], dims: int, bound: int, above: B | None = None
) -> list[tuple[Box, B]]:
    """Boxes covering ``[0, bound]^dims`` exactly once, each with one behaviour.

    ``points`` maps the reachable valuations to their behaviour. Clock by clock, each value in
    ``[0, bound]`` that no reachable valuation has takes the behaviour of the nearest reachable
    value below it (above it, if there is none below) or, past the largest reachable value,
    ``above`` when it is given (the rejecting sink: the deadlines have passed); neighbouring
    values that behave the same merge into one interval. The result is deterministic and
    complete.
    """
    if not points:
        return []
    if dims == 0:
        ((_, behaviour),) = points.items()
        return [((), behaviour)]
    groups: dict[int, dict[tuple[int, ...], B]] = {}
    for valuation, behaviour in points.items():
        groups.setdefault(valuation[0], {})[valuation[1:]] = behaviour
    present = sorted(groups)
    signature = {x: tuple(partition(groups[x], dims - 1, bound, above)) for x in present}
    beyond = None if above is None else tuple(_full(dims - 1, bound, above))

    def behaviour_at(x: int) -> tuple[tuple[Box, B], ...]:
        if beyond is not None and x > present[-1]:
            return beyond
        return signature[_nearest(present, x)]

    result: list[tuple[Box, B]] = []
    start, current = 0, behaviour_at(0)
    for x in range(1, bound + 1):
        here = behaviour_at(x)
        if here != current:
            result.extend(_prefixed(start, x - 1, current))
            start, current = x, here
    result.extend(_prefixed(start, bound, current))
    return result


def _full(dims: int, bound: int, behaviour: B) -> list[tuple[Box, B]]:
    return [(tuple((0, bound) for _ in range(dims)), behaviour)]


def _nearest(present: list[int], x: int) -> int:
    below = [p for p in present if p <= x]
    return below[-1] if below else present[0]


def _prefixed(lo: int, hi: int, rest: tuple[tuple[Box, B], ...]) -> list[tuple[Box, B]]:
    return [(((lo, hi), *box), behaviour) for box, behaviour in rest]
