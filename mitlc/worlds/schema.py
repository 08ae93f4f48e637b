"""The world file's schema: pydantic models of the YAML, exported as a JSON schema for editors.

These models check the *shape* of a world file: types, ranges, required and unknown fields.
Checks that need the whole file (a cell inside the grid, a start that is not blocked, adjacent
wall sides, the spec's propositions) are a separate pass, in :mod:`mitlc.worlds.load`. Every
scalar type below raises its own error message (``expected a positive integer, got "ten"``)
so that :func:`mitlc.worlds.load.issues_of` can show it as is. The grid world file is here, with
the scalar types and sections every kind shares; an env world file's own models are in
:mod:`mitlc.worlds.env_schema`.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Callable, Sequence
from typing import Annotated, Any, Literal

from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Discriminator,
    Field,
    Tag,
    WithJsonSchema,
    model_validator,
)
from pydantic_core import PydanticCustomError

from mitlc.limits import MAX_HORIZON
from mitlc.worlds.model import Rewards

Action = Literal["up", "down", "left", "right", "stay"]
ACTIONS: tuple[Action, ...] = ("up", "down", "left", "right", "stay")
COMPASS = ("N", "W", "S", "E")
PROPOSITION = "^(?!(true|false)$)[a-z][a-z0-9_]*$"
"""A proposition's name, as the spec grammar reads it (``grammars/mitl.lark``, ``ATOM``)."""


def show(value: object) -> str:
    """A value as the world file would spell it (JSON), cut short when long."""
    try:
        text = json.dumps(value, ensure_ascii=False, default=str)
    except ValueError:  # a recursive value (a YAML alias inside itself)
        text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _fail(expected: str, value: object) -> PydanticCustomError:
    return PydanticCustomError(
        "world_value", "expected {expected}, got {got}", {"expected": expected, "got": show(value)}
    )


def _scalar(expected: str, test: Callable[[Any], bool]) -> BeforeValidator:
    """A validator raising ``expected ..., got ...`` for a value failing ``test``."""

    def check(value: Any) -> Any:
        if not test(value):
            raise _fail(expected, value)
        return value

    return BeforeValidator(check)


def _is_int(value: object) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _is_number(value: object) -> bool:
    """An int or a finite float (not a bool, nan or infinity)."""
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def _cell(value: object) -> object:
    if not isinstance(value, list | tuple) or len(value) != 2 or not all(map(_is_int, value)):
        raise _fail("a cell [row, col] of two integers", value)
    return tuple(value)


def _cells(value: object) -> object:
    if isinstance(value, list) and len(value) == 2 and all(map(_is_int, value)):
        raise _fail("a list of cells [[row, col], ...]", value)
    return value


def _side(value: object) -> object:
    if isinstance(value, list | tuple) and len(value) == 2:
        first, second = value
        if isinstance(second, str) and second in COMPASS:
            return (_cell(first), second)
        if isinstance(second, list | tuple):
            return (_cell(first), _cell(second))
    raise _fail("a side: [[row, col], [row, col]] or [[row, col], N|W|S|E]", value)


PositiveInt = Annotated[
    int, Field(gt=0), _scalar("a positive integer", lambda v: _is_int(v) and v > 0)
]
Number = Annotated[float, _scalar("a number", _is_number)]


def _horizon(value: object) -> object:
    if not isinstance(value, int) or isinstance(value, bool) or value <= 0:
        raise _fail("a positive integer", value)
    if value > MAX_HORIZON:
        raise _fail(f"at most {MAX_HORIZON:,} steps (mitlc's limit)", value)
    return value


Horizon = Annotated[int, Field(gt=0, le=MAX_HORIZON), BeforeValidator(_horizon)]
Probability = Annotated[
    float,
    Field(ge=0, le=1),
    _scalar("a probability (a number from 0 to 1)", lambda v: _is_number(v) and 0 <= v <= 1),
]
Discount = Annotated[
    float, Field(gt=0, le=1), _scalar("a number in (0, 1]", lambda v: _is_number(v) and 0 < v <= 1)
]


def _world_name(value: object) -> object:
    """A world's name names its run directory (``runs/NAME-q-s0``): one printable path
    component, so that a world file cannot send a run elsewhere."""
    if not (isinstance(value, str) and value.strip()):
        raise _fail("a non-empty string", value)
    if (
        len(value) > 100
        or value.startswith(".")
        or any(c in "/\\" or not c.isprintable() for c in value)
    ):
        raise _fail(
            "a name of at most 100 printable characters, without / or \\ or a leading .", value
        )
    return value


WorldName = Annotated[str, BeforeValidator(_world_name)]
Proposition = Annotated[
    str,
    _scalar(
        "a proposition name (a lowercase letter, then lowercase letters, digits or _)",
        lambda v: isinstance(v, str) and bool(re.fullmatch(PROPOSITION, v)),
    ),
    Field(json_schema_extra={"pattern": PROPOSITION}),
]
Cell = Annotated[tuple[int, int], BeforeValidator(_cell)]
"""A cell ``[row, col]``; row 0 is the top row, column 0 the left column."""
Cells = Annotated[list[Cell], BeforeValidator(_cells)]
"""A list of cells (one cell alone, ``[r, c]``, is refused rather than read as two)."""
Compass = Literal["N", "W", "S", "E"]
Side = Annotated[tuple[Cell, Cell] | tuple[Cell, Compass], BeforeValidator(_side)]
"""A side of a cell: two adjacent cells, or a cell and a compass side (N is up)."""


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Grid(_Model):
    """The size of the grid."""

    rows: PositiveInt = Field(description="The number of rows (row 0 is the top row).")
    cols: PositiveInt = Field(description="The number of columns (column 0 is the left column).")


class Motion(_Model):
    """Where a move takes the robot. Give exactly one of ``sideways``, ``spread`` and
    ``stall``."""

    intended: Probability = Field(description="The probability of moving the intended way.")
    sideways: Probability | None = Field(
        default=None,
        description="The probability of slipping to each of the two perpendicular directions "
        "(intended + 2 * sideways = 1). A slip that is infeasible leaves the robot in place.",
    )
    spread: Probability | None = Field(
        default=None,
        description="The probability split evenly over the other feasible directions "
        "(not off the grid, not blocked, not through a wall or window); with none feasible, it "
        "stays in place (intended + spread = 1).",
    )
    stall: Probability | None = Field(
        default=None,
        description="The probability of not moving at all, a wheel slip (intended + stall = 1): "
        "two outcomes a move, so teams of robots stay small.",
    )

    @model_validator(mode="after")
    def _one_model_summing_to_one(self) -> Motion:
        given = [x for x in (self.sideways, self.spread, self.stall) if x is not None]
        if len(given) != 1:
            raise PydanticCustomError(
                "motion_kind",
                "give exactly one of 'sideways', 'spread' and 'stall', with 'intended'",
            )
        if self.sideways is not None:
            total = self.intended + 2 * self.sideways
            how = f"intended {show(self.intended)} + 2 * sideways {show(self.sideways)}"
        elif self.stall is not None:
            total = self.intended + self.stall
            how = f"intended {show(self.intended)} + stall {show(self.stall)}"
        else:
            assert self.spread is not None
            total = self.intended + self.spread
            how = f"intended {show(self.intended)} + spread {show(self.spread)}"
        if abs(total - 1) > 1e-12:
            raise PydanticCustomError(
                "motion_sum",
                "probabilities sum to {total}, expected 1 ({how})",
                {"total": show(round(total, 12)), "how": how},
            )
        return self


PositiveNumber = Annotated[
    float, Field(gt=0), _scalar("a positive number", lambda v: _is_number(v) and v > 0)
]
LabelProbability = Annotated[
    float,
    Field(gt=0, le=1),
    _scalar("a probability in (0, 1]", lambda v: _is_number(v) and 0 < v <= 1),
]


class WeightedStart(_Model):
    """Start cells drawn with the given weights (normalised: they need not sum to 1)."""

    cells: Annotated[Cells, Field(min_length=1)] = Field(description="The start cells.")
    weights: list[PositiveNumber] = Field(
        description="A positive weight per cell, in the same order; the start is cell i with "
        "probability weights[i] / sum(weights)."
    )


def _start_kind(value: Any) -> str | None:
    if isinstance(value, str):
        return "uniform"
    if isinstance(value, dict):
        return "weighted"
    if isinstance(value, list | tuple):
        return "list" if all(isinstance(x, list | tuple) for x in value) else "cell"
    return None


START_TAGS = ("cell", "list", "weighted", "uniform")
"""The forms of ``start:`` (pydantic's union tags, dropped from error paths)."""
Start = Annotated[
    Annotated[Cell, Tag("cell")]
    | Annotated[Annotated[Cells, Field(min_length=1)], Tag("list")]
    | Annotated[WeightedStart, Tag("weighted")]
    | Annotated[Literal["uniform"], Tag("uniform")],
    Discriminator(
        _start_kind,
        custom_error_type="start_kind",
        custom_error_message="expected a cell [row, col], a list of cells, "
        "{cells: [...], weights: [...]} or uniform",
    ),
]
"""Where an episode starts (:mod:`mitlc.worlds.starts`): a cell, a list of cells (drawn
uniformly), cells with weights, or ``uniform`` (every free cell)."""


class UncertainLabel(_Model):
    """A proposition that holds in its cells with a probability, drawn independently each
    time the robot is in one of them (:mod:`mitlc.worlds.uncertain`)."""

    cells: Cells = Field(description="The free cells where the proposition may hold.")
    probability: LabelProbability = Field(
        default=1.0,
        description="The probability that it holds, each step the robot is in one of its "
        "cells, independently of every other step and label (1: certain).",
    )


def _grid_label_kind(value: Any) -> str | None:
    return "list" if isinstance(value, list) else "uncertain" if isinstance(value, dict) else None


LABEL_TAGS = ("list", "uncertain")
"""The forms of a grid label (pydantic's union tags, dropped from error paths)."""
GridLabel = Annotated[
    Annotated[Cells, Tag("list")] | Annotated[UncertainLabel, Tag("uncertain")],
    Discriminator(
        _grid_label_kind,
        custom_error_type="label_kind",
        custom_error_message="expected a list of cells or {cells: [...], probability: p}",
    ),
]
"""A grid label: its cells (certain), or ``{cells: [...], probability: p}``."""


def label_cells(label: Sequence[Cell] | UncertainLabel) -> tuple[Sequence[Cell], tuple[str, ...]]:
    """A grid label's cells and their path below the label's (``()`` or ``("cells",)``)."""
    if isinstance(label, UncertainLabel):
        return label.cells, ("cells",)
    return label, ()


class NoisyCell(_Model):
    """The robot observes a cell: its own, or by mistake an adjacent free cell."""

    type: Literal["noisy-cell"] = Field(description="Noisy observations of the robot's cell.")
    correct: Probability = Field(
        description="The probability of observing the true cell; the rest is spread evenly over "
        "the adjacent free cells (a cell with none is observed correctly)."
    )
    neighbourhood: Literal[4, 8] = Field(
        default=4, description="Adjacent cells: 4 (N, W, S, E) or 8 (with the diagonals)."
    )


class LocalPattern(_Model):
    """The robot observes the kind of its cell's four sides, N, W, S, E, each one of wall
    (grid edge, wall, blocked neighbour), hallway (open to a free cell), door or window."""

    type: Literal["local-pattern"] = Field(description="Deterministic local side patterns.")


Observation = Annotated[NoisyCell | LocalPattern, Field(discriminator="type")]


class InlineSpec(_Model):
    """A task written in the world file."""

    formula: str = Field(description="An MITL formula over the labels' propositions.")


def _spec_kind(value: Any) -> str | None:
    return "path" if isinstance(value, str) else "inline" if isinstance(value, dict) else None


SpecRef = Annotated[
    Annotated[str, Tag("path")] | Annotated[InlineSpec, Tag("inline")],
    Discriminator(
        _spec_kind,
        custom_error_type="spec_kind",
        custom_error_message="expected a spec file's path or {formula: ...}",
    ),
]


class Reward(_Model):
    """The reward terms of an episode."""

    satisfied: Number = Field(default=100.0, description="Given when the task becomes satisfied.")
    accept: Number = Field(default=100.0, description="Given on each visit to an acceptance set.")
    violated: Number = Field(default=0.0, description="Given when the task becomes violated.")
    move: Number = Field(
        default=0.0, description="Given on each step that is not 'stay' (a cost: < 0)."
    )

    def rewards(self) -> Rewards:
        """The validated terms as the world's :class:`~mitlc.worlds.model.Rewards`."""
        return Rewards(
            accept=self.accept, satisfied=self.satisfied, violated=self.violated, move=self.move
        )


def _proposition_cost(value: object) -> object:
    if isinstance(value, int | float) and not isinstance(value, bool):
        if not _is_number(value):
            raise _fail("a number", value)
        return {"hold": value}
    if isinstance(value, dict):
        return value
    raise _fail("a number (its hold cost) or {hold: number, start: number}", value)


class PropositionCost(_Model):
    """What a step arriving in a position where the proposition holds pays (a negative cost is
    a reward)."""

    hold: Number = Field(default=0.0, description="Paid on every step arriving where it holds.")
    start: Number = Field(
        default=0.0,
        description="Paid on every step arriving where it holds from where it did not hold.",
    )


PropositionCostEntry = Annotated[
    PropositionCost,
    BeforeValidator(_proposition_cost),
    WithJsonSchema(
        {
            "description": "A number (the hold cost) or {hold: number, start: number}.",
            "oneOf": [
                {"type": "number"},
                {
                    "type": "object",
                    "properties": {"hold": {"type": "number"}, "start": {"type": "number"}},
                    "additionalProperties": False,
                },
            ],
        }
    ),
]


class TransitionRule(_Model):
    """A cost on the automaton transitions that match: from a state of the obligation
    ``from`` (a location's, as mitlc compile prints it), reading a letter where ``when``
    holds, into a state of the obligation ``to`` (docs/costs.md)."""

    source: str | None = Field(
        default=None,
        alias="from",
        description="The source state's obligation, as mitlc compile prints a location's (clock "
        "names optional); left out: every state.",
    )
    when: str = Field(
        default="true",
        description="A Boolean formula over the propositions, on the letter the transition reads.",
    )
    to: str | None = Field(
        default=None, description="The target state's obligation; left out: any target."
    )
    cost: Number = Field(description="Paid on each step whose transition matches.")


class CostsSection(_Model):
    """Costs paid on the steps of an episode, beside its success: the checker reports the least
    expected cost among the policies of best success (docs/costs.md)."""

    step: Number = Field(default=0.0, description="Paid on every step.")
    actions: dict[str, Number] = Field(
        default_factory=dict, description="Paid on every step taking the named action."
    )
    propositions: dict[Proposition, PropositionCostEntry] = Field(
        default_factory=dict,
        description="Per proposition, what a step arriving where it holds pays: a number (hold) "
        "or {hold: ..., start: ...} (start: only when it did not hold where the step came from).",
    )
    transitions: list[TransitionRule] = Field(
        default_factory=list, description="Costs on the automaton's transitions."
    )


COSTS_DESCRIPTION = (
    "Costs paid on the steps of an episode (negative: rewards): per step, per action, per "
    "proposition and per automaton transition (docs/costs.md)."
)


class TaskFields(_Model):
    """The part every world file has, whatever its world: the task, its rewards, the
    episode's horizon, the discount and the learners' settings."""

    spec: SpecRef = Field(
        description="The task: a spec file's path, relative to this file, or {formula: ...}."
    )
    reward: Reward = Field(default=Reward(), description="The reward terms.")
    horizon: Horizon = Field(
        description=f"The number of steps of an episode (at most {MAX_HORIZON:,})."
    )
    discount: Discount = Field(default=0.99, description="The discount factor, in (0, 1].")
    training: dict[Any, Any] = Field(
        default_factory=dict, description="Settings for the learners: a mapping, free-form."
    )


class WorldFile(TaskFields):
    """A world file: a grid world (an MDP, or a POMDP with an observation model) and its task."""

    name: WorldName | None = Field(
        default=None,
        description="The world's name (default: the file's stem), which names its run "
        "directories: printable, without / or \\ or a leading '.'.",
    )
    grid: Grid = Field(description="The grid's size: its rows and columns.")
    blocked: Cells = Field(
        default_factory=list, description="Cells the robot can never be in: [row, col] each."
    )
    labels: dict[Proposition, GridLabel] = Field(
        default_factory=dict,
        description="For each proposition, the free cells where it holds, or {cells: [...], "
        "probability: p}: it holds there with probability p, independently at each step. Every "
        "proposition of the spec must label a cell; others are allowed and ignored.",
    )
    start: Start = Field(
        description="The robot's first cell: [row, col]; a list of cells (drawn uniformly); "
        "{cells: [...], weights: [...]}; or uniform (every free cell)."
    )
    actions: list[Action] = Field(
        default_factory=lambda: list(ACTIONS),
        min_length=1,
        description="The actions, in this order (default: up, down, left, right, stay). Up is "
        "towards row 0; 'stay' is certain.",
    )
    motion: Motion = Field(description="The motion model of the four moves.")
    walls: list[Side] = Field(
        default_factory=list,
        description="Sides the robot cannot cross: [[r, c], [r, c]] (adjacent cells) or "
        "[[r, c], N|W|S|E]. The grid's edge is a wall already.",
    )
    doors: list[Side] = Field(
        default_factory=list,
        description="Sides with a door: the robot goes through; seen as 'door'. Must join two "
        "free cells.",
    )
    windows: list[Side] = Field(
        default_factory=list,
        description="Sides with a window: the robot cannot cross; seen as 'window'. May be on "
        "the grid's edge.",
    )
    observation: Observation | None = Field(
        default=None,
        description="The observation model; null (the default) for a fully observed MDP.",
    )
    costs: CostsSection | None = Field(default=None, description=COSTS_DESCRIPTION)


MODELS: dict[tuple[str, ...], type[BaseModel]] = {
    (): WorldFile,
    ("grid",): Grid,
    ("motion",): Motion,
    ("observation", "noisy-cell"): NoisyCell,
    ("observation", "local-pattern"): LocalPattern,
    ("spec", "inline"): InlineSpec,
    ("reward",): Reward,
    ("costs",): CostsSection,
    ("costs", "propositions", "*"): PropositionCost,
    ("costs", "transitions", "*"): TransitionRule,
    ("start", "weighted"): WeightedStart,
    ("labels", "*", "uncertain"): UncertainLabel,
}
"""The model at each place of the file, by pydantic's error location (union tags included; a
list index, a label's or a priced proposition's name, as ``*``)."""
OBSERVATION_TYPES = ("noisy-cell", "local-pattern")
