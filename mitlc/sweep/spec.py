"""A sweep file: which worlds, learners, seeds and settings to train, one trial each.

::

    name: case1-learners             # optional (default: the file's stem)
    worlds:                          # world files, relative to this file
      - ../specs/paper/case1.yaml
      - ../specs/gym/frozenlake4x4.yaml
    learners:                        # a name each: its algorithm and its own settings
      q: {algo: q}
      dqn: {algo: dqn, set: {dqn.num_envs: 8}}
    seeds: 5                         # seeds 0..4, or a list: [0, 7, 9]
    grid:                            # optional: --set paths, each with the values to try
      discount.gamma: [0.95, 0.99]
    episodes: 20000                  # optional: every trial's budget (else each world's own)
    eval_episodes: 1000              # greedy episodes measured at the end of each trial
    cpus_per_trial: 1
    max_failures: 2                  # retries of a trial whose worker dies

Each trial is one world x one learner x one point of the grid (the product of its lists) x one
seed: ``mitlc train`` with the learner's ``algo``, its ``set``, the grid point and the seed as
overrides of the world file's own settings (:func:`mitlc.learn.config.config_for`), then
``mitlc eval``. Every problem is reported with the field's path, the line and the column (a
setting path is checked against every world it runs on): ``sweep.yaml:6:23:
learners.dqn.set.dqn.num_env: training.dqn.num_env: unknown setting ...``.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mitlc.errors import MitlcError
from mitlc.learn.bounds import SWEEP

MAX_TRIALS = int(SWEEP["trials"].high)
"""The most trials one sweep may have (:data:`mitlc.learn.bounds.SWEEP`, as every bound of a
sweep file's numbers)."""
KEYS = ("name", "worlds", "learners", "seeds", "grid", "episodes", "eval_episodes",
        "cpus_per_trial", "max_failures")  # fmt: skip
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")


class SweepError(MitlcError):
    """A sweep file that cannot be used: one line per problem, ``file:line:col: path:
    message``."""


@dataclass(frozen=True, slots=True)
class Learner:
    """A learner of the sweep: its name, algorithm and its own settings (``--set`` paths)."""

    name: str
    algo: str
    settings: tuple[tuple[str, Any], ...] = ()


@dataclass(frozen=True, slots=True)
class Trial:
    """One run of the sweep: a world, a learner, a grid point and a seed."""

    world: str
    """The world file's absolute path."""
    world_name: str
    learner: str
    point: tuple[tuple[str, Any], ...]
    """The grid point: (setting path, value) pairs."""
    seed: int
    overrides: dict[str, Any] = field(hash=False, compare=False)
    """Everything given to the world's settings: algo, the learner's settings, the point, the
    seed and, where the sweep sets it, the episodes."""
    eval_episodes: int = 1000

    @property
    def setting(self) -> str:
        """The learner and grid point, the name a report groups seeds under."""
        if not self.point:
            return self.learner
        return self.learner + "[" + ", ".join(f"{k}={v}" for k, v in self.point) + "]"

    @property
    def trial_id(self) -> str:
        """A stable name, also its run directory's: world, setting and seed, made safe."""
        point = ""
        if self.point:
            digest = hashlib.sha256(json.dumps(self.point).encode()).hexdigest()[:8]
            point = f"-{digest}"
        return f"{_safe(self.world_name)}--{_safe(self.learner)}{point}--s{self.seed}"

    def to_data(self) -> dict[str, Any]:
        """JSON-ready (for Ray's trial config and the trial's ``trial.json``)."""
        return {
            "world": self.world,
            "world_name": self.world_name,
            "learner": self.learner,
            "point": [list(p) for p in self.point],
            "seed": self.seed,
            "overrides": self.overrides,
            "eval_episodes": self.eval_episodes,
        }

    @classmethod
    def from_data(cls, data: Mapping[str, Any]) -> Trial:
        """Read :meth:`to_data`."""
        return cls(
            world=str(data["world"]),
            world_name=str(data["world_name"]),
            learner=str(data["learner"]),
            point=tuple((str(k), v) for k, v in data["point"]),
            seed=int(data["seed"]),
            overrides=dict(data["overrides"]),
            eval_episodes=int(data["eval_episodes"]),
        )


@dataclass(frozen=True, slots=True)
class Sweep:
    """A validated sweep file."""

    name: str
    path: Path
    trials: tuple[Trial, ...]
    cpus_per_trial: float = 1.0
    max_failures: int = 2


def _safe(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", text)[:60] or "_"


def load_sweep(path: str | Path) -> Sweep:
    """Read and validate the sweep file at ``path`` (see the module docstring); a
    :class:`SweepError` naming every problem's field."""
    from mitlc.worlds.source import WorldError, read_yaml

    path = Path(path)
    filename = str(path)
    try:
        source = read_yaml(path, filename, kind="sweep file")
    except WorldError as err:
        raise SweepError(str(err)) from None
    checker = _Checker(path, source)
    sweep = checker.sweep()
    if checker.problems:
        raise SweepError(checker.render())
    assert sweep is not None
    return sweep


class _Checker:
    """Collects every problem of a sweep file, each at its field."""

    def __init__(self, path: Path, source: Any) -> None:
        self.path, self.source = path, source
        self.problems: list[Any] = []
        self.loaded: dict[str, Any] = {}
        """Each world, loaded once (:func:`mitlc.worlds.door.open_world`), by its path."""

    def add(self, where: tuple[str | int, ...], message: str, key: bool = False) -> None:
        self.problems.append(self.source.locate(where, message, key=key))

    def render(self) -> str:
        ordered = sorted(self.problems, key=lambda p: (p.line, p.column))
        return "\n".join(p.render(str(self.path)) for p in ordered)

    def sweep(self) -> Sweep | None:
        data = self.source.data
        if not isinstance(data, dict):
            self.add((), "expected a mapping with worlds, learners and seeds")
            return None
        for key in data:
            if key not in KEYS:
                self.add((str(key),), f"unknown field (known: {', '.join(KEYS)})", key=True)
        for key in ("worlds", "learners", "seeds"):
            if key not in data:
                self.add((), f"{key}: missing")
        name = data.get("name", self.path.stem)
        if not isinstance(name, str) or not _NAME.match(name):
            self.add(("name",), f"expected a name of letters, digits, '_', '.', '-', got {name!r}")
        worlds = self._worlds(data.get("worlds"))
        learners = self._learners(data.get("learners"))
        seeds = self._seeds(data.get("seeds"))
        grid = self._grid(data.get("grid", {}))
        episodes = self._count(data, "episodes", None)
        eval_episodes = self._count(data, "eval_episodes", 1000)
        failures = self._count(data, "max_failures", 2)
        cpus = self._cpus(data.get("cpus_per_trial", 1))
        if self.problems or worlds is None or learners is None or seeds is None or grid is None:
            return None
        sizes = [len(values) for values in grid.values()]  # counted before the grid is expanded
        count = len(worlds) * len(learners) * math.prod(sizes) * len(seeds)
        if count > MAX_TRIALS:
            self.add((), f"{count:,} trials: more than {MAX_TRIALS:,} (mitlc's limit)")
            return None
        points = [tuple(zip(grid, values, strict=True)) for values in
                  itertools.product(*grid.values())]  # fmt: skip
        trials = []
        for (world_index, (world, world_name)), learner in itertools.product(
            enumerate(worlds), learners
        ):
            for point in points:
                overrides: dict[str, Any] = {"algo": learner.algo, **dict(learner.settings)}
                overrides.update(dict(point))
                if episodes is not None:
                    overrides["episodes"] = episodes
                if not self._settings_fit(world, world_index, learner, point, overrides):
                    continue
                for seed in seeds:
                    trials.append(Trial(world, world_name, learner.name, point, seed,
                                        {**overrides, "seed": seed}, eval_episodes))  # fmt: skip
        if self.problems:
            return None
        names = [trial.trial_id for trial in trials]
        if len(set(names)) != len(names):
            self.add(("worlds",), "two worlds or learners have the same name: rename one")
            return None
        return Sweep(str(name), self.path, tuple(trials), float(cpus), int(failures))

    # -- the fields ----------------------------------------------------------------------------

    def _worlds(self, value: Any) -> list[tuple[str, str]] | None:
        if not isinstance(value, list) or not value:
            if value is not None:
                self.add(("worlds",), "expected a non-empty list of world files")
            return None
        from mitlc.learn.config import config_for
        from mitlc.worlds.door import open_world

        worlds = []
        for i, item in enumerate(value):
            if not isinstance(item, str) or not item or "\x00" in item:
                self.add(("worlds", i), f"expected a world file's path, got {item!r}")
                continue
            world = (self.path.parent / item).resolve()
            if not world.is_file():
                self.add(("worlds", i), f"unknown world: no file {item!r} (relative to the "
                         "sweep file)")  # fmt: skip
                continue
            try:
                loaded = open_world(world)  # once per world: its settings are checked on it
                _, name = config_for(loaded, {})
                self.loaded[str(world)] = loaded
            except MitlcError as err:
                self.add(("worlds", i), f"the world {item!r} does not load: {_first_line(err)}")
                continue
            worlds.append((str(world), name))
        return worlds

    def _learners(self, value: Any) -> list[Learner] | None:
        from mitlc.learn.config import ALGORITHMS

        if not isinstance(value, dict) or not value:
            if value is not None:
                self.add(("learners",), "expected a mapping of learner names to {algo, set}")
            return None
        learners = []
        for name, spec in value.items():
            where: tuple[str | int, ...] = ("learners", str(name))
            if not isinstance(name, str) or not _NAME.match(name):
                self.add(where, f"{name!r} is not a learner name", key=True)
                continue
            if not isinstance(spec, dict):
                self.add(where, "expected {algo: ..., set: {...}}")
                continue
            for key in spec:
                if key not in ("algo", "set"):
                    self.add((*where, str(key)), "unknown field (known: algo, set)", key=True)
            algo = spec.get("algo")
            if algo not in ALGORITHMS:
                self.add((*where, "algo"), f"expected one of {', '.join(ALGORITHMS)}, got "
                         f"{algo!r}")  # fmt: skip
                continue
            settings = spec.get("set", {})
            if not isinstance(settings, dict):
                self.add((*where, "set"), "expected a mapping of setting paths to values")
                continue
            learners.append(Learner(name, str(algo), tuple(sorted(settings.items()))))
        return learners

    def _seeds(self, value: Any) -> list[int] | None:
        count, each = SWEEP["seeds"], SWEEP["seeds[]"]
        if _whole(value) and count.problem(value) is None:
            return list(range(value))
        if (
            isinstance(value, list) and value
            and all(_whole(s) and each.problem(s) is None for s in value)
        ):  # fmt: skip
            if len(set(value)) != len(value):
                self.add(("seeds",), "a seed is listed twice")
                return None
            return list(value)
        if value is not None:
            self.add(("seeds",), f"expected a count above 0 (at most {count.high:,}) or a "
                     f"non-empty list of seeds in {each.range_text()}, got {value!r}")  # fmt: skip
        return None

    def _grid(self, value: Any) -> dict[str, list[Any]] | None:
        if not isinstance(value, dict):
            self.add(("grid",), "expected a mapping of setting paths to lists of values")
            return None
        grid: dict[str, list[Any]] = {}
        for key, values in value.items():
            if not isinstance(values, list) or not values:
                self.add(("grid", str(key)), f"expected a non-empty list of values, got "
                         f"{values!r}")  # fmt: skip
                continue
            if key in ("seed", "algo"):
                self.add(("grid", str(key)), f"{key} is the sweep's own (seeds, learners)",
                         key=True)  # fmt: skip
                continue
            grid[str(key)] = values
        return grid

    def _count(self, data: dict[str, Any], key: str, default: int | None) -> Any:
        """The whole number at ``key`` within its bound (:data:`mitlc.learn.bounds.SWEEP`)."""
        value = data.get(key, default)
        if value is None:
            return None
        bound = SWEEP[key]
        if not _whole(value):
            self.add((key,), f"expected a whole number in {bound.range_text()}, got {value!r}")
            return default
        problem = bound.problem(value)
        if problem is not None:
            self.add((key,), problem)
            return default
        return value

    def _cpus(self, value: Any) -> float:
        """``cpus_per_trial``: a number within its bound."""
        bound = SWEEP["cpus_per_trial"]
        if isinstance(value, bool) or not isinstance(value, int | float):
            self.add(("cpus_per_trial",), f"expected a number of CPUs in {bound.range_text()}, "
                     f"got {value!r}")  # fmt: skip
            return 1.0
        problem = bound.problem(value)
        if problem is not None:
            self.add(("cpus_per_trial",), problem)
        return float(value)

    def _settings_fit(
        self,
        world: str,
        index: int,
        learner: Learner,
        point: tuple[tuple[str, Any], ...],
        overrides: dict[str, Any],
    ) -> bool:
        """Whether the overrides resolve on ``world``; each bad one reported at its field."""
        from mitlc.learn.config import config_for

        try:
            config_for(self.loaded[world], overrides)
            return True
        except MitlcError:
            pass
        sources: list[tuple[tuple[str | int, ...], str, Any]] = [
            (("learners", learner.name, "set", k), k, v) for k, v in learner.settings
        ]
        sources += [(("grid", k), k, v) for k, v in point]
        found = False
        for where, key, value in sources:
            try:
                config_for(self.loaded[world], {"algo": learner.algo, key: value})
            except MitlcError as err:
                self.add(where, f"{_first_line(err)} (on worlds[{index}])")
                found = True
        if not found:
            try:
                config_for(self.loaded[world], overrides)
            except MitlcError as err:
                self.add(("learners", learner.name), f"{_first_line(err)} (on worlds[{index}])")
        return False


def _whole(value: Any) -> bool:
    """Whether ``value`` is an integer (not a bool)."""
    return isinstance(value, int) and not isinstance(value, bool)


def _first_line(err: BaseException) -> str:
    text = str(err).strip()
    return text.splitlines()[0] if text else type(err).__name__
