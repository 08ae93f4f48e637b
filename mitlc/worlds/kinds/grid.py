"""The grid kind: a world file with ``grid:`` (and no ``robots:``), a single robot on a grid
MDP or POMDP (:mod:`mitlc.worlds.grid` is its geometry and models; its drawn starts and
uncertain labels are :mod:`mitlc.worlds.uncertain`'s)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from mitlc.worlds.grid import GridMap, Layout, check, local_pattern, noisy_cell, transitions
from mitlc.worlds.model import Observations, World
from mitlc.worlds.schema import LocalPattern, WorldFile, label_cells
from mitlc.worlds.source import (
    Source,
    WorldError,
    from_pydantic,
    require_labelled,
    task_of,
    world_costs,
)
from mitlc.worlds.uncertain import label_letters, start_cells, start_of


def claims(data: Mapping[str, Any]) -> bool:
    """A grid world file is any mapping the other kinds do not claim (its errors then say
    what a grid needs)."""
    return True


def validate(path: Path, source: Source) -> tuple[WorldFile, Layout]:
    """The grid file's shape (pydantic) and its whole-file checks (:func:`grid.check`)."""
    filename = str(path)
    try:
        world = WorldFile.model_validate(source.data)
    except ValidationError as err:
        problems = [source.locate(p, m, key=k) for p, m, k in from_pydantic(err)]
        raise WorldError(filename, problems) from None
    layout, found = check(world)
    if found:
        raise WorldError(filename, [source.locate(p, m) for p, m in found])
    return world, layout


@dataclass(frozen=True, slots=True)
class GridDeclaration:
    """A validated grid world file (see the module docstring)."""

    path: Path
    source: Source
    file: WorldFile
    layout: Layout
    kind = "grid"

    @staticmethod
    def read(path: Path, source: Source) -> GridDeclaration:
        """The declaration of the grid file at ``path`` (its YAML already read: ``source``)."""
        return GridDeclaration(path, source, *validate(path, source))

    @property
    def name(self) -> str:
        """The world's name: the file's ``name``, else the file's stem."""
        return self.file.name or self.path.stem

    def finite(self, spec: str | None = None) -> World:
        """The world: a grid is finite."""
        return self.build(spec)

    def build(self, spec: str | None = None) -> World:
        """The world, its task replaced by ``spec`` (a formula's text) when given."""
        path, source, world, layout = self.path, self.source, self.file, self.layout
        text, spec_source, propositions = task_of(world, path, source, spec)
        cells = layout.cells()
        missing = [p for p in propositions if not label_cells(world.labels.get(p, []))[0]]
        told = (text, spec_source)
        require_labelled(path, source, told, missing, world.labels, "labels no cell")
        costs, propositions = world_costs(world, path, source, propositions, world.actions)
        states = label_letters(cells, world.labels, propositions)
        starts = start_cells(layout, world.start)
        index = {cell: c for c, cell in enumerate(cells)}
        start, distribution = start_of(states.starts([(index[c], p) for c, p in starts]))
        observations: Observations | None = None
        if isinstance(world.observation, LocalPattern):
            observations = local_pattern(layout)
        elif world.observation is not None:
            observations = noisy_cell(
                layout, world.observation.correct, world.observation.neighbourhood
            )
        drawing = GridMap(
            layout,
            tuple((p, tuple(label_cells(label)[0])) for p, label in sorted(world.labels.items())),
            tuple(cell for cell, _ in starts),
        )
        motion = transitions(layout, world.actions, world.motion)
        return World(
            name=self.name,
            rows=layout.rows,
            cols=layout.cols,
            cells=tuple(cells[c] for c in states.cell.tolist()),
            actions=tuple(world.actions),
            start=start,
            start_distribution=distribution,
            transitions=states.transitions(motion, len(world.actions)),
            propositions=propositions,
            letters=states.letter,
            spec=text,
            spec_source=spec_source,
            horizon=world.horizon,
            discount=world.discount,
            rewards=world.reward.rewards(),
            observations=states.observations(observations),
            costs=costs,
            training=dict(world.training),
            drawing=drawing,
        )
