"""Labelling functions: each declarative form, the field-path errors of bad declarations, the
checks against an observation space, per-state letters of a discrete env, and pickling."""

from __future__ import annotations

import pickle
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces

from mitlc.errors import MitlcError
from mitlc.gym import TaskWrapper
from mitlc.labels import (
    CachedLetters,
    DeclaredLetters,
    LabelDeclarationError,
    Labeller,
    compile_labels,
    letter_reader,
    letters_of_states,
)

TAXI = {"radices": [5, 5, 5, 4], "fields": ["row", "col", "passenger", "destination"]}
PLANE = spaces.Box(-5.0, 5.0, (3,), np.float32)
PARTS = spaces.Dict({"pos": spaces.Box(-5.0, 5.0, (2,), np.float32), "door": spaces.Discrete(3)})


def holds(labels: Labeller, obs: Any, info: dict[str, Any] | None = None) -> set[str]:
    return set(labels(obs, info or {}))


# -- the forms ---------------------------------------------------------------------------------


def test_obs_form_accepts_ints_and_numpy_ints() -> None:
    labels = compile_labels({"goal": {"obs": [15, 3]}}, spaces.Discrete(16))
    assert holds(labels, 15) == holds(labels, np.int64(3)) == {"goal"}
    assert holds(labels, 4) == set()


def test_decoded_form_reads_mixed_radix_like_taxi() -> None:
    taxi: Any = gym.make("Taxi-v4").unwrapped
    labels = compile_labels(
        {
            "in_taxi": {"decoded": {**TAXI, "where": {"passenger": [4]}}},
            "corner": {"decoded": {**TAXI, "where": {"row": [0, 4], "col": [0, 4]}}},
            "there": {"decoded": {**TAXI, "where": {"passenger": "destination"}}},
        },
        taxi.observation_space,
    )
    for s in range(500):
        row, col, passenger, destination = taxi.decode(s)
        expected = {"in_taxi"} if passenger == 4 else set()
        expected |= {"there"} if passenger == destination else set()
        expected |= {"corner"} if row in (0, 4) and col in (0, 4) else set()
        assert holds(labels, s) == expected


def test_box_and_disc_forms_are_closed() -> None:
    labels = compile_labels(
        {
            "room": {"box": {"index": [0, 1], "low": [0.0, 0.0], "high": [1.0, 2.0]}},
            "spot": {"disc": {"index": [0, 2], "center": [2.0, 3.0], "radius": 0.5}},
        },
        PLANE,
    )
    assert holds(labels, np.array([1.0, 2.0, 9.0])) == {"room"}
    assert holds(labels, np.array([1.0, 2.01, 0.0])) == set()
    assert holds(labels, np.array([2.5, 0.0, 3.0])) == {"spot"}
    assert holds(labels, np.array([2.5, 0.0, 3.01])) == set()


def test_info_form_and_lists_of_forms() -> None:
    labels = compile_labels({"done": [{"info": "reached"}, {"obs": [7]}]})
    assert holds(labels, 0, {"reached": 1}) == holds(labels, 7) == {"done"}
    assert holds(labels, 0, {"reached": 0}) == holds(labels, 0) == set()


def test_key_picks_the_part_of_a_dict_observation() -> None:
    labels = compile_labels(
        {
            "open": {"obs": [2], "key": "door"},
            "near": {"disc": {"index": [0, 1], "center": [0, 0], "radius": 1, "key": "pos"}},
        },
        PARTS,
    )
    assert holds(labels, {"door": 2, "pos": np.zeros(2)}) == {"open", "near"}
    assert holds(labels, {"door": 1, "pos": np.ones(2)}) == set()


def test_letters_of_states_uses_the_same_definition() -> None:
    declared = {"goal": {"obs": [15]}, "hole": {"obs": [5, 7, 11, 12]}}
    letters = letters_of_states(declared, 16, ("hole", "goal"))
    assert letters.dtype == np.int64 and letters.tolist()[5] == 1 and letters[15] == 2
    assert int(letters.sum()) == 4 * 1 + 2
    assert letters_of_states(
        lambda obs, info: {"goal"} if obs == 2 else (), 3, ("goal",)
    ).tolist() == [0, 0, 1]


def test_readers_memoise_discrete_observations_and_pickle() -> None:
    labels = compile_labels({"a": {"obs": [1]}, "b": {"info": "b"}})
    assert isinstance(labels.letter_reader(["a"]), CachedLetters)
    mixed = labels.letter_reader(["b", "a"])
    assert isinstance(mixed, DeclaredLetters)
    assert mixed(1, {"b": True}) == 3 and mixed(1, {}) == 2
    reader = labels.letter_reader(["a"])
    assert [reader(s, {}) for s in (0, 1, 1, np.int64(1))] == [0, 1, 1, 1]
    copy = pickle.loads(pickle.dumps(reader))
    assert copy(1, {}) == 1 and pickle.loads(pickle.dumps(labels)) == labels


def test_callable_labels_give_letters_by_name() -> None:
    read = letter_reader(lambda obs, info: ["b", "zzz"] if obs else [], ("a", "b"))
    assert read(1, {}) == 2 and read(0, {}) == 0


# -- errors ------------------------------------------------------------------------------------


def goal(form: str, body: Any, **beside: Any) -> dict[str, Any]:
    """``{"goal": {form: body, **beside}}``."""
    return {"goal": {form: body, **beside}}


def box(**fields: Any) -> dict[str, Any]:
    return goal("box", {"index": [0], "low": [0], "high": [1], **fields})


def disc(**fields: Any) -> dict[str, Any]:
    return goal("disc", {"index": [0], "center": [0], "radius": 1, **fields})


def decoded(**fields: Any) -> dict[str, Any]:
    return goal("decoded", {**TAXI, "where": {"passenger": [4]}, **fields})


BAD = [
    ([1, 2], None, "labels: expected a mapping"),
    ({"2x": {"obs": [1]}}, None, "labels: '2x' is not a proposition name"),
    (goal("room", [1]), None, "labels.goal: unknown form 'room'"),
    (goal("obs", [1], info="x"), None, "labels.goal: expected exactly one"),
    ({"goal": {}}, None, "labels.goal: expected exactly one"),
    ({"goal": []}, None, "labels.goal: expected at least one form"),
    ({"goal": "obs"}, None, "labels.goal: expected a mapping"),
    (goal("obs", "15"), None, "labels.goal.obs: expected a list of integers"),
    (goal("obs", [1.5]), None, "labels.goal.obs: expected a list of integers"),
    (goal("obs", [True]), None, "labels.goal.obs: expected a list of integers"),
    ({"goal": [{"obs": [1]}, {"obs": 3}]}, None, r"labels.goal\[1\].obs: expected a list"),
    (goal("obs", [16]), spaces.Discrete(16), "labels.goal.obs: 16 is outside"),
    (goal("obs", [1]), PLANE, "labels.goal.obs: needs a Discrete observation"),
    (goal("info", 3), None, "labels.goal.info: expected a dotted path"),
    (goal("box", {"index": [0], "low": [0]}), None, "labels.goal.box: missing field 'high'"),
    (box(lo=1), None, "labels.goal.box: unknown field 'lo'"),
    (box(index=[3]), PLANE, "labels.goal.box.index: index 3 is out of range"),
    (box(index=[-1]), None, "labels.goal.box.index: expected a non-empty"),
    (box(low=[0, 1]), None, "labels.goal.box.low: expected 1 numbers"),
    (box(low=[2]), None, "labels.goal.box: low is above high"),
    (box(low=["a"]), None, "labels.goal.box.low: expected a list of finite"),
    (box(), spaces.Discrete(4), "labels.goal.box.index: needs a one-dimensional Box"),
    (disc(radius=-0.5), None, "labels.goal.disc.radius: expected a non-negative number"),
    (disc(radius="1"), None, "labels.goal.disc.radius: expected a non-negative number"),
    (decoded(), spaces.Discrete(400), "labels.goal.decoded.radices: their product 500"),
    (decoded(where={"seat": [4]}), None, "labels.goal.decoded.where: unknown field 'seat'"),
    (decoded(where={"passenger": [5]}), None, "labels.goal.decoded.where.passenger: 5 is not"),
    (decoded(fields=["a"]), None, "labels.goal.decoded.fields: expected 4 names"),
    (decoded(where={"row": "row"}), None, "labels.goal.decoded.where.row: 'row' is not another"),
    (goal("obs", [1], key="door"), spaces.Discrete(4), "labels.goal.key: the observation space"),
    (goal("obs", [1]), PARTS, "labels.goal: the observation is a Dict: name its part"),
    (goal("obs", [1], key="lid"), PARTS, "labels.goal.key: unknown part 'lid'"),
    ({"goal": {**box()["goal"], "key": "pos"}}, PARTS, "labels.goal.key: not allowed beside"),
]


@pytest.mark.parametrize(("declarations", "space", "message"), BAD)
def test_bad_declarations_name_the_field(declarations: Any, space: Any, message: str) -> None:
    with pytest.raises(LabelDeclarationError, match=f"^{message}"):
        compile_labels(declarations, space)


def test_the_error_is_typed() -> None:
    assert issubclass(LabelDeclarationError, MitlcError)
    assert issubclass(LabelDeclarationError, ValueError)


def test_a_task_proposition_no_label_declares_is_refused() -> None:
    env = gym.make("FrozenLake-v1")
    with pytest.raises(LabelDeclarationError, match=r"propositions \['hole'\] are not declared"):
        TaskWrapper(env, "F goal & G !hole", {"goal": {"obs": [15]}}, horizon=10)
    with pytest.raises(LabelDeclarationError, match=r"labels\.goal\.obs: 99 is outside"):
        TaskWrapper(env, "F goal", {"goal": {"obs": [99]}}, horizon=10)
