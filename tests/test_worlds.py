"""Worlds: the paper's worlds and their defining facts, hand-worked rows of the motion and
observation models, the error message of every bad world file (golden files), and the JSON
schema exported for editors."""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mitlc.errors import MitlcError
from mitlc.worlds import World, WorldError, load_world, read_world_file, world_json_schema
from tests.conftest import GOLDEN, ROOT, check_golden

PAPER = ROOT / "specs" / "paper"
WORLDS = {name: PAPER / f"{name}.yaml" for name in ("case1", "case1-cost", "case2", "case3-office")}
BAD = sorted((ROOT / "tests" / "worlds").glob("*.yaml"))
TOLERANCE = 1e-12


@pytest.fixture(scope="module")
def worlds() -> dict[str, World]:
    return {name: load_world(path) for name, path in WORLDS.items()}


def row(world: World, cell: tuple[int, int], action: str) -> dict[tuple[int, int], float]:
    """The next-cell distribution of ``action`` in ``cell``."""
    r = world.state_of(cell) * world.num_actions + world.actions.index(action)
    targets, probs = world.transitions.row(r)
    return {world.cells[int(t)]: float(p) for t, p in zip(targets, probs, strict=True)}


def observed(world: World, cell: tuple[int, int]) -> dict[str, float]:
    """The observation distribution in ``cell``, by observation name."""
    assert world.observations is not None
    ids, probs = world.observations.model.row(world.state_of(cell))
    names = world.observations.names
    return {names[int(i)]: float(p) for i, p in zip(ids, probs, strict=True)}


def approx(dist: dict[Any, float]) -> Any:
    return pytest.approx(dist, abs=TOLERANCE)


# --- the paper's worlds ----------------------------------------------------------------------


def test_paper_worlds_have_their_sizes(worlds: dict[str, World]) -> None:
    sizes = {name: (w.rows, w.cols, w.num_states, w.num_actions) for name, w in worlds.items()}
    assert sizes == {
        "case1": (5, 5, 24, 5),
        "case1-cost": (5, 5, 24, 5),
        "case2": (10, 10, 88, 5),
        "case3-office": (4, 4, 16, 5),
    }
    assert [w.is_pomdp for w in worlds.values()] == [False, False, True, True]
    assert worlds["case1"].propositions == ("a", "b")
    assert worlds["case3-office"].propositions == ("a", "printer")
    assert worlds["case1"].rewards.move == 0 and worlds["case1-cost"].rewards.move == -5


@pytest.mark.parametrize("name", WORLDS)
def test_every_row_is_a_distribution(worlds: dict[str, World], name: str) -> None:
    world = worlds[name]
    models = [world.transitions]
    if world.observations is not None:
        models.append(world.observations.model)
    for model in models:
        assert np.all(model.probs > 0)
        for r in range(model.num_rows):
            targets, probs = model.row(r)
            assert np.all(np.diff(targets) > 0), "targets sorted, no duplicates"
            assert abs(probs.sum() - 1.0) <= TOLERANCE
    assert world.transitions.num_rows == world.num_states * world.num_actions


@pytest.mark.parametrize("name", WORLDS)
def test_stay_is_certain(worlds: dict[str, World], name: str) -> None:
    world = worlds[name]
    for cell in world.cells:
        assert row(world, cell, "stay") == {cell: 1.0}


def test_paper_worlds_name_their_specs(worlds: dict[str, World]) -> None:
    world = worlds["case1"]
    assert world.spec_source == str(PAPER / "case1.mitl")
    assert world.spec == (PAPER / "case1.mitl").read_text(encoding="utf-8")
    assert world.cells[world.start] == (4, 4)
    letters = {world.cells[s]: int(letter) for s, letter in enumerate(world.letters) if letter}
    assert letters == {(0, 3): 1, (3, 0): 2}
    office = worlds["case3-office"]
    assert {office.cells[s] for s, x in enumerate(office.letters) if x == 2} == {(1, 3)}


def test_office_has_13_observations_and_b_looks_like_c(worlds: dict[str, World]) -> None:
    office = worlds["case3-office"]
    assert office.observations is not None
    assert len(office.observations.names) == 13
    assert sorted(office.observations.names) == list(office.observations.names)
    assert all(list(observed(office, c).values()) == [1.0] for c in office.cells)
    assert observed(office, (0, 0)) == observed(office, (1, 0)) == {"wall,wall,wall,door": 1.0}
    assert observed(office, (0, 3)) == {"window,door,wall,window": 1.0}  # office a
    assert observed(office, (2, 3)) == {"wall,hallway,wall,wall": 1.0}  # the supply alcove


def test_noisy_cell_sees_the_true_cell_with_probability_0_9(worlds: dict[str, World]) -> None:
    world = worlds["case2"]
    assert world.observations is not None
    assert world.observations.names[:2] == ("r0c0", "r0c1")
    for s, cell in enumerate(world.cells):
        assert observed(world, cell)[f"r{cell[0]}c{cell[1]}"] == pytest.approx(0.9)
        assert world.observations.names[s] == f"r{cell[0]}c{cell[1]}"
    # The corner sees its two neighbours; (6, 2) has (5, 2) blocked above it.
    assert observed(world, (9, 0)) == approx({"r9c0": 0.9, "r8c0": 0.05, "r9c1": 0.05})
    third = 0.1 / 3
    expected = {"r6c2": 0.9, "r6c1": third, "r7c2": third, "r6c3": third}
    assert observed(world, (6, 2)) == approx(expected)


# --- hand-worked rows of the motion model ----------------------------------------------------


@pytest.mark.parametrize(
    ("cell", "action", "expected"),
    [
        ((4, 4), "up", {(3, 4): 0.8, (4, 3): 0.1, (4, 4): 0.1}),  # corner: right is off the grid
        ((4, 4), "right", {(4, 4): 0.9, (3, 4): 0.1}),  # into the edge: stays, or slips up
        ((0, 0), "left", {(0, 0): 0.9, (1, 0): 0.1}),
        ((2, 1), "right", {(2, 1): 0.8, (1, 1): 0.1, (3, 1): 0.1}),  # into the blocked cell
        ((1, 2), "down", {(1, 2): 0.8, (1, 1): 0.1, (1, 3): 0.1}),
        ((3, 2), "left", {(3, 1): 0.8, (3, 2): 0.1, (4, 2): 0.1}),  # the slip up is blocked
    ],
)
def test_case1_motion_rows(
    worlds: dict[str, World],
    cell: tuple[int, int],
    action: str,
    expected: dict[tuple[int, int], float],
) -> None:
    assert row(worlds["case1"], cell, action) == approx(expected)


@pytest.mark.parametrize(
    ("cell", "action", "expected"),
    [
        # Open hallway: 0.1 spread over the three other ways.
        ((2, 2), "up", {(1, 2): 0.9, (2, 1): 0.1 / 3, (3, 2): 0.1 / 3, (2, 3): 0.1 / 3}),
        ((0, 0), "right", {(0, 1): 0.9, (0, 0): 0.1}),  # through b's door; nothing else feasible
        ((0, 0), "down", {(0, 0): 0.9, (0, 1): 0.1}),  # into the wall b | c
        ((0, 3), "up", {(0, 3): 0.9, (0, 2): 0.1}),  # into a's window
        ((0, 2), "right", {(0, 3): 0.9, (0, 1): 0.05, (1, 2): 0.05}),  # through a's door
        ((3, 0), "up", {(3, 0): 0.9, (3, 1): 0.1}),  # the wall below storage
        ((2, 3), "left", {(2, 2): 0.9, (2, 3): 0.1}),  # out of the supply alcove
    ],
)
def test_office_motion_rows(
    worlds: dict[str, World],
    cell: tuple[int, int],
    action: str,
    expected: dict[tuple[int, int], float],
) -> None:
    assert row(worlds["case3-office"], cell, action) == approx(expected)


def write_world(tmp_path: Path, **changes: Any) -> Path:
    """A small valid world (3x3, one blocked cell) with ``changes``, written to a file."""
    data: dict[str, Any] = {
        "grid": {"rows": 3, "cols": 3},
        "blocked": [[1, 1]],
        "labels": {"a": [[0, 0]]},
        "start": [2, 2],
        "motion": {"intended": 0.8, "sideways": 0.1},
        "spec": {"formula": "F a"},
        "horizon": 10,
    } | changes
    path = tmp_path / "world.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


def test_noisy_cell_with_8_neighbours_and_defaults(tmp_path: Path) -> None:
    observation = {"type": "noisy-cell", "correct": 0.6, "neighbourhood": 8}
    world = load_world(write_world(tmp_path, observation=observation, name=None))
    assert world.name == "world" and world.discount == 0.99 and world.spec_source == "<inline>"
    assert world.actions == ("up", "down", "left", "right", "stay")
    # (0, 1) sees (0, 0), (0, 2), (1, 0), (1, 2) around it; (1, 1) is blocked.
    around = {name: 0.1 for name in ("r0c0", "r0c2", "r1c0", "r1c2")}
    assert observed(world, (0, 1)) == approx({"r0c1": 0.6} | around)


def test_walls_windows_doors_and_spread(tmp_path: Path) -> None:
    sides = {
        "walls": [[[0, 0], [0, 1]]],
        "windows": [[[0, 2], "N"], [[1, 2], [2, 2]]],
        "doors": [[[0, 1], [0, 2]]],
    }
    motion = {"intended": 0.7, "spread": 0.3}
    world = load_world(write_world(tmp_path, motion=motion, **sides))
    assert row(world, (0, 0), "right") == approx({(0, 0): 0.7, (1, 0): 0.3})
    assert row(world, (0, 1), "right") == approx({(0, 2): 0.7, (0, 1): 0.3})  # door
    assert row(world, (2, 2), "up") == approx({(2, 2): 0.7, (2, 1): 0.3})  # window
    read = read_world_file(write_world(tmp_path, training={"episodes": 5}))
    assert read.training == {"episodes": 5}


def test_actions_keep_their_order(tmp_path: Path) -> None:
    world = load_world(write_world(tmp_path, actions=["stay", "left"]))
    assert world.actions == ("stay", "left")
    assert world.transitions.num_rows == 2 * world.num_states
    assert row(world, (2, 2), "left") == approx({(2, 1): 0.8, (1, 2): 0.1, (2, 2): 0.1})


# --- bad world files -------------------------------------------------------------------------


def test_there_are_at_least_15_bad_worlds() -> None:
    assert len(BAD) >= 15


@pytest.mark.parametrize("path", BAD, ids=[p.stem for p in BAD])
def test_bad_world_message_matches_golden(
    path: Path, update_golden: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(ROOT)
    relative = path.relative_to(ROOT)
    with pytest.raises(WorldError) as info:
        load_world(relative)
    text = info.value.render()
    assert isinstance(info.value, MitlcError) and str(info.value) == text
    for problem in info.value.problems:
        assert problem.render(str(relative)).startswith(f"{relative}:")
    check_golden(GOLDEN / "worlds" / f"{path.stem}.err", text + "\n", update_golden)


def test_a_missing_world_file(tmp_path: Path) -> None:
    with pytest.raises(WorldError, match="cannot read the world file: No such file"):
        load_world(tmp_path / "nope.yaml")


json_values = st.recursive(
    st.none() | st.booleans() | st.integers(-3, 12) | st.floats(-1, 2) | st.text(max_size=4),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=4), inner),
    max_leaves=6,
)
FIELDS = ["grid", "blocked", "labels", "start", "motion", "walls", "doors", "spec", "horizon"]


@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(field=st.sampled_from(FIELDS), value=json_values)
def test_any_bad_value_is_a_world_error(tmp_path: Path, field: str, value: Any) -> None:
    try:
        world = load_world(write_world(tmp_path, **{field: value}))
    except WorldError as err:
        assert "Traceback" not in err.render() and err.problems
    else:
        assert world.num_states > 0


# --- the JSON schema -------------------------------------------------------------------------


def test_json_schema_describes_every_field() -> None:
    schema = world_json_schema()
    json.dumps(schema)
    assert schema["type"] == "object" and schema["additionalProperties"] is False
    assert set(schema["required"]) == {"grid", "start", "motion", "spec", "horizon"}
    for name, prop in schema["properties"].items():
        assert prop.get("description"), f"{name} has no description"


def schema_errors(value: Any, schema: dict[str, Any], root: dict[str, Any]) -> list[str]:
    """The keywords of ``schema`` that ``value`` breaks: the subset of JSON Schema that
    ``world_json_schema`` uses (jsonschema is not a dependency)."""
    if "$ref" in schema:
        return schema_errors(value, root["$defs"][schema["$ref"].split("/")[-1]], root)
    kinds: dict[str, Any] = {"object": dict, "array": list, "string": str, "integer": int}
    kinds |= {"number": (int, float), "null": type(None)}
    errors: list[str] = []
    kind = schema.get("type")
    if kind == "boolean":
        return [] if isinstance(value, bool) else [f"{value!r} is not of type boolean"]
    if kind and (isinstance(value, bool) or not isinstance(value, kinds[kind])):
        return [f"{value!r} is not of type {kind}"]
    for key in ("anyOf", "oneOf"):
        if key in schema:
            fits = [not schema_errors(value, sub, root) for sub in schema[key]]
            if sum(fits) == 0 or (key == "oneOf" and sum(fits) > 1):
                errors.append(f"{value!r} fits {sum(fits)} of {key}")
    if value not in schema.get("enum", [value]) or schema.get("const", value) != value:
        errors.append(f"{value!r} is not allowed")
    if isinstance(value, int | float):
        if value < schema.get("minimum", value) or value > schema.get("maximum", value):
            errors.append(f"{value!r} is out of range")
        if "exclusiveMinimum" in schema and value <= schema["exclusiveMinimum"]:
            errors.append(f"{value!r} is too small")
    if isinstance(value, list):
        if not schema.get("minItems", 0) <= len(value) <= schema.get("maxItems", len(value)):
            errors.append(f"{value!r} has the wrong length")
        subs = schema.get("prefixItems", []) + [schema.get("items", {})] * len(value)
        for item, sub in zip(value, subs, strict=False):
            errors += schema_errors(item, sub, root)
    if isinstance(value, dict):
        errors += [f"{k!r} is required" for k in schema.get("required", []) if k not in value]
        for key, item in value.items():
            patterns = schema.get("patternProperties", {})
            sub = schema.get("properties", {}).get(key)
            sub = sub or next((v for p, v in patterns.items() if re.match(p, key)), None)
            if sub is None and schema.get("additionalProperties") is False:
                errors.append(f"{key!r} is not allowed")
            errors += schema_errors(item, sub or {}, root)
    return errors


@pytest.mark.parametrize("name", WORLDS)
def test_json_schema_accepts_the_paper_worlds(name: str) -> None:
    schema = world_json_schema()
    data = yaml.safe_load(WORLDS[name].read_text(encoding="utf-8"))
    assert schema_errors(data, schema, schema) == []


@pytest.mark.parametrize(
    "name", ["unknown-field", "horizon-text", "discount-range", "action-unknown", "label-name"]
)
def test_json_schema_refuses_bad_shapes(name: str) -> None:
    schema = world_json_schema()
    data = yaml.safe_load((ROOT / "tests" / "worlds" / f"{name}.yaml").read_text(encoding="utf-8"))
    assert schema_errors(data, schema, schema) != []


@pytest.mark.parametrize(("kind", "folder"), [("env-world", "gym"), ("plane-world", "continuous")])
def test_json_schemas_of_env_and_plane_worlds_accept_the_shipped_ones(
    kind: str, folder: str
) -> None:
    schema = world_json_schema(kind)
    json.dumps(schema)
    assert schema["type"] == "object" and schema["additionalProperties"] is False
    for name, prop in schema["properties"].items():
        assert prop.get("description"), f"{kind}: {name} has no description"
    files = sorted((ROOT / "specs" / folder).glob("*.yaml"))
    assert len(files) == 3
    for path in files:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
        assert schema_errors(data, schema, schema) == [], path
    bad = {**yaml.safe_load(files[0].read_text(encoding="utf-8")), "horizon": "soon"}
    assert schema_errors(bad, schema, schema) != []


def test_the_json_schema_of_team_worlds_accepts_the_shipped_ones() -> None:
    schema = world_json_schema("team-world")
    assert schema["additionalProperties"] is False and "robots" in schema["required"]
    teams = sorted((ROOT / "specs" / "teams").glob("*.yaml"))
    files = [p for p in teams if "robots" in yaml.safe_load(p.read_text(encoding="utf-8"))]
    assert len(files) >= 3
    for path in files:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
        assert schema_errors(data, schema, schema) == [], path
    bad = {**yaml.safe_load(files[0].read_text(encoding="utf-8")), "start": [0, 0]}
    assert schema_errors(bad, schema, schema) != []
