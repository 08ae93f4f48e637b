"""The exact checker against Storm on random small MDPs and random specs."""

from __future__ import annotations

import random
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from mitlc.automata import translate
from mitlc.check import check
from mitlc.check.drn import storm_label, storm_property, to_drn
from mitlc.check.solve import pmax, pmax_horizon
from mitlc.product.explicit import SATISFIED, VIOLATED, build_product
from mitlc.syntax import ast, atoms, parse, to_text
from mitlc.worlds.model import Sparse, World
from tests.strategies import random_formula

stormpy = pytest.importorskip("stormpy")


def random_world(rng: random.Random, spec: str) -> World:
    """A random MDP: 3-7 states, 2-3 actions, 1-3 successors a row, random labels."""
    n, num_actions = rng.randint(3, 7), rng.randint(2, 3)
    props = atoms(parse(spec))
    indptr, targets, probs = [0], [], []
    for _ in range(n * num_actions):
        succ = sorted(rng.sample(range(n), rng.randint(1, min(3, n))))
        weights = [rng.randint(1, 4) for _ in succ]
        targets += succ
        probs += [w / sum(weights) for w in weights]
        indptr.append(len(targets))
    letters = np.array([rng.randrange(1 << len(props)) for _ in range(n)], dtype=np.int64)
    return World(
        name="random",
        rows=1,
        cols=n,
        cells=tuple((0, c) for c in range(n)),
        actions=tuple(f"a{i}" for i in range(num_actions)),
        start=0,
        transitions=Sparse(np.array(indptr), np.array(targets), np.array(probs)),
        propositions=props,
        letters=letters,
        spec=spec,
        spec_source="<inline>",
        horizon=8,
        discount=0.99,
    )


def storm_value(drn: str, prop: str, tmp: Path) -> float:
    path = tmp / "product.drn"
    path.write_text(drn, encoding="utf-8")
    model = stormpy.build_model_from_drn(str(path))
    result = stormpy.model_checking(model, stormpy.parse_properties(prop)[0])
    return float(result.get_value_vector()[model.initial_states[0]])


def formulas(seed: int, count: int) -> list[ast.Formula]:
    rng = random.Random(seed)
    out = [
        parse("(!a U[2,4] a) & (!b U[4,6] b)"),
        parse("G F a"),
        parse("F G a"),
        parse("G (a -> F b) & F G !b"),
        parse("G F a | F G b"),
    ]
    while len(out) < count:
        f = random_formula(
            rng, rng.randint(1, 4), ["a", "b"], bounded=rng.random() < 0.3, max_bound=3
        )
        if atoms(f):
            out.append(f)
    return out


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_pmax_agrees_with_storm(seed: int, tmp_path: Path) -> None:
    rng = random.Random(100 + seed)
    checked = 0
    for formula in formulas(seed, 20):
        automaton = translate(formula)
        world = random_world(rng, to_text(formula))
        product = build_product(world, automaton)
        mine = float(pmax(product).values[product.initial])
        theirs = storm_value(to_drn(product), storm_property(product), tmp_path)
        assert abs(mine - theirs) < 1e-6, (to_text(formula), mine, theirs)
        checked += 1
    assert checked == 20


@pytest.mark.parametrize("seed", [4, 5])
def test_pmax_horizon_agrees_with_storm(seed: int, tmp_path: Path) -> None:
    """Without jumps, success within H is being in a state whose end value holds (the
    satisfied one among them) at step H (0 sets), or satisfied within H (co-safety)."""
    rng = random.Random(200 + seed)
    compared = 0
    for formula in formulas(seed, 40):
        automaton = translate(formula)
        if automaton.epsilon or automaton.num_sets > 1:
            continue
        world = random_world(rng, to_text(formula))
        product = build_product(world, automaton)
        horizon = rng.randint(0, 8)
        mine, _ = pmax_horizon(product, horizon)
        if automaton.num_sets == 0:
            end = storm_label(product, "end")
            theirs = storm_value(
                to_drn(product), f"Pmax=? [F[{horizon},{horizon}] {end}]", tmp_path
            )
        elif all(m == 0 or x == SATISFIED for x, m in _state_marks(product)):
            good = storm_label(product, "satisfied")
            theirs = storm_value(to_drn(product), f"Pmax=? [F<={horizon} {good}]", tmp_path)
        else:
            continue
        assert abs(mine - theirs) < 1e-9, (to_text(formula), horizon, mine, theirs)
        compared += 1
    assert compared >= 15


def _state_marks(product: object) -> list[tuple[int, int]]:
    p = product
    return [
        (x, int(np.bitwise_or.reduce(p.marks[p.choice_ptr[x] : p.choice_ptr[x + 1]])))  # type: ignore[attr-defined]
        for x in range(p.num_states)  # type: ignore[attr-defined]
    ]


def test_absorbing_states_and_policy_follow_the_world() -> None:
    world = random_world(random.Random(9), "F[0,2] a")
    product = build_product(world, translate(parse("F[0,2] a")))
    assert product.world_state[VIOLATED] == -1 and product.world_state[SATISFIED] == -1
    solution = pmax(product)
    assert solution.values.min() >= 0.0 and solution.values.max() <= 1.0 + 1e-12
    assert solution.values[SATISFIED] == 1.0 and solution.values[VIOLATED] == 0.0


PAPER_WORLDS = ["case1", "case1-cost", "case2", "case3-office"]


@pytest.mark.parametrize("name", PAPER_WORLDS)
def test_paper_worlds_agree_with_storm(name: str, tmp_path: Path) -> None:
    from mitlc.check import check
    from mitlc.worlds import load_world
    from tests.conftest import ROOT

    world = load_world(ROOT / "specs" / "paper" / f"{name}.yaml")
    automaton = translate(parse(world.spec))
    report = check(world, automaton)
    drn = to_drn(report.product)
    theirs = storm_value(drn, storm_property(report.product), tmp_path)
    assert abs(report.pmax - theirs) < 1e-6, (name, report.pmax, theirs)
    h = world.horizon
    if automaton.num_sets == 0:
        bad = storm_label(report.product, "violated")
        within = 1 - storm_value(drn, f"Pmin=? [F<={h} {bad}]", tmp_path)
    else:
        within = storm_value(drn, f'Pmax=? [F<={h} "satisfied"]', tmp_path)
    assert abs(report.pmax_horizon - within) < 1e-9, (name, report.pmax_horizon, within)
    assert 0.9 < report.pmax <= 1.0


def test_check_command(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from mitlc.cli import app
    from tests.conftest import ROOT

    world = str(ROOT / "specs" / "paper" / "case1.yaml")
    runner = CliRunner()
    drn, policy = tmp_path / "p.drn", tmp_path / "policy.json"
    result = runner.invoke(
        app, ["check", world, "--json", "--export-drn", str(drn), "--policy", str(policy)]
    )
    assert result.exit_code == 0, result.output
    import json

    report = json.loads(result.output)
    assert {"product_states", "product_transitions", "pmax", "pmax_horizon", "seconds"} <= set(
        report
    )
    assert drn.read_text(encoding="utf-8").startswith("// mitlc product")
    rows = json.loads(policy.read_text(encoding="utf-8"))
    assert len(rows) == report["product_states"] - 2
    other = runner.invoke(
        app, ["check", world, "--spec", str(ROOT / "specs/paper/case1-literal.mitl")]
    )
    assert other.exit_code == 0 and "pmax" in other.output
    missing = runner.invoke(app, ["check", str(tmp_path / "nope.yaml")])
    assert missing.exit_code == 1 and "Traceback" not in missing.output


def test_export_dot_of_a_small_product(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from typer.testing import CliRunner

    import mitlc.check.drn as drn
    from mitlc.cli import app
    from tests.conftest import ROOT

    world = str(ROOT / "specs" / "paper" / "case1.yaml")
    out = tmp_path / "product.dot"
    result = CliRunner().invoke(app, ["check", world, "--export-dot", str(out)])
    assert result.exit_code == 0, result.output
    text = out.read_text(encoding="utf-8")
    assert text.startswith("digraph product") and '[label="(4,4) q0", penwidth=2]' in text
    monkeypatch.setattr(drn, "DOT_LIMIT", 10)
    refused = CliRunner().invoke(app, ["check", world, "--export-dot", str(out)])
    assert refused.exit_code == 1 and "too many to draw" in refused.output


def test_pmax_horizon_without_history_gives_the_same_value() -> None:
    rng = random.Random(77)
    for formula in formulas(7, 10):
        world = random_world(rng, to_text(formula))
        product = build_product(world, translate(formula))
        full, history = pmax_horizon(product, 6)
        last, kept = pmax_horizon(product, 6, keep_history=False)
        assert full == last and len(history) == 7 and len(kept) == 1
        assert np.array_equal(history[-1], kept[0])


TWO_LABELS = """
name: two-labels
grid: {rows: 1, cols: 3}
labels: {a: [[0, 0]], b: [[0, 2]]}
start: [0, 0]
actions: [left, right, stay]
motion: {intended: 0.8, sideways: 0.1}
spec: {formula: "F a & F b"}
reward: {satisfied: 1, accept: 1, violated: 0, move: 0}
horizon: 10
discount: 0.9
"""


def test_check_maps_the_worlds_propositions_by_name(tmp_path: Path) -> None:
    """The world labels (a, b) and starts on a; the task G !b names b only. Read as the
    automaton's letters without the names, the start's {a} was {b}: 0.0 instead of 1.0."""
    from mitlc.check import check
    from mitlc.product.explicit import LabelError
    from mitlc.worlds import load_world

    path = tmp_path / "two.yaml"
    path.write_text(TWO_LABELS)
    world = load_world(path)
    assert world.propositions == ("a", "b")
    report = check(world, translate(parse("G !b")))
    assert report.pmax == pytest.approx(1.0) and report.pmax_horizon == pytest.approx(1.0)
    assert check(world, translate(parse("G !a"))).pmax == 0.0  # the start is labelled a
    assert check(world, translate(parse("!a U b"))).pmax == 0.0
    with pytest.raises(LabelError, match=r"\['c'\] are not among the world's \['a', 'b'\]"):
        check(world, translate(parse("F c")))


def test_a_drawn_start_is_checked_from_its_distribution(tmp_path: Path) -> None:
    """A world whose start is drawn: `check` reports the average over the start states, and
    Storm, given every start state as an initial state of the DRN export, agrees state by
    state."""
    rng = random.Random(7)
    for formula in formulas(7, 8):
        world = random_world(rng, to_text(formula))
        weights = [rng.randint(1, 5) for _ in range(world.num_states)]
        dist = tuple((s, w / sum(weights)) for s, w in enumerate(weights))
        drawn = replace(world, start_distribution=dist, start=weights.index(max(weights)))
        automaton = translate(formula)
        report = check(drawn, automaton)
        alone = [check(replace(world, start=s), automaton).pmax for s, _ in dist]
        assert report.pmax == pytest.approx(
            sum(p * v for (_, p), v in zip(dist, alone, strict=True))
        )
        path = tmp_path / "product.drn"
        path.write_text(to_drn(report.product), encoding="utf-8")
        model = stormpy.build_model_from_drn(str(path))
        prop = stormpy.parse_properties(storm_property(report.product))[0]
        values = stormpy.model_checking(model, prop).get_value_vector()
        assert len(model.initial_states) == len(report.product.initial_distribution)
        storm = {int(s): values[int(s)] for s in model.initial_states}
        assert sorted(storm.values()) == pytest.approx(
            sorted(float(report.solution.values[x]) for x, _ in report.product.initial_distribution)
        )
