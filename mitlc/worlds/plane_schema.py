"""The schema of a continuous world file (``plane:`` in place of ``grid:``), and its whole-file
checks; the semantics are :mod:`mitlc.worlds.plane`'s.

As for grids (:mod:`mitlc.worlds.schema`), the pydantic models check the *shape* (types,
ranges, required and unknown fields) and :func:`check_file` what needs the whole file: every
region inside the room, no box with ``low`` above ``high``, a free start, headings listed once.
A region is ``{box: {low: [x, y], high: [x, y]}}`` or ``{disc: {center: [x, y], radius: r}}``;
the start is a point ``[x, y]`` or a region; a label is a region or a list of regions.

Unions carry a *tag* in pydantic's error locations (:func:`tag_positions` finds them, so the
loader drops them from the field's path): ``point``, ``box`` or ``disc`` for the start, ``box``
or ``disc`` for a region, ``one`` or ``many`` for a label.
"""

from __future__ import annotations

import difflib
import math
from typing import Annotated, Any

from pydantic import BaseModel, BeforeValidator, ConfigDict, Discriminator, Field, Tag
from pydantic_core import PydanticCustomError

from mitlc.worlds.grid import FieldPath, Found, render
from mitlc.worlds.schema import (
    InlineSpec,
    Proposition,
    Reward,
    TaskFields,
    WorldName,
    _fail,
    _is_number,
    _scalar,
    show,
)

HEADINGS: dict[str, float] = {"right": 0.0, "up": 90.0, "left": 180.0, "down": 270.0}
"""The named headings and their angles in degrees, counter-clockwise from the x axis (up is +y)."""


def _point(value: object) -> object:
    if not isinstance(value, list | tuple) or len(value) != 2 or not all(map(_is_number, value)):
        raise _fail("a point [x, y] of two numbers", value)
    return (float(value[0]), float(value[1]))


def _heading(value: object) -> object:
    if _is_number(value):
        return float(value)  # type: ignore[arg-type]
    if isinstance(value, str) and value in HEADINGS:
        return value
    close = difflib.get_close_matches(value, list(HEADINGS), n=1) if isinstance(value, str) else []
    hint = f"; did you mean {close[0]!r}?" if close else ""
    raise PydanticCustomError(
        "world_value",
        "unknown heading: expected up, down, left, right or an angle in degrees, got {got}{hint}",
        {"got": show(value), "hint": hint},
    )


Point = Annotated[tuple[float, float], BeforeValidator(_point)]
"""A point ``[x, y]`` in metres (the origin at the room's lower-left corner, y up)."""
PositiveNumber = Annotated[float, _scalar("a positive number", lambda v: _is_number(v) and v > 0)]
NonNegative = Annotated[float, _scalar("a non-negative number", lambda v: _is_number(v) and v >= 0)]
Flag = Annotated[bool, _scalar("true or false", lambda v: isinstance(v, bool))]
Heading = Annotated[str | float, BeforeValidator(_heading)]


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Room(_Model):
    """The room: the rectangle [0, width] x [0, height], in metres."""

    width: PositiveNumber = Field(description="Its extent along x (metres).")
    height: PositiveNumber = Field(description="Its extent along y (metres).")


class BoxBody(_Model):
    """A closed axis-aligned rectangle."""

    low: Point = Field(description="The lower-left corner [x, y].")
    high: Point = Field(description="The upper-right corner [x, y].")


class DiscBody(_Model):
    """A closed disc."""

    center: Point = Field(description="The centre [x, y].")
    radius: PositiveNumber = Field(description="The radius (metres).")


class BoxRegion(_Model):
    """``{box: {low: [x, y], high: [x, y]}}``."""

    box: BoxBody


class DiscRegion(_Model):
    """``{disc: {center: [x, y], radius: r}}``."""

    disc: DiscBody


def _region_kind(value: Any) -> str | None:
    if isinstance(value, dict):
        return "box" if "box" in value else "disc" if "disc" in value else None
    return None


REGION_TEXT = "a region {box: {low: [x, y], high: [x, y]}} or {disc: {center: [x, y], radius: r}}"
Region = Annotated[
    Annotated[BoxRegion, Tag("box")] | Annotated[DiscRegion, Tag("disc")],
    Discriminator(
        _region_kind,
        custom_error_type="region_kind",
        custom_error_message=f"expected {REGION_TEXT}",
    ),
]


def _start_kind(value: Any) -> str | None:
    return "point" if isinstance(value, list | tuple) else _region_kind(value)


Start = Annotated[
    Annotated[Point, Tag("point")]
    | Annotated[BoxRegion, Tag("box")]
    | Annotated[DiscRegion, Tag("disc")],
    Discriminator(
        _start_kind,
        custom_error_type="start_kind",
        custom_error_message=f"expected a point [x, y] or {REGION_TEXT}",
    ),
]


def _label_kind(value: Any) -> str | None:
    return "one" if isinstance(value, dict) else "many" if isinstance(value, list) else None


Label = Annotated[
    Annotated[Region, Tag("one")] | Annotated[list[Region], Tag("many"), Field(min_length=1)],
    Discriminator(
        _label_kind,
        custom_error_type="label_kind",
        custom_error_message=f"expected {REGION_TEXT}, or a list of regions",
    ),
]


class Actions(_Model):
    """The robot's actions: one move per heading, in order, then ``stay`` if allowed."""

    headings: list[Heading] = Field(
        default_factory=lambda: list[str | float](["up", "down", "left", "right"]),
        min_length=1,
        description="Directions of the moves: up, down, left, right, or an angle in degrees "
        "counter-clockwise from the x axis (default: up, down, left, right).",
    )
    stay: Flag = Field(default=True, description="Whether the robot may stay (a certain action).")
    step: PositiveNumber = Field(default=1.0, description="The length of a move (metres).")


class Noise(_Model):
    """Gaussian motion noise, added to every move."""

    std: NonNegative = Field(
        default=0.0, description="The standard deviation per axis (metres; isotropic)."
    )


class Sensor(_Model):
    """A noisy position sensor (the world is then a POMDP)."""

    std: NonNegative = Field(description="The standard deviation per axis (metres; isotropic).")


class Plane(_Model):
    """A room in the plane with a point robot."""

    room: Room = Field(description="The room's size: {width: ..., height: ...} in metres.")
    start: Start = Field(description="The start: a point [x, y], or a region sampled uniformly.")
    actions: Actions = Field(default=Actions(), description="The headings, stay and step length.")
    noise: Noise = Field(default=Noise(), description="The motion noise: {std: ...}.")
    obstacles: list[Region] = Field(
        default_factory=list, description="Boxes and discs the robot cannot enter or cross."
    )
    sensor: Sensor | None = Field(
        default=None, description="A noisy position sensor; null (the default) for an MDP."
    )


class PlaneWorldFile(TaskFields):
    """A continuous world file: a room in the plane and its task."""

    name: WorldName | None = Field(
        default=None,
        description="The world's name (default: the file's stem), which names its run "
        "directories: printable, without / or \\ or a leading '.'.",
    )
    plane: Plane = Field(description="The room, the start, the actions, noise and obstacles.")
    labels: dict[Proposition, Label] = Field(
        default_factory=dict,
        description="For each proposition, the region (or list of regions) where it holds.",
    )


MODELS: dict[tuple[str, ...], type[BaseModel]] = {
    (): PlaneWorldFile,
    ("plane",): Plane,
    ("plane", "room"): Room,
    ("plane", "actions"): Actions,
    ("plane", "noise"): Noise,
    ("plane", "sensor"): Sensor,
    ("spec",): InlineSpec,
    ("reward",): Reward,
}
"""The model at each place of the file, by the field's path (tags dropped)."""


def _region_at(path: FieldPath) -> bool:
    """Whether ``path`` (tags dropped) is where the file has a region."""
    if path == ("plane", "start"):
        return True
    if len(path) == 3 and path[:2] == ("plane", "obstacles"):
        return True
    return bool(path) and path[0] == "labels" and len(path) in (2, 3)


def tag_positions(loc: tuple[str | int, ...]) -> set[int]:
    """The positions of union tags in a pydantic error location of a plane world file."""
    tags: set[int] = set()

    def tag(at: int, names: tuple[str, ...]) -> bool:
        if len(loc) > at and loc[at] in names:
            tags.add(at)
            return True
        return False

    if loc[:2] == ("plane", "start"):
        tag(2, ("point", "box", "disc"))
    elif loc[:2] == ("plane", "obstacles"):
        tag(3, ("box", "disc"))
    elif loc[:1] == ("labels",) and tag(2, ("one", "many")):
        tag(3 if loc[2] == "one" else 4, ("box", "disc"))
    elif loc[:1] == ("spec",):
        tag(1, ("path", "inline"))
    return tags


def unknown_field(path: FieldPath) -> str:
    """The message of an unknown field at ``path`` (tags dropped; its last item the field's
    name), with the closest known field's name or the known fields."""
    where, name = path[:-1], str(path[-1])
    if _region_at(where):
        if name in ("box", "disc"):
            return "a region has one of box: and disc:, not both"
        fields = ["box", "disc"]
    elif where and where[-1] in ("box", "disc") and _region_at(where[:-1]):
        fields = list((BoxBody if where[-1] == "box" else DiscBody).model_fields)
    else:
        fields = list(MODELS.get(tuple(map(str, where)), PlaneWorldFile).model_fields)
    close = difflib.get_close_matches(name, fields, n=1)
    return (
        f"unknown field; did you mean {close[0]!r}?"
        if close
        else (f"unknown field (known: {', '.join(fields)})")
    )


# --- checks of the whole file ------------------------------------------------------------------


def _num(x: float) -> str:
    return f"{x:g}"


def _pt(p: tuple[float, float]) -> str:
    return f"[{_num(p[0])}, {_num(p[1])}]"


def check_file(file: PlaneWorldFile) -> Found:
    """What is wrong with a plane world file beyond its shape (the module docstring)."""
    found: Found = []
    plane = file.plane
    width, height = plane.room.width, plane.room.height
    room = f"the {_num(width)} m x {_num(height)} m room"
    regions: list[tuple[FieldPath, BoxRegion | DiscRegion]] = []
    if not isinstance(plane.start, tuple):
        regions.append((("plane", "start"), plane.start))
    regions += [(("plane", "obstacles", i), r) for i, r in enumerate(plane.obstacles)]
    for name, label in file.labels.items():
        if isinstance(label, list):
            regions += [(("labels", name, i), r) for i, r in enumerate(label)]
        else:
            regions.append((("labels", name), label))
    bad: set[FieldPath] = set()
    for path, region in regions:
        if isinstance(region, BoxRegion):
            low, high = region.box.low, region.box.high
            axes = [a for a in (0, 1) if low[a] > high[a]]
            if axes:
                a = axes[0]
                found.append(
                    (
                        (*path, "box"),
                        f"low {_pt(low)} is above high {_pt(high)} in {'xy'[a]} "
                        f"({_num(low[a])} > {_num(high[a])})",
                    )
                )
                bad.add(path)
                continue
            inside = low[0] >= 0 and low[1] >= 0 and high[0] <= width and high[1] <= height
            what = f"the box from {_pt(low)} to {_pt(high)}"
        else:
            (x, y), r = region.disc.center, region.disc.radius
            inside = x - r >= 0 and y - r >= 0 and x + r <= width and y + r <= height
            what = f"the disc of radius {_num(r)} around {_pt((x, y))}"
        if not inside:
            found.append((path, f"{what} is not inside {room}"))
            bad.add(path)
    _check_start(file, room, bad, found)
    _check_headings(plane.actions, found)
    return found


def _check_start(file: PlaneWorldFile, room: str, bad: set[FieldPath], found: Found) -> None:
    """A point start inside the room and in no obstacle; a region start overlapping none."""
    plane, where = file.plane, ("plane", "start")
    start = plane.start
    if isinstance(start, tuple):
        x, y = start
        if not (0 <= x <= plane.room.width and 0 <= y <= plane.room.height):
            found.append((where, f"the start {_pt(start)} is outside {room}"))
            return
    elif where in bad:
        return
    for i, obstacle in enumerate(plane.obstacles):
        path: FieldPath = ("plane", "obstacles", i)
        if path in bad:
            continue
        if isinstance(start, tuple) and _contains(obstacle, start):
            found.append((where, f"the start {_pt(start)} is inside the obstacle {render(path)}"))
            return
        if not isinstance(start, tuple) and _overlap(start, obstacle):
            found.append((where, f"the start region overlaps the obstacle {render(path)}"))
            return


def _check_headings(actions: Actions, found: Found) -> None:
    """Each direction listed once."""
    first: dict[float, int] = {}
    for i, heading in enumerate(actions.headings):
        angle = heading_angle(heading)
        if angle in first:
            also = render(("plane", "actions", "headings", first[angle]))
            shown = show(heading) if isinstance(heading, str) else _num(heading)
            found.append(
                (
                    ("plane", "actions", "headings", i),
                    f"heading {shown} is the direction of {also} again",
                )
            )
        first.setdefault(angle, i)


def heading_angle(heading: str | float) -> float:
    """A heading's angle in degrees, in [0, 360)."""
    angle = HEADINGS[heading] if isinstance(heading, str) else float(heading)
    return angle % 360.0


def _contains(region: BoxRegion | DiscRegion, p: tuple[float, float]) -> bool:
    if isinstance(region, BoxRegion):
        low, high = region.box.low, region.box.high
        return low[0] <= p[0] <= high[0] and low[1] <= p[1] <= high[1]
    (cx, cy), r = region.disc.center, region.disc.radius
    return math.hypot(p[0] - cx, p[1] - cy) <= r


def _overlap(one: BoxRegion | DiscRegion, two: BoxRegion | DiscRegion) -> bool:
    """Whether the interiors of two regions meet."""
    if isinstance(one, DiscRegion) and isinstance(two, BoxRegion):
        one, two = two, one
    if isinstance(one, BoxRegion) and isinstance(two, BoxRegion):
        a, b = one.box, two.box
        return all(a.low[k] < b.high[k] and b.low[k] < a.high[k] for k in (0, 1))
    if isinstance(one, BoxRegion) and isinstance(two, DiscRegion):
        (cx, cy), r = two.disc.center, two.disc.radius
        nx = min(max(cx, one.box.low[0]), one.box.high[0])
        ny = min(max(cy, one.box.low[1]), one.box.high[1])
        return math.hypot(cx - nx, cy - ny) < r
    assert isinstance(one, DiscRegion) and isinstance(two, DiscRegion)
    (ax, ay), (bx, by) = one.disc.center, two.disc.center
    return math.hypot(ax - bx, ay - by) < one.disc.radius + two.disc.radius
