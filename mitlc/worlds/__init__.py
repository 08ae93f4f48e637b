"""Worlds: a YAML file declaring a grid MDP or POMDP and its task, validated into a
:class:`World` of plain arrays (see ``DESIGN.md``, "Worlds (YAML)")."""

from mitlc.worlds.door import load_world, open_world, read_world, read_world_file
from mitlc.worlds.model import Observations, Rewards, Sparse, World
from mitlc.worlds.schema import WorldFile
from mitlc.worlds.schemas import world_json_schema
from mitlc.worlds.source import Problem, WorldError

__all__ = [
    "Observations",
    "Problem",
    "Rewards",
    "Sparse",
    "World",
    "WorldError",
    "WorldFile",
    "load_world",
    "open_world",
    "read_world",
    "read_world_file",
    "world_json_schema",
]
