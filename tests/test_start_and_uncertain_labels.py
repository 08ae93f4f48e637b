"""Drawn starts and uncertain labels in grid world files (:mod:`mitlc.worlds.uncertain`).

``check`` against Storm on random small worlds that use both, against hand computations on two
tiny lines, the simulator's Monte-Carlo success against the exact evaluation of a fixed policy,
and the errors of bad starts, weights and probabilities with their field paths and lines.
"""

from __future__ import annotations

import json
import random
import re
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from mitlc.automata import translate
from mitlc.check import check
from mitlc.check.drn import storm_label, storm_property, to_drn
from mitlc.learn.envs.vec import VecProduct, tables
from mitlc.learn.evaluation.exact import policy_success
from mitlc.product.explicit import SATISFIED, VIOLATED, build_product
from mitlc.syntax import parse, to_text
from mitlc.worlds import WorldError, load_world
from tests.conftest import ROOT
from tests.test_check import _state_marks
from tests.test_check_grids import padded, random_spec, random_world_yaml

stormpy = pytest.importorskip("stormpy")

LINE3 = """\
grid: {rows: 1, cols: 3}
labels:
  a: {cells: [[0, 2]], probability: 0.5}
start: {cells: [[0, 0], [0, 1]], weights: [1, 3]}
motion: {intended: 1.0, sideways: 0.0}
spec: {formula: "F[0,2] a"}
horizon: 5
"""

LINE2 = """\
grid: {rows: 1, cols: 2}
labels:
  a: {cells: [[0, 1]], probability: 0.5}
start: [[0, 0], [0, 1]]
motion: {intended: 0.8, stall: 0.2}
spec: {formula: "F[0,1] a"}
horizon: 2
"""


def _write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / f"{name}.yaml"
    path.write_text(text, encoding="utf-8")
    return path


def test_line_of_three_by_hand(tmp_path: Path) -> None:
    """Certain moves; ``a`` holds at (0, 2) w.p. 1/2, drawn again at every step; the task
    reads positions 0, 1 and 2. From (0, 0) the robot is at (0, 2) at position 2 only: one draw,
    1/2. From (0, 1) it is there at positions 1 and 2: two draws, 1 - (1/2)^2 = 3/4. The starts
    weigh 1 : 3, so the optimum is 1/4 * 1/2 + 3/4 * 3/4 = 11/16."""
    world = load_world(_write(tmp_path, "line3", LINE3))
    assert world.cells == ((0, 0), (0, 1), (0, 2), (0, 2))  # (0, 2) without a, then with a
    assert world.letters.tolist() == [0, 0, 0, 1]
    assert world.start == 1 and world.start_distribution == ((0, 0.25), (1, 0.75))
    report = check(world, translate(parse(world.spec)))
    assert report.pmax == pytest.approx(float(Fraction(11, 16)), abs=1e-12)
    assert report.pmax_horizon == pytest.approx(float(Fraction(11, 16)), abs=1e-12)
    per_cell = report.start_cells(world)
    assert [c["cell"] for c in per_cell] == [[0, 0], [0, 1]]
    assert [c["probability"] for c in per_cell] == [0.25, 0.75]
    assert [c["pmax_horizon"] for c in per_cell] == pytest.approx([0.5, 0.75], abs=1e-12)


def test_line_of_two_by_hand(tmp_path: Path) -> None:
    """A move succeeds w.p. 4/5 (else the robot stays); ``a`` holds at (0, 1) w.p. 1/2 per
    step; the task reads positions 0 and 1. Start (0, 1), drawn w.p. 1/2: two draws of a, 3/4.
    Start (0, 0), w.p. 1/2: the move right arrives w.p. 4/5 and a holds there w.p. 1/2: 2/5.
    The optimum is (3/4 + 2/5) / 2 = 23/40. Every start state is the start cell with an
    outcome: (0, 0); (0, 1) without a; (0, 1) with a, w.p. 1/2, 1/4, 1/4."""
    world = load_world(_write(tmp_path, "line2", LINE2))
    assert world.start_distribution == ((0, 0.5), (1, 0.25), (2, 0.25))
    assert world.start == 0
    report = check(world, translate(parse(world.spec)))
    assert report.pmax_horizon == pytest.approx(float(Fraction(23, 40)), abs=1e-12)
    assert report.pmax == pytest.approx(float(Fraction(23, 40)), abs=1e-12)
    assert report.summary()["start_states"] == 3


def test_check_json_gives_each_start_cell(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from mitlc.cli import app

    path = _write(tmp_path, "line3", LINE3)
    result = CliRunner().invoke(app, ["check", str(path), "--json"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert data["pmax_horizon"] == pytest.approx(11 / 16)
    assert [(c["cell"], round(c["pmax_horizon"], 12)) for c in data["start_cells"]] == [
        ([0, 0], 0.5),
        ([0, 1], 0.75),
    ]


# --- random worlds against Storm ----------------------------------------------------------


def with_starts_and_noise(text: str, rng: random.Random) -> str:
    """A random world of tests.test_check_grids with a drawn start and uncertain labels."""
    data: dict[str, Any] = yaml.safe_load(text)
    rows, cols = data["grid"]["rows"], data["grid"]["cols"]
    blocked = {tuple(c) for c in data["blocked"]}
    free = [[r, c] for r in range(rows) for c in range(cols) if (r, c) not in blocked]
    form = rng.choice(["cell", "list", "weighted", "uniform"])
    chosen = rng.sample(free, rng.randint(1, min(3, len(free))))
    if form == "list":
        data["start"] = chosen
    elif form == "weighted":
        data["start"] = {"cells": chosen, "weights": [rng.randint(1, 4) for _ in chosen]}
    elif form == "uniform":
        data["start"] = "uniform"
    for p in list(data["labels"]):
        if rng.random() < 0.6:
            probability = rng.choice([0.3, 0.5, 0.9])
            data["labels"][p] = {"cells": data["labels"][p], "probability": probability}
    return yaml.safe_dump(data, sort_keys=False)


def storm_values(drn: str, prop: str, tmp: Path) -> list[float]:
    """Storm's value of ``prop`` at every state of the DRN model."""
    path = tmp / "product.drn"
    for text in (drn, padded(drn)):
        path.write_text(text, encoding="utf-8")
        model = stormpy.build_model_from_drn(str(path))
        try:
            result = stormpy.model_checking(model, stormpy.parse_properties(prop)[0])
        except RuntimeError as err:
            if "Invalid item count" not in str(err):
                raise
            continue
        return [float(v) for v in result.get_value_vector()]
    raise AssertionError("Storm failed on the padded model too")


def start_average(values: list[float], starts: tuple[tuple[int, float], ...]) -> float:
    """The DRN numbers the start states first, in the product's order."""
    return sum(p * values[i] for i, (_, p) in enumerate(starts))


@pytest.mark.parametrize("seed", [21, 22, 23])
def test_random_worlds_agree_with_storm(seed: int, tmp_path: Path) -> None:
    rng = random.Random(seed)
    compared = horizon_compared = 0
    for i in range(14):
        formula = random_spec(rng)
        text = with_starts_and_noise(random_world_yaml(rng, formula, f"noisy-{seed}-{i}"), rng)
        world = load_world(_write(tmp_path, f"world{i}", text))
        automaton = translate(formula)
        report = check(world, automaton)
        product = report.product
        starts = product.starts
        drn = to_drn(product)
        theirs = storm_values(drn, storm_property(product), tmp_path)
        case = (text, report.pmax)
        assert report.pmax == pytest.approx(start_average(theirs, starts), abs=1e-6), case
        compared += world.start_distribution != ()
        if automaton.epsilon or (
            automaton.num_sets
            and not all(m == 0 or x == SATISFIED for x, m in _state_marks(product))
        ):
            continue
        h, end = world.horizon, storm_label(product, "end")
        within = storm_values(drn, f"Pmax=? [F[{h},{h}] {end}]", tmp_path)
        assert report.pmax_horizon == pytest.approx(start_average(within, starts), abs=1e-9), case
        horizon_compared += 1
    assert compared >= 5 and horizon_compared >= 3


# --- the simulator against the exact evaluation --------------------------------------------

SMALL = """\
grid: {rows: 3, cols: 3}
blocked: [[1, 1]]
labels:
  a: {cells: [[0, 2], [2, 2]], probability: 0.6}
  b: [[2, 0]]
start: {cells: [[0, 0], [2, 1], [1, 2]], weights: [2, 1, 1]}
motion: {intended: 0.8, sideways: 0.1}
spec: {formula: "!b U[0,6] a"}
horizon: 8
"""


def test_monte_carlo_agrees_with_the_exact_evaluation(tmp_path: Path) -> None:
    """A fixed random memoryless policy: its exact success (:func:`policy_success`) and the
    success of 40,000 simulated episodes, one per env (:class:`VecProduct`, which draws the
    start and every label outcome) agree within four standard errors."""
    world = load_world(_write(tmp_path, "small", SMALL))
    product = build_product(world, translate(parse(world.spec)))
    rng = np.random.default_rng(0)
    n, a = product.num_states, world.num_actions
    ranks = rng.integers(0, a, size=n)
    live = product.world_state >= 0
    choices = np.where(live, product.choice_ptr[:-1] + ranks, -1)[None, :]
    exact = policy_success(product, choices, world.horizon)
    assert 0.05 < exact < 0.95
    episodes = 40_000
    sim = VecProduct(tables(product, world), episodes, np.random.default_rng(1))
    first = np.full(episodes, -1)  # each env's first episode only: no bias to short ones
    while (first < 0).any():
        state = sim.state
        step = sim.step(np.where(live[state], ranks[state], 0))
        ended = step.done & (first < 0)
        first[ended] = step.success[ended]
    estimate = float(first.mean())
    sigma = (exact * (1 - exact) / episodes) ** 0.5
    assert abs(estimate - exact) < 4 * sigma, (estimate, exact)
    assert product.world_state[[VIOLATED, SATISFIED]].tolist() == [-1, -1]


def test_the_wrapper_draws_starts_and_outcomes(tmp_path: Path) -> None:
    """``ProductEnv.reset`` draws the start state from the start distribution, and
    ``info["state"]`` is the state with its outcome: in LINE2, (0, 0), (0, 1) and (0, 1)
    with a, w.p. 1/2, 1/4, 1/4."""
    world = load_world(_write(tmp_path, "line2", LINE2))
    env = world.task_env(translate(parse(world.spec)))
    counts = np.zeros(world.num_states)
    for seed in range(4000):
        _, info = env.reset(seed=seed)
        counts[info["state"]] += 1
    assert counts / counts.sum() == pytest.approx([0.5, 0.25, 0.25], abs=0.03)


def test_what_the_agent_observes(tmp_path: Path) -> None:
    """MDP: the state (cell and outcome) is the observation; POMDP: the sensor's row of the
    cell, the same for each outcome, over the cells' names."""
    mdp = load_world(_write(tmp_path, "line3", LINE3))
    assert mdp.observations is None and mdp.num_states == 4
    pomdp_text = LINE3 + "observation: {type: noisy-cell, correct: 0.8}\n"
    pomdp = load_world(_write(tmp_path, "line3p", pomdp_text))
    assert pomdp.observations is not None
    assert pomdp.observations.names == ("r0c0", "r0c1", "r0c2")
    rows = [pomdp.observations.model.row(s) for s in range(4)]
    assert rows[2][0].tolist() == rows[3][0].tolist() == [1, 2]
    assert rows[2][1].tolist() == rows[3][1].tolist() == pytest.approx([0.2, 0.8])
    assert pomdp.transitions.num_rows == 4 * pomdp.num_actions


POMDP = """\
grid: {rows: 2, cols: 3}
labels:
  a: {cells: [[0, 2]], probability: 0.5}
start: START
motion: {intended: 0.8, sideways: 0.1}
observation: {type: noisy-cell, correct: 0.7}
spec: {formula: "F[0,4] a"}
horizon: 6
"""


def test_the_pomdp_bounds_start_from_the_distribution(tmp_path: Path) -> None:
    """From (0, 2) alone a staying robot draws a five times: 1 - 1/2^5 = 31/32, whatever it
    observes. From every cell, the observation-based policy's exact success lies below the
    fully observable optimum and inside Storm's belief bounds (all from the same start
    distribution)."""
    from mitlc.check.observed import observed_bound
    from mitlc.check.pomdp import pomdp_bounds

    one = load_world(_write(tmp_path, "one", POMDP.replace("START", "[0, 2]")))
    automaton = translate(parse(one.spec))
    report = check(one, automaton)
    assert report.pmax_horizon == pytest.approx(31 / 32)
    assert observed_bound(one, report.product).value == pytest.approx(31 / 32)
    world = load_world(_write(tmp_path, "every", POMDP.replace("START", "uniform")))
    report = check(world, automaton)
    observed = observed_bound(world, report.product).value
    assert 0.5 < observed < report.pmax_horizon < 1.0
    bounds = pomdp_bounds(world, automaton)
    if bounds is None:
        pytest.skip("stormpy.pomdp is not installed")
    assert bounds["lower"] - 1e-9 <= observed <= bounds["upper"] + 1e-9, bounds


def test_an_uncertain_label_nothing_reads_adds_no_state(tmp_path: Path) -> None:
    text = LINE3.replace("labels:\n", "labels:\n  b: [[0, 0]]\n").replace("F[0,2] a", "F b")
    text = text.replace("a: {cells", "c: {cells")
    world = load_world(_write(tmp_path, "plain", text))
    assert world.num_states == 3 and world.propositions == ("b",)


def test_the_shipped_random_start_example_checks() -> None:
    world = load_world(ROOT / "specs" / "paper" / "case2-random-start.yaml")
    assert world.is_pomdp and world.num_states == 90 and len(world.start_distribution) == 90
    report = check(world, translate(parse(world.spec)))
    assert report.pmax == pytest.approx(1.0)
    assert 0.99 < report.pmax_horizon <= 1.0 + 1e-9
    assert to_text(parse(world.spec)) == "G F (a & F b)"  # read as rounds: 0.0 as LTLf


# --- errors ----------------------------------------------------------------------------------

BASE = """\
grid: {rows: 2, cols: 3}
blocked: [[1, 1]]
labels:
  a: LABEL
start: START
motion: {intended: 1.0, sideways: 0.0}
spec: {formula: "F a"}
horizon: 5
"""

ERRORS = [
    ("[[0, 0], [1, 1]]", "[[0, 2]]", r":5:17: start\[1\]: cell \[1, 1\] is blocked"),
    ("[[0, 0], [4, 0]]", "[[0, 2]]", r":5:17: start\[1\]: cell \[4, 0\] is outside the 2x3 grid"),
    ("[[0, 0], [0, 0]]", "[[0, 2]]", r"start\[1\]: cell \[0, 0\] is listed twice"),
    ("{cells: [[0, 0], [0, 1]], weights: [1]}", "[[0, 2]]", r"start.weights: 1 weights for 2"),
    ("{cells: [[0, 0]], weights: [-1]}", "[[0, 2]]", r"start.weights\[0\]: expected a positive"),
    ("{cells: [[0, 0]], weights: [0]}", "[[0, 2]]", r"start.weights\[0\]: expected a positive"),
    ("{cells: [[0, 0]]}", "[[0, 2]]", r"start.weights: required field is missing"),
    ("{cells: [[0, 0]], weight: [1]}", "[[0, 2]]", r"start.weight: unknown field; did you"),
    ("{cells: [], weights: []}", "[[0, 2]]", r"start.cells: expected at least 1 item"),
    ("everywhere", "[[0, 2]]", r"start: expected 'uniform', got \"everywhere\""),
    ("5", "[[0, 2]]", r"start: expected a cell \[row, col\], a list of cells, .* got 5"),
    ("[]", "[[0, 2]]", r"start: expected at least 1 item"),
    ("[0, 0]", "{cells: [[0, 2]], probability: 1.5}", r"labels.a.probability: expected a prob"),
    ("[0, 0]", "{cells: [[0, 2]], probability: 0}", r"labels.a.probability: expected a prob"),
    ("[0, 0]", "{cells: [[1, 1]], probability: 0.5}", r"labels.a.cells\[0\]: cell \[1, 1\] is"),
    (
        "[0, 0]",
        "{cells: [[0, 2]], prob: 0.5}",
        r"labels.a.prob: unknown field \(known: cells, probability\)",
    ),
    ("[0, 0]", "{probability: 0.5}", r"labels.a.cells: required field is missing"),
    ("[0, 0]", "yes", r"labels.a: expected a list of cells or \{cells: \[...\], probability"),
]


@pytest.mark.parametrize(("start", "label", "expected"), ERRORS)
def test_bad_starts_and_labels_name_their_field(
    start: str, label: str, expected: str, tmp_path: Path
) -> None:
    path = _write(tmp_path, "bad", BASE.replace("START", start).replace("LABEL", label))
    with pytest.raises(WorldError) as info:
        load_world(path)
    assert re.search(expected, info.value.render()), info.value.render()


def test_a_good_base_loads(tmp_path: Path) -> None:
    text = BASE.replace("START", "uniform").replace("LABEL", "{cells: [[0, 2]]}")
    world = load_world(_write(tmp_path, "good", text))
    assert world.num_states == 5 and len(world.start_distribution) == 5
    assert world.start == 0  # every cell as probable: the lowest state


def test_the_json_schema_takes_every_form() -> None:
    from mitlc.worlds import world_json_schema
    from tests.test_worlds import schema_errors

    schema = world_json_schema()
    path = ROOT / "specs" / "paper" / "case2-random-start.yaml"
    data = yaml.safe_load(path.read_text(encoding="utf-8"))
    assert schema_errors(data, schema, schema) == []
    for start in ([1, 2], [[1, 2], [2, 2]], {"cells": [[1, 2]], "weights": [2]}):
        assert schema_errors({**data, "start": start}, schema, schema) == []
    labels = {"a": [[6, 3]], "b": {"cells": [[3, 8]]}}
    assert schema_errors({**data, "labels": labels}, schema, schema) == []
