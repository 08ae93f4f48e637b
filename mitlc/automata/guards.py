"""Clock guards: partitioning the valuations of a location into boxes of equal behaviour.

The behaviour along one clock is piecewise constant, changing only at the values some reachable
valuation has (its *breakpoints*), so :func:`partition` walks the sorted breakpoints instead of
every value in ``[0, bound]``: its cost is ``O(p log p)`` in the ``p`` reachable valuations
(times the boxes of the lower clocks compared at each breakpoint), not ``O(bound)`` per level.
"""

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
    if dims == 1:
        return _partition_line(points, bound, above)
    groups: dict[int, dict[tuple[int, ...], B]] = {}
    for valuation, behaviour in points.items():
        groups.setdefault(valuation[0], {})[valuation[1:]] = behaviour
    present = sorted(groups)
    # Runs of constant behaviour: ``(first value, behaviour)``; the value ``present[i]`` (or 0
    # for the first) starts the run of ``present[i]``'s behaviour, which lasts until the next
    # breakpoint. Only the breakpoints inside ``[0, bound]`` start a run.
    runs: list[tuple[int, tuple[tuple[Box, B], ...]]] = []
    for i, x in enumerate(present):
        start = 0 if i == 0 else x
        if start > bound:
            break
        here = tuple(partition(groups[x], dims - 1, bound, above))
        if not runs or runs[-1][1] != here:
            runs.append((start, here))
    if above is not None and present[-1] < bound:
        beyond = tuple(_full(dims - 1, bound, above))
        if runs[-1][1] != beyond:
            runs.append((present[-1] + 1, beyond))
    result: list[tuple[Box, B]] = []
    for i, (start, rest) in enumerate(runs):
        end = runs[i + 1][0] - 1 if i + 1 < len(runs) else bound
        result.extend(_prefixed(start, end, rest))
    return result


def _partition_line(
    points: Mapping[tuple[int, ...], B], bound: int, above: B | None
) -> list[tuple[Box, B]]:
    """:func:`partition` of one clock, without the recursion (the common case)."""
    present = sorted(points)
    runs: list[tuple[int, B]] = []
    for i, x in enumerate(present):
        start = 0 if i == 0 else x[0]
        if start > bound:
            break
        here = points[x]
        if not runs or runs[-1][1] != here:
            runs.append((start, here))
    if above is not None and present[-1][0] < bound and runs[-1][1] != above:
        runs.append((present[-1][0] + 1, above))
    return [
        (((start, runs[i + 1][0] - 1 if i + 1 < len(runs) else bound),), behaviour)
        for i, (start, behaviour) in enumerate(runs)
    ]


def _full(dims: int, bound: int, behaviour: B) -> list[tuple[Box, B]]:
    return [(tuple((0, bound) for _ in range(dims)), behaviour)]


def _prefixed(lo: int, hi: int, rest: tuple[tuple[Box, B], ...]) -> list[tuple[Box, B]]:
    return [(((lo, hi), *box), behaviour) for box, behaviour in rest]
