"""Several robots on one grid, as one finite joint :class:`~mitlc.worlds.model.World`.

A team world file (:class:`~mitlc.worlds.team_schema.TeamWorldFile`) is a grid world file with
``robots:`` (string ids; their order is the joint order) in place of ``start:``. This module
is the one definition of what it means:

**Propositions.** For every cell label ``p`` and robot ``r``, ``p_r`` holds when robot ``r``
stands on a ``p`` cell (``a_robot_0``); plain ``p`` holds when any robot stands on a ``p``
cell. A robot's own ``labels:`` add cells that only its ``p_r`` sees. The collision label
(``collisions.label``, if declared) holds at a joint position where two robots share a cell,
and at the position reached by a step on which two robots swapped cells. Two sources naming
one proposition (label ``a`` of robot ``b_c`` and label ``a_b`` of robot ``c``) is an error.

**Moves.** A joint action is one action per robot, named like ``up|stay``. Each robot moves
independently by its own motion model (:func:`mitlc.worlds.grid.move`), so the joint outcome's
probability is the product of the robots'. Without blocking, those outcomes are the next
positions, collisions included. With ``collisions.block: true``, every robot in a conflict
(its outcome is another robot's outcome, or the two outcomes swap their cells) stays where it
was, and this repeats until no conflict is left. It ends within ``robots`` rounds: a round
with a conflict sends back at least one robot that had moved (two robots that both stay are
in distinct cells, as every joint state of a blocking world is), and once every robot stays
there is no conflict. Blocking therefore never lets the collision label hold.

**Joint states.** A joint state is the robots' cells, plus a swap flag where it matters: the
collision label depends on the move that reached a position (a swap leaves the robots in
distinct cells), and ``World.letters`` must be a function of the state, so a world with a
collision label and no blocking carries ``swapped`` (the step into this state swapped two
robots). Sharing a cell is read from the cells, so ``collided = shared cell or swapped``.
The flag never changes a move, and flagged states exist only for cells where a swap can end
(two robots in adjacent cells joined by a feasible move). States are numbered: every cell
tuple in lexicographic order of the robots' cell indices (robot 0 most significant; only
tuples of distinct cells when collisions block), then the flagged ones in the same order.
Robots start in distinct cells, unflagged.

**Observations.** A robot with ``observation:`` sees its own cell through its noisy-cell or
local-pattern model; one without sees its own cell. If any robot has a model, the world's
observation is the joint one: the tuple of the robots' ids as one mixed-radix id (robot 0 most
significant), named like ``r0c0|r4c4``; otherwise the world is an MDP.

**Size.** The joint table is counted before it is built: first joint states x joint actions
from the counts of cells and actions alone, then the entries exactly (per joint state, the
product over robots of the outcomes of all their actions), and the joint observation table
likewise; past :data:`~mitlc.limits.MAX_TEAM_TRANSITIONS` entries it is a :class:`TeamError` at
``robots``. The tables are built with numpy, a block of joint states at a time
(:mod:`mitlc.worlds.team_tables`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import cast

import numpy as np

from mitlc.errors import MitlcError
from mitlc.limits import MAX_TEAM_TRANSITIONS
from mitlc.worlds.grid import FieldPath, Found, GridMap, Layout, checked_layout, render
from mitlc.worlds.model import BoolArray, IntArray, World
from mitlc.worlds.schema import show
from mitlc.worlds.team_model import Team, radix_parts
from mitlc.worlds.team_schema import TeamWorldFile
from mitlc.worlds.team_tables import (
    JointMotion,
    RobotTables,
    joint_observations,
    joint_states,
    observation_entries,
    pairs,
    robot_tables,
    transition_entries,
)


class TeamError(MitlcError):
    """What is wrong with a team world: each problem as (the field's path, a message)."""

    def __init__(self, found: Found) -> None:
        self.found = list(found)
        super().__init__("\n".join(f"{render(p)}: {m}" if p else m for p, m in self.found))


@dataclass(frozen=True, slots=True)
class Meaning:
    """What a proposition of a team world reads: ``kind`` is ``any`` (label on any robot),
    ``robot`` (label on robot ``robot``) or ``collision``."""

    kind: str
    label: str = ""
    robot: int = -1


# --- the checks that need the whole file ------------------------------------------------------


def check_team(world: TeamWorldFile) -> tuple[Layout, Found]:
    """The layout of a team file, and what is wrong with its cells, sides, starts and
    proposition names: each problem as (the field's path, a message)."""
    checker, too_large = checked_layout(world)
    if too_large is not None:
        return checker.bare, too_large
    starts: dict[tuple[int, int], str] = {}
    for rid, robot in world.robots.items():
        at: FieldPath = ("robots", rid)
        if checker.cell((*at, "start"), robot.start) and robot.start in starts:
            other = starts[robot.start]
            message = (
                f"cell {show(robot.start)} is robot {other!r}'s start too (robots start in "
                "different cells)"
            )
            checker.found.append(((*at, "start"), message))
        starts.setdefault(robot.start, rid)
        for label, cells in robot.labels.items():
            for i, cell in enumerate(cells):
                checker.cell((*at, "labels", label, i), cell)
            checker.once((*at, "labels", label), "cell", cells)
        if robot.actions is not None:
            checker.once((*at, "actions"), "action", robot.actions)
    _, clashes = meanings(world)
    return checker.layout(), checker.found + clashes


def meanings(world: TeamWorldFile) -> tuple[dict[str, Meaning], Found]:
    """Every proposition the file labels and what it reads, and a problem for each name that
    two sources would give (a label, a robot's label, the collision label)."""
    found: Found = []
    named: dict[str, tuple[Meaning, str]] = {}

    def add(name: str, meaning: Meaning, path: FieldPath, what: str) -> None:
        if name in named and named[name][0] != meaning:
            message = (
                f"proposition {name!r} would be both {named[name][1]} and {what}; rename a "
                "label or the robot"
            )
            found.append((path, message))
        named.setdefault(name, (meaning, what))

    for label in world.labels:
        add(label, Meaning("any", label), ("labels", label), f"label {label!r} on any robot")
    if world.collisions is not None:
        label = world.collisions.label
        add(label, Meaning("collision"), ("collisions", "label"), "the collision label")
    for r, (rid, robot) in enumerate(world.robots.items()):
        for label in sorted(set(world.labels) | set(robot.labels)):
            path: FieldPath = ("robots", rid, "labels", label)
            if label not in robot.labels:
                path = ("robots", rid)
            what = f"label {label!r} on robot {rid!r}"
            add(f"{label}_{rid}", Meaning("robot", label, r), path, what)
    return {name: meaning for name, (meaning, _) in named.items()}, found


# --- the joint world ----------------------------------------------------------------------------


HOW = (
    "use fewer robots, fewer free cells (a smaller grid, more blocked cells), fewer actions per "
    "robot (robots.<id>.actions), or certain moves (motion: {intended: 1.0, sideways: 0.0})"
)
"""How to make a team world smaller (the size problem's advice)."""


def _lower_bound(world: TeamWorldFile, layout: Layout, limit: int) -> Found:
    """A size problem found without enumerating anything: every joint state has a row per
    joint action, each with at least one entry."""
    m, n = len(layout.cells()), len(world.robots)
    block = world.collisions is not None and world.collisions.block
    configs = math.perm(m, n) if block else m**n
    actions = math.prod(len(r.actions or world.actions) for r in world.robots.values())
    if configs * actions <= limit:
        return []
    message = (
        f"{n} robots on {m} free cells make at least {configs:,} joint states x {actions:,} "
        f"joint actions = {configs * actions:,} transitions, more than mitlc's limit of "
        f"{limit:,}; {HOW}"
    )
    return [(("robots",), message)]


def _exact(robots: list[RobotTables], positions: IntArray, m: int, limit: int) -> Found:
    """A size problem of the enumerated joint states (:func:`transition_entries`)."""
    n, states = len(robots), len(positions)
    actions = math.prod(len(r.actions) for r in robots)
    entries = transition_entries(robots, positions)
    if entries > limit:
        message = (
            f"{n} robots on {m} free cells make {states:,} joint states x {actions:,} joint "
            f"actions, with {entries:,} transitions ({entries / (states * actions):.1f} outcomes "
            f"a joint move on average), more than mitlc's limit of {limit:,}; {HOW}"
        )
        return [(("robots",), message)]
    if any(r.observations is not None for r in robots):
        names, seen = observation_entries(robots, positions)
        if max(names, seen) > limit:
            message = (
                f"{n} robots on {m} free cells make {names:,} joint observations with "
                f"{seen:,} observation entries, more than mitlc's limit of {limit:,}; give "
                "fewer robots an observation model, or use fewer robots or cells"
            )
            return [(("robots",), message)]
    return []


def _states(world: TeamWorldFile, layout: Layout) -> tuple[IntArray, BoolArray]:
    block = world.collisions is not None and world.collisions.block
    flag = world.collisions is not None and not block
    return joint_states(layout, len(world.robots), block, flag)


def size_problem(world: TeamWorldFile, layout: Layout, limit: int = MAX_TEAM_TRANSITIONS) -> Found:
    """A problem at ``robots`` when the joint transition table (or observation table) would
    have more than ``limit`` entries: counted, not built."""
    found = _lower_bound(world, layout, limit)
    if found:
        return found
    positions, _ = _states(world, layout)
    return _exact(robot_tables(world, layout), positions, len(layout.cells()), limit)


def build_team_world(
    world: TeamWorldFile,
    layout: Layout,
    *,
    name: str,
    spec: str,
    spec_source: str,
    propositions: Sequence[str],
    limit: int = MAX_TEAM_TRANSITIONS,
) -> World:
    """The joint world of a checked team file (see the module docstring), labelled over
    ``propositions`` (each one :func:`meanings` knows); a :class:`TeamError` at ``robots`` if
    its tables would have more than ``limit`` entries (:func:`size_problem`)."""
    found = _lower_bound(world, layout, limit)
    if found:
        raise TeamError(found)
    cells = layout.cells()
    positions, swapped = _states(world, layout)
    robots = robot_tables(world, layout)
    found = _exact(robots, positions, len(cells), limit)
    if found:
        raise TeamError(found)
    block = world.collisions is not None and world.collisions.block
    action_parts = radix_parts(tuple(len(r.actions) for r in robots))
    team = Team(
        robots=tuple(world.robots),
        cells=cells,
        actions=tuple(r.actions for r in robots),
        positions=positions,
        swapped=swapped,
        action_parts=action_parts,
        observations=tuple(r.observations for r in robots),
        collision=None if world.collisions is None else world.collisions.label,
        block=block,
    )
    starts = tuple(robot.start for robot in world.robots.values())
    joint = JointMotion(robots, positions, swapped, block)
    flat = np.asarray(cells, dtype=np.int64)[positions].reshape(len(positions), -1)
    return World(
        name=name,
        rows=layout.rows,
        cols=layout.cols,
        cells=cast(tuple[tuple[int, int], ...], tuple(map(tuple, flat.tolist()))),
        actions=tuple(
            "|".join(r.actions[a] for r, a in zip(robots, parts, strict=True))
            for parts in action_parts.tolist()
        ),
        start=team.state_of(starts),
        transitions=joint.table(transition_entries(robots, positions)),
        propositions=tuple(propositions),
        letters=_letters(world, layout, team, propositions),
        spec=spec,
        spec_source=spec_source,
        horizon=world.horizon,
        discount=world.discount,
        rewards=world.reward.rewards(),
        observations=joint_observations(robots, positions, cells),
        team=team,
        training=dict(world.training),
        drawing=GridMap(
            layout, tuple((p, tuple(c)) for p, c in sorted(world.labels.items())), starts
        ),
    )


def _letters(
    world: TeamWorldFile, layout: Layout, team: Team, propositions: Sequence[str]
) -> IntArray:
    """Each joint state's letter over ``propositions`` (see the module docstring)."""
    known, _ = meanings(world)
    cells = layout.cells()
    positions, n = team.positions, team.num_robots
    robots = list(world.robots.values())
    letters = np.zeros(len(positions), dtype=np.int64)
    for bit, name in enumerate(propositions):
        meaning = known[name]
        if meaning.kind == "collision":
            holds = team.swapped.copy()
            for i, j in pairs(n):
                holds |= positions[:, i] == positions[:, j]
        else:
            labelled = set(world.labels.get(meaning.label, ()))
            if meaning.kind == "robot":
                labelled |= set(robots[meaning.robot].labels.get(meaning.label, ()))
            mask = np.asarray([cell in labelled for cell in cells], dtype=bool)
            on = mask[positions]
            holds = np.asarray(on.any(axis=1) if meaning.kind == "any" else on[:, meaning.robot])
        letters |= holds.astype(np.int64) << bit
    return letters
