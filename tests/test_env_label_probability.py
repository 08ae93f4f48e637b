"""Declared env labels with ``probability:`` (:mod:`mitlc.labels.chance`, issue 44 item 3).

The wrapper's draws against their probability and their seed; the finite env world's exact
``check`` against Storm and against hand computations on FrozenLake (deterministic and
slippery) and CliffWalking (a label of the step's events); the wrapper's success against the
exact evaluation of the same fixed policy; the errors with their field paths; the schema.
"""

from __future__ import annotations

import re
import warnings
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
import yaml

from mitlc.automata import translate
from mitlc.check import check
from mitlc.check.drn import storm_label, to_drn
from mitlc.gym import TaskWrapper
from mitlc.labels import LabelDeclarationError, compile_labels, perceive
from mitlc.learn.evaluation.exact import policy_success
from mitlc.product.explicit import build_product
from mitlc.syntax import parse
from mitlc.worlds import World, WorldError, load_world
from mitlc.worlds.uncertain import expand_outcomes

LAKE: dict[str, Any] = {"id": "FrozenLake-v1", "kwargs": {"map_name": "4x4", "is_slippery": False}}
HOLES = [5, 7, 11, 12]
LEFT, DOWN, RIGHT, UP = range(4)


def lake(slippery: bool = False, steps: int = 100) -> gym.Env[Any, Any]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return gym.make(
            "FrozenLake-v1", map_name="4x4", is_slippery=slippery, max_episode_steps=steps
        )


def lake_world(tmp_path: Path, labels: dict[str, Any], formula: str, *, slippery: bool) -> World:
    env = {**LAKE, "kwargs": {**LAKE["kwargs"], "is_slippery": slippery}}
    data = {"name": "lake", "env": env, "labels": labels, "spec": {"formula": formula}}
    return load_world(write(tmp_path, {**data, "horizon": 20}))


def write(tmp_path: Path, data: dict[str, Any], name: str = "world.yaml") -> Path:
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


# --- the wrapper's draws ------------------------------------------------------------------------


def stay_letters(label: dict[str, Any], seed: int, steps: int = 400) -> tuple[list[bool], Any]:
    """``a`` labels FrozenLake's start; the agent stays there (left, on a map that does not
    slip) for ``steps`` steps, each reading the letter drawn at the position before: whether
    ``a`` was perceived at each, and the env's generator's state at the end."""
    labels = {"a": label, "goal": {"obs": [15]}}
    wrapper = TaskWrapper(lake(steps=10 * steps), "F (a & goal)", labels, horizon=steps)
    bit = 1 << wrapper.automaton.propositions.index("a")
    wrapper.reset(seed=seed)
    seen, done = [], False
    while not done:
        _, _, terminated, truncated, info = wrapper.step(LEFT)
        seen.append(bool(info["letter"] & bit))
        done = terminated or truncated
    return seen, wrapper.np_random.bit_generator.state


def test_the_wrapper_perceives_a_label_with_its_probability() -> None:
    """p = 0.7 at the start cell, 4,000 draws over 10 seeds: the frequency lies within four
    standard errors of 0.7; each seed's draws repeat exactly, and two seeds differ."""
    label = {"obs": [0], "probability": 0.7}
    runs = [stay_letters(label, seed)[0] for seed in range(10)]
    draws = np.concatenate(runs)
    assert len(draws) == 4000
    sigma = (0.7 * 0.3 / len(draws)) ** 0.5
    assert abs(draws.mean() - 0.7) < 4 * sigma, draws.mean()
    assert stay_letters(label, 3)[0] == runs[3]
    assert runs[3] != runs[4]


def test_a_certain_label_reads_as_before() -> None:
    """``probability: 1`` reads the letters the plain form reads and draws nothing from the
    env's generator."""
    plain, plain_state = stay_letters({"obs": [0]}, 5)
    certain, certain_state = stay_letters({"obs": [0], "probability": 1}, 5)
    assert plain == certain and all(plain)
    assert plain_state == certain_state
    assert stay_letters({"obs": [0], "probability": 0.5}, 5)[1] != plain_state


def test_the_draw_gives_the_exact_models_outcome_probabilities() -> None:
    """:func:`perceive` on a position with a certain bit and two uncertain ones: each of the
    four letters comes as often as the grid's expansion (:func:`expand_outcomes`, which the
    finite env world reads) says, within four standard errors of 40,000 draws."""
    chances = (4, ((1, 0.3), (2, 0.6)))
    states = expand_outcomes([4], [[(0, 0.3), (1, 0.6)]])
    rng = np.random.default_rng(7)
    n = 40_000
    drawn = np.array([perceive(chances, rng) for _ in range(n)])
    assert states.letter.tolist() == [4, 5, 6, 7]
    for letter, p in zip(states.letter.tolist(), states.prob.tolist(), strict=True):
        sigma = (p * (1 - p) / n) ** 0.5
        assert abs(float((drawn == letter).mean()) - p) < 4 * sigma, (letter, p)


def test_a_list_of_forms_draws_each() -> None:
    """``[{obs: [1]}, {obs: [1, 2], probability: 0.5}]``: certain at 1, w.p. 1/2 at 2;
    two uncertain forms at one position: 1 - (1 - 0.5)(1 - 0.4) = 0.7."""
    labels = compile_labels(
        {
            "a": [{"obs": [1]}, {"obs": [1, 2], "probability": 0.5}],
            "b": [{"obs": [3], "probability": 0.5}, {"obs": [3], "probability": 0.4}],
        }
    )
    read = labels.chance_reader(["a", "b"])
    assert read(1, {}) == (1, ())
    assert read(2, {}) == (0, ((1, 0.5),))
    certain, ((bit, p),) = read(3, {})
    assert (certain, bit) == (0, 2) and p == pytest.approx(0.7)
    assert read(0, {}) == (0, ())


# --- the finite env world, exact --------------------------------------------------------------


def storm_pmax_horizon(world: World, tmp_path: Path) -> tuple[float, float]:
    """``check``'s ``pmax_horizon`` and Storm's on the exported product (as
    tests/test_start_and_uncertain_labels.py exports and compares it)."""
    pytest.importorskip("stormpy")
    from tests.test_start_and_uncertain_labels import start_average, storm_values

    report = check(world, translate(parse(world.spec)))
    product = report.product
    end, h = storm_label(product, "end"), world.horizon
    values = storm_values(to_drn(product), f"Pmax=? [F[{h},{h}] {end}]", tmp_path)
    return report.pmax_horizon, start_average(values, product.starts)


@pytest.mark.parametrize("p", [0.3, 0.7])
def test_a_revisited_label_by_hand_and_storm(p: float, tmp_path: Path) -> None:
    """``a`` at cell 1 (frozen, next to the start) w.p. p; ``F[0,8] a`` reads positions 0 to 8.
    On the map that does not slip the agent steps right, then stays (up bounces off the edge):
    eight fresh draws at positions 1 to 8, so the optimum is p + (1-p)p + ... = 1 - (1-p)^8.
    Slippery, Storm agrees with ``check``."""
    labels = {"a": {"obs": [1], "probability": p}}
    world = lake_world(tmp_path, labels, "F[0,8] a", slippery=False)
    assert world.num_states == 17  # cell 1 with a and without
    mine, storm = storm_pmax_horizon(world, tmp_path)
    assert mine == pytest.approx(1 - (1 - p) ** 8, abs=1e-12)
    assert storm == pytest.approx(mine, abs=1e-9)
    slippery = lake_world(tmp_path, labels, "F[0,8] a", slippery=True)
    mine, storm = storm_pmax_horizon(slippery, tmp_path)
    assert 0.0 < mine < 1 - (1 - p) ** 8
    assert storm == pytest.approx(mine, abs=1e-9)


@pytest.mark.parametrize("slippery", [False, True])
def test_the_goal_is_drawn_once_on_arrival(slippery: bool, tmp_path: Path) -> None:
    """The goal ends the episode, and an ended episode keeps its last letter (the wrapper reads
    no new position): its outcome is drawn once. On the map that does not slip the goal is six
    steps away, so ``F[0,8] goal`` has optimum exactly 0.9; slippery, 0.9 times that of the
    certain goal, and Storm agrees."""
    labels = {"goal": {"obs": [15], "probability": 0.9}, "hole": {"obs": HOLES}}
    world = lake_world(tmp_path, labels, "!hole U[0,8] goal", slippery=slippery)
    mine, storm = storm_pmax_horizon(world, tmp_path)
    assert storm == pytest.approx(mine, abs=1e-9)
    certain = {"goal": {"obs": [15]}, "hole": {"obs": HOLES}}
    plain = lake_world(tmp_path, certain, "!hole U[0,8] goal", slippery=slippery)
    reference = check(plain, translate(parse(plain.spec))).pmax_horizon
    assert reference == (1.0 if not slippery else pytest.approx(reference))
    assert mine == pytest.approx(0.9 * reference, abs=1e-12)
    assert 0.0 < mine < 0.9 or not slippery


def test_an_event_label_with_a_probability(tmp_path: Path) -> None:
    """CliffWalking: a step into the cliff sends the agent back to the start; ``cliff`` reads
    that step's reward and is perceived w.p. 0.4. Stepping right from the start falls at every
    step, so ``F[0,3] cliff`` (positions 1 to 3 drawn) has optimum 1 - 0.6^3 = 0.784."""
    data = {
        "name": "cliff",
        "env": {"id": "CliffWalking-v1"},
        "labels": {"cliff": {"reward": {"below": -50}, "probability": 0.4}},
        "spec": {"formula": "F[0,3] cliff"},
        "horizon": 5,
    }
    world = load_world(write(tmp_path, data))
    mine, storm = storm_pmax_horizon(world, tmp_path)
    assert mine == pytest.approx(1 - 0.6**3, abs=1e-12)
    assert storm == pytest.approx(mine, abs=1e-9)


def test_the_check_command_reads_the_file(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from mitlc.cli import app

    data = {
        "name": "lake",
        "env": LAKE,
        "labels": {"a": {"obs": [1], "probability": 0.5}},
        "spec": {"formula": "F[0,3] a"},
        "horizon": 5,
    }
    result = CliRunner().invoke(app, ["check", str(write(tmp_path, data)), "--json"])
    assert result.exit_code == 0, result.output
    assert '"pmax_horizon": 0.875' in result.stdout  # three draws: 1 - 1/8


# --- the wrapper against the exact evaluation ----------------------------------------------------

POLICY = [LEFT, UP, UP, UP, LEFT, LEFT, LEFT, LEFT, UP, DOWN, LEFT, LEFT, LEFT, RIGHT, DOWN, LEFT]
"""A policy of the slippery 4x4 lake by cell (the one that reaches the goal most often)."""
MIXED = {
    "a": {"obs": [4, 8, 9], "probability": 0.6},
    "goal": {"obs": [15], "probability": 0.8},
    "hole": {"obs": HOLES},
}
MIXED_TASK = "F[0,10] a & (!hole U[0,19] goal)"


def test_the_wrappers_success_is_the_exact_evaluations(tmp_path: Path) -> None:
    """The fixed policy above on the slippery lake with two labels drawn (``a`` on frozen
    cells, revisited; the goal, once): its exact success on the finite world
    (:func:`policy_success`) and its success in 4,000 episodes of the wrapper agree within
    four standard errors."""
    world = lake_world(tmp_path, MIXED, MIXED_TASK, slippery=True)
    product = build_product(world, translate(parse(world.spec)))
    live = product.world_state >= 0
    cell = np.array([r * 4 + c for r, c in world.cells])
    ranks = np.array(POLICY)[cell[np.maximum(product.world_state, 0)]]
    choices = np.where(live, product.choice_ptr[:-1] + ranks, -1)[None, :]
    exact = policy_success(product, choices, world.horizon)
    assert 0.1 < exact < 0.9
    wrapper = TaskWrapper(lake(slippery=True), MIXED_TASK, MIXED, horizon=world.horizon)
    episodes, wins = 4000, 0
    for seed in range(episodes):
        obs, info = wrapper.reset(seed=seed)
        done = False
        while not done:
            obs, _, terminated, truncated, info = wrapper.step(POLICY[int(obs["env"])])
            done = terminated or truncated
        wins += bool(info["success"])
    sigma = (exact * (1 - exact) / episodes) ** 0.5
    assert abs(wins / episodes - exact) < 4 * sigma, (wins / episodes, exact)


# --- errors and the schema -----------------------------------------------------------------------

BAD = [
    ({"obs": [15], "probability": 0}, r"labels\.goal\.probability: expected a probability in"),
    ({"obs": [15], "probability": 1.5}, r"labels\.goal\.probability: expected a probability in"),
    ({"obs": [15], "probability": "x"}, r"labels\.goal\.probability: expected a probability in"),
    ([{"obs": [14]}, {"obs": [15], "probability": -1}], r"labels\.goal\[1\]\.probability: exp"),
]


@pytest.mark.parametrize(("label", "expected"), BAD)
def test_a_bad_probability_names_its_field(label: Any, expected: str, tmp_path: Path) -> None:
    """In a world file (with its line) and in the wrapper's declarations alike."""
    data = {"name": "lake", "env": LAKE, "labels": {"goal": label}}
    path = write(tmp_path, {**data, "spec": {"formula": "F goal"}, "horizon": 5})
    with pytest.raises(WorldError) as info:
        load_world(path)
    assert re.search(r":\d+:\d+: " + expected, info.value.render()), info.value.render()
    with pytest.raises(LabelDeclarationError, match=expected):
        TaskWrapper(lake(), "F goal", {"goal": label}, horizon=5)


def test_a_labelling_function_takes_no_probability() -> None:
    def goal(obs: Any, info: Any) -> set[str]:
        return {"goal"} if obs == 15 else set()

    with pytest.raises(LabelDeclarationError, match=r"labels\.goal\.probability: a labelling fu"):
        TaskWrapper(lake(), "F goal", {"goal": {"function": goal, "probability": 0.5}}, horizon=5)
    with pytest.raises(LabelDeclarationError, match=r"labels\.goal: expected a form, not a lab"):
        TaskWrapper(lake(), "F goal", {"goal": goal}, horizon=5)


def test_the_json_schema_takes_the_probability() -> None:
    from mitlc.worlds import world_json_schema
    from tests.test_worlds import schema_errors

    schema = world_json_schema("env-world")
    base = {"name": "lake", "env": LAKE, "spec": {"formula": "F goal"}, "horizon": 5}
    good = [
        {"obs": [15], "probability": 0.9},
        {
            "decoded": {"radices": [4, 4], "fields": ["r", "c"], "where": {"r": [3]}},
            "probability": 1,
        },
        {"box": {"index": [0], "low": [0], "high": [1]}, "probability": 0.5},
    ]
    for label in good:
        assert schema_errors({**base, "labels": {"goal": label}}, schema, schema) == [], label
    for label in ({"obs": [15], "probability": 0}, {"obs": [15], "probability": 1.5}):
        assert schema_errors({**base, "labels": {"goal": label}}, schema, schema) != [], label


def test_the_team_wrapper_draws_reproducibly() -> None:
    """The PettingZoo team wrapper reads through the same :class:`LetterTaker`: with labels
    drawn (MPE's generator, seeded by ``reset(seed=...)``), PettingZoo's seed test passes."""
    simple_spread = pytest.importorskip("mpe2.simple_spread_v3")
    from pettingzoo.test import parallel_seed_test

    from mitlc.pettingzoo import TeamTaskWrapper

    near = {"disc": {"index": [2, 3], "center": [0.0, 0.0], "radius": 0.5}, "probability": 0.5}
    right = {"box": {"index": [2], "low": [0.0], "high": [1.0]}, "probability": 0.7}

    def make() -> TeamTaskWrapper:
        env = simple_spread.parallel_env(N=2, max_cycles=25)
        return TeamTaskWrapper(
            env,
            {"agent_0": "G (right -> F near)"},
            team="F[0,20] (near_agent_0 | near_agent_1)",
            labels={"near": near, "right": right},
            horizon=30,
        )

    parallel_seed_test(make, num_cycles=40)
