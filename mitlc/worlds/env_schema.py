"""The env world file's schema (:class:`EnvWorldFile`): a gymnasium environment named by id,
its labels over the env's observation, ``info``, attributes, reward and termination, and the
occupancy the shaping may read; pydantic models of the YAML, exported as a JSON schema for
editors, with the scalar types and shared sections of :mod:`mitlc.worlds.schema` (worlds made
from it: :mod:`mitlc.worlds.gym_world`)."""

from __future__ import annotations

import re
from typing import Annotated, Any, Literal

from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Discriminator,
    Field,
    Tag,
    WithJsonSchema,
)

from mitlc.worlds.schema import (
    COSTS_DESCRIPTION,
    CostsSection,
    InlineSpec,
    LabelProbability,
    Number,
    PositiveInt,
    PositiveNumber,
    Proposition,
    PropositionCost,
    Reward,
    TaskFields,
    TransitionRule,
    WorldName,
    _fail,
    _is_int,
    _Model,
    _scalar,
)

NAME = "^[A-Za-z_][A-Za-z0-9_-]*$"
"""An action's or a decoded field's name."""


def _env_id(value: object) -> object:
    if not (isinstance(value, str) and value.strip()):
        raise _fail("a gymnasium environment id (a non-empty string, e.g. FrozenLake-v1)", value)
    return value


def _kwarg_key(value: object) -> object:
    if not (isinstance(value, str) and value.isidentifier()):
        raise _fail("an argument's name (a Python identifier)", value)
    return value


def _is_state(value: object) -> bool:
    return _is_int(value) and value >= 0  # type: ignore[operator]


def _states(value: object) -> object:
    if not isinstance(value, list) or not all(map(_is_state, value)):
        raise _fail("a list of observations (integers from 0)", value)
    return value


def _where(value: object) -> object:
    if isinstance(value, str) and re.fullmatch(NAME, value):
        return value
    if isinstance(value, list) and all(map(_is_state, value)):
        return value
    raise _fail("a list of the field's values [0, 1, ...] or another field's name", value)


EnvId = Annotated[str, BeforeValidator(_env_id)]
KwargName = Annotated[str, BeforeValidator(_kwarg_key)]
Name = Annotated[
    str,
    _scalar(
        "a name (a letter or _, then letters, digits, _ or -)",
        lambda v: isinstance(v, str) and bool(re.fullmatch(NAME, v)),
    ),
    Field(json_schema_extra={"pattern": NAME}),
]
States = Annotated[list[int], BeforeValidator(_states)]
Where = Annotated[list[int] | str, BeforeValidator(_where)]


def _module(value: object) -> object:
    if not (isinstance(value, str) and re.fullmatch(MODULE, value)):
        raise _fail("an installed module's dotted name (e.g. minigrid), never a file", value)
    return value


MODULE = r"[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*"
"""A module's dotted name (:data:`mitlc.worlds.env_make.MODULE`)."""
ModuleName = Annotated[str, BeforeValidator(_module), Field(json_schema_extra={"pattern": MODULE})]


class WrapperEntry(_Model):
    """A gymnasium wrapper class from an installed module, and its keyword arguments."""

    model_config = ConfigDict(extra="forbid", frozen=True, populate_by_name=True)
    cls: str = Field(alias="class", description="module:Class, e.g. "
                     "minigrid.wrappers:ImgObsWrapper.")  # fmt: skip
    kwargs: dict[KwargName, Any] = Field(
        default_factory=dict, description="Keyword arguments: YAML scalars, lists and mappings."
    )


def _wrapper(value: object) -> object:
    return {"class": value} if isinstance(value, str) else value


Wrapper = Annotated[
    WrapperEntry,
    BeforeValidator(_wrapper),
    WithJsonSchema(
        {
            "description": "module:Class, or {class: module:Class, kwargs: {...}}",
            "oneOf": [
                {"type": "string", "pattern": f"^{MODULE}:[A-Za-z][A-Za-z0-9_]*$"},
                {
                    "type": "object",
                    "properties": {"class": {"type": "string"}, "kwargs": {"type": "object"}},
                    "required": ["class"],
                    "additionalProperties": False,
                },
            ],
        }
    ),
]


class Env(_Model):
    """A registered gymnasium environment, the installed modules that register it, the
    arguments it is made with and the wrappers put around it."""

    model_config = ConfigDict(extra="forbid", frozen=True, populate_by_name=True)
    id: EnvId = Field(description="A registered gymnasium id, e.g. FrozenLake-v1 or Taxi-v4, or "
                      "module:EnvId (the installed module is imported first).")  # fmt: skip
    imports: list[ModuleName] = Field(
        default_factory=list,
        alias="import",
        description="Installed modules to import first, by dotted name (their import registers "
        "their envs), e.g. [minigrid].",
    )
    kwargs: dict[KwargName, Any] = Field(
        default_factory=dict,
        description="Keyword arguments of gymnasium.make(id, **kwargs): YAML scalars, lists "
        "and mappings only.",
    )
    wrappers: list[Wrapper] = Field(
        default_factory=list,
        description="Gymnasium wrappers applied in order (inside the task wrapper): "
        "'module:Class' or {class: module:Class, kwargs: {...}}.",
    )


ENV_PROBABILITY_DESCRIPTION = (
    "The probability that the proposition is perceived where the form holds, drawn anew at "
    "each position, independently of every other (1: certain; mitlc/labels/chance.py)."
)


class ObsLabel(_Model):
    """A proposition that holds in the listed observations (the env's discrete states)."""

    obs: States = Field(description="The observations where the proposition holds.")
    probability: LabelProbability = Field(default=1.0, description=ENV_PROBABILITY_DESCRIPTION)


class Decoding(_Model):
    """A proposition over the fields of an encoded state: the state id read as a mixed-radix
    number, the first field most significant (as Taxi's ``decode``)."""

    radices: list[PositiveInt] = Field(
        min_length=1, description="The number of values of each field, most significant first."
    )
    fields: list[Name] = Field(min_length=1, description="The fields' names, in the same order.")
    where: dict[Name, Where] = Field(
        description="For each field named, the values where the proposition holds, or another "
        "field's name (the two fields are equal). The proposition holds where every entry does."
    )


class DecodedLabel(_Model):
    """A proposition over the decoded fields of the state."""

    decoded: Decoding = Field(description="The decoding and the condition on its fields.")
    probability: LabelProbability = Field(default=1.0, description=ENV_PROBABILITY_DESCRIPTION)


FORM_KEYS = ("box", "disc", "info", "key", "attr", "reward", "terminated")
"""Keys that make an env world's label one of :mod:`mitlc.labels`' other forms."""


def _label_kind(value: Any) -> str | None:
    if isinstance(value, list):
        return "form"
    if isinstance(value, dict):
        if any(k in value for k in FORM_KEYS):
            return "form"
        decoded = value.get("decoded")
        if isinstance(decoded, dict) and "key" in decoded:
            return "form"
        return "obs" if "obs" in value else "decoded" if "decoded" in value else None
    return None


FormLabel = Annotated[
    dict[str, Any] | list[Any],
    WithJsonSchema(
        {
            "description": "Another of mitlc.labels' forms, or a list of forms.",
            "oneOf": [
                {"type": "array", "minItems": 1},
                {
                    "type": "object",
                    "properties": {
                        "probability": {
                            "type": "number",
                            "exclusiveMinimum": 0,
                            "maximum": 1,
                            "description": ENV_PROBABILITY_DESCRIPTION,
                        }
                    },
                    "anyOf": [
                        *({"required": [key]} for key in FORM_KEYS),
                        {
                            "required": ["decoded"],
                            "properties": {"decoded": {"type": "object", "required": ["key"]}},
                        },
                    ],
                },
            ],
        }
    ),
]
"""A label in another of :mod:`mitlc.labels`' forms (a box or disc in a Box observation, an
``info`` key, a part of a Dict observation, or a list of forms), checked by
:func:`mitlc.labels.compile_labels` against the env's observation space."""

EnvLabel = Annotated[
    Annotated[ObsLabel, Tag("obs")]
    | Annotated[DecodedLabel, Tag("decoded")]
    | Annotated[FormLabel, Tag("form")],
    Discriminator(
        _label_kind,
        custom_error_type="label_kind",
        custom_error_message="expected {obs: [...]}, {decoded: {...}}, {box: {...}}, "
        "{disc: {...}}, {info: path}, {attr: path}, {reward: {...}}, {terminated: true} or a "
        "list of them",
    ),
]


class OccupancySection(_Model):
    """Which cells of a grid over the env's positions are free, for the shaping's distances
    through free space (mitlc/labels/occupancy.py)."""

    cells: list[list[Literal[0, 1]]] = Field(
        min_length=1,
        description="Rows of 0 (free) and 1 (blocked), the top row first as a map prints it, "
        "each as long as the first.",
    )
    cell_size: PositiveNumber = Field(description="The side of a cell, in the env's units.")
    origin: tuple[Number, Number] = Field(
        description="[x, y]: the position of the map's lower-left corner (y points up)."
    )


class EnvWorldFile(TaskFields):
    """A world file naming a gymnasium environment and its task: a finite one (a transition
    table) is checked and learned as a world; any other is learned through the task
    wrapper."""

    name: WorldName | None = Field(
        default=None,
        description="The world's name (default: the file's stem), which names its run "
        "directories: printable, without / or \\ or a leading '.'.",
    )
    env: Env = Field(description="The gymnasium environment: {id: ..., kwargs: {...}}.")
    actions: list[Name] | None = Field(
        default=None,
        min_length=1,
        description="Names of the env's discrete actions, in order (default: the known names "
        "of FrozenLake and Taxi, else a0, a1, ...).",
    )
    labels: dict[Proposition, EnvLabel] = Field(
        default_factory=dict,
        description="For each proposition, where it holds: {obs: [...]} or {decoded: {...}} "
        "for a discrete observation; {box: {index, low, high}}, {disc: {index, center, "
        "radius}} for a Box one; 'key' for a part of a Dict observation; {info: path} or "
        "{attr: path} (a dotted path into info or on env.unwrapped) with a test (equals, in, "
        "below, above, box, disc; none: truthy); the step's events {reward: {below: x}}, "
        "{terminated: true}; or a list of these (any of them). Any form may carry "
        "probability: p beside it (perceived with probability p where it holds, drawn at each "
        "position). Every proposition of the spec must be labelled.",
    )
    costs: CostsSection | None = Field(default=None, description=COSTS_DESCRIPTION)
    occupancy: OccupancySection | None = Field(
        default=None,
        description="For shaping: {cells: [[0, 1, ...], ...], cell_size: ..., origin: [x, y]}, "
        "the free and blocked cells of the positions the labels' regions are over, so that "
        "their distances go around the obstacles (default: the env's own map where mitlc "
        "reads one: a maze's maze_map, a MiniGrid grid; else straight lines).",
    )


ENV_MODELS: dict[tuple[str, ...], type[BaseModel]] = {
    (): EnvWorldFile,
    ("env",): Env,
    ("env", "wrappers", "*"): WrapperEntry,
    ("labels", "*", "obs"): ObsLabel,
    ("labels", "*", "decoded"): DecodedLabel,
    ("labels", "*", "decoded", "decoded"): Decoding,
    ("spec", "inline"): InlineSpec,
    ("reward",): Reward,
    ("costs",): CostsSection,
    ("costs", "propositions", "*"): PropositionCost,
    ("costs", "transitions", "*"): TransitionRule,
    ("occupancy",): OccupancySection,
}
"""The model at each place of an env world file, by pydantic's error location (union tags
included, a label's name as ``*``)."""
