"""The team world file's schema: a grid world file with ``robots:`` in place of ``start:``.

The grid's fields (``grid``, ``blocked``, ``labels``, ``walls``, ``doors``, ``windows``) and the
task's (``spec``, ``reward``, ``horizon``, ``discount``, ``training``) are the grid world
file's own types (:mod:`mitlc.worlds.schema`); ``actions`` and ``motion`` are defaults that a
robot may replace. These models check the shape only; the whole-file rules (cells inside the
grid and free, distinct starts, proposition names that do not clash) are
:func:`mitlc.worlds.team.check_team`'s. The semantics are :mod:`mitlc.worlds.team`'s docstring.
"""

from __future__ import annotations

import re
from typing import Annotated

from pydantic import BaseModel, Field

from mitlc.worlds.schema import (
    ACTIONS,
    Action,
    Cell,
    Cells,
    Grid,
    InlineSpec,
    LocalPattern,
    Motion,
    NoisyCell,
    Observation,
    Proposition,
    Reward,
    Side,
    TaskFields,
    WorldName,
    _Model,
    _scalar,
)

ROBOT_ID = "^[a-z0-9][a-z0-9_]*$"
"""A robot's id: lowercase letters, digits and ``_``, so that ``p_<id>`` is a proposition."""

RobotId = Annotated[
    str,
    _scalar(
        "a robot id (lowercase letters, digits or _, e.g. robot_0)",
        lambda v: isinstance(v, str) and len(v) <= 64 and bool(re.fullmatch(ROBOT_ID, v)),
    ),
    Field(json_schema_extra={"pattern": ROBOT_ID}),
]


class Robot(_Model):
    """One robot of the team: where it starts, and what it does differently from the defaults."""

    start: Cell = Field(description="The robot's first cell, [row, col].")
    actions: list[Action] | None = Field(
        default=None,
        min_length=1,
        description="This robot's actions, in order (default: the file's actions).",
    )
    motion: Motion | None = Field(
        default=None, description="This robot's motion model (default: the file's motion)."
    )
    observation: Observation | None = Field(
        default=None,
        description="What this robot observes of its own cell: a noisy cell or its local "
        "pattern; null (the default): its own cell.",
    )
    labels: dict[Proposition, Cells] = Field(
        default_factory=dict,
        description="Cells only this robot's propositions see: p labels these cells for "
        "p_<id> (not for the team's plain p).",
    )


class Collisions(_Model):
    """Two robots in one cell, or two robots that swapped cells on the last step."""

    label: Proposition = Field(
        default="collide",
        description="The proposition that holds where two robots share a cell, or on the "
        "position reached by a step on which two robots swapped cells.",
    )
    block: bool = Field(
        default=False,
        description="true: robots whose moves would collide stay where they were (then the "
        "label never holds); false: collisions happen and are labelled.",
    )


class TeamWorldFile(TaskFields):
    """A team world file: several robots on one grid (an MDP, or a POMDP when a robot has an
    observation model) and the team's task."""

    name: WorldName | None = Field(
        default=None,
        description="The world's name (default: the file's stem), which names its run "
        "directories: printable, without / or \\ or a leading '.'.",
    )
    grid: Grid = Field(description="The grid's size: its rows and columns.")
    blocked: Cells = Field(
        default_factory=list, description="Cells no robot can ever be in: [row, col] each."
    )
    labels: dict[Proposition, Cells] = Field(
        default_factory=dict,
        description="For each proposition p, the free cells where it holds: p_<id> holds when "
        "robot <id> is on one, p when any robot is.",
    )
    actions: list[Action] = Field(
        default_factory=lambda: list(ACTIONS),
        min_length=1,
        description="Every robot's actions unless it names its own (default: up, down, left, "
        "right, stay).",
    )
    motion: Motion = Field(description="Every robot's motion model unless it names its own.")
    walls: list[Side] = Field(
        default_factory=list,
        description="Sides no robot can cross: [[r, c], [r, c]] or [[r, c], N|W|S|E].",
    )
    doors: list[Side] = Field(
        default_factory=list, description="Sides with a door: must join two free cells."
    )
    windows: list[Side] = Field(
        default_factory=list, description="Sides with a window: no robot can cross."
    )
    robots: dict[RobotId, Robot] = Field(
        min_length=1,
        description="The robots by id (lowercase letters, digits, _); their order is the order "
        "of a joint state, a joint action and a joint observation.",
    )
    collisions: Collisions | None = Field(
        default=None,
        description="The collision label and whether collisions are blocked; left out: robots "
        "pass through each other, unlabelled.",
    )


TEAM_MODELS: dict[tuple[str, ...], type[BaseModel]] = {
    (): TeamWorldFile,
    ("grid",): Grid,
    ("motion",): Motion,
    ("robots", "*"): Robot,
    ("robots", "*", "motion"): Motion,
    ("robots", "*", "observation", "noisy-cell"): NoisyCell,
    ("robots", "*", "observation", "local-pattern"): LocalPattern,
    ("collisions",): Collisions,
    ("spec", "inline"): InlineSpec,
    ("reward",): Reward,
}
"""The model at each place of a team file, by pydantic's error location (a robot's id or a
list index as ``*``, union tags included)."""
