"""The episode's reading of a task (docs/episodes.md) against the reference, exhaustively.

:func:`mitlc.semantics.episode_success` reads the formula on the trace alone (LTLf with
windows, the top-level recurrences as rounds). Every path that judges an episode reads the
automaton instead, through :func:`mitlc.task.rules.success`; here the task monitor (with the
best epsilon jumps), the gymnasium wrapper, the vectorised simulator, the exact evaluation of a
policy and the checker's ``pmax_horizon`` are each compared with the reference on **every**
trace up to length 5 over two propositions, for random formulas of five families (bounded;
unbounded; requests ``G (a -> F b)``; top-level ``G F β`` conjuncts mixed with deadlines; eventual
recurrences ``G F (a & F b)`` beside weak ones and requests), and
the issue-42 reproductions are regression tests. The slow suite does the same with more
formulas.
"""

from __future__ import annotations

import itertools
import random
from collections.abc import Iterator, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces

from mitlc.automata import DigitalAutomaton, translate
from mitlc.check.solve import pmax_horizon
from mitlc.gym import TaskWrapper
from mitlc.learn.envs.vec import VecProduct, tables
from mitlc.learn.evaluation.exact import policy_success
from mitlc.product import build_product
from mitlc.product.explicit import Product
from mitlc.semantics import Letter, episode_success
from mitlc.syntax import ast, parse, to_text
from mitlc.task import TaskMonitor
from mitlc.task.monitor import MonitorState
from mitlc.worlds.gym_world import EnvWorldFile, build_world
from mitlc.worlds.model import Rewards, World
from tests.strategies import random_formula

ATOMS = ("a", "b")
LETTERS: tuple[Letter, ...] = tuple(
    frozenset(p for i, p in enumerate(ATOMS) if m >> i & 1) for m in range(1 << len(ATOMS))
)
LONGEST = 5

ISSUE_CASES = [  # (formula, trace, success): the reproductions of issue 42
    ("G F a", ["b"], False),
    ("G F a", ["b", "a"], True),
    ("G F a", ["a", "b"], True),
    ("G F (a | b)", ["", ""], False),
    ("G F a & G F b", ["a", "a"], False),
    ("G F a & G F b", ["a", "b", ""], True),
    ("G F a & G !b", ["a", "b"], False),
    ("G F a & G !b", ["", "a", ""], True),
    ("G (b -> F a) & G F a", ["a", "b"], False),
    ("G (b -> F a) & G F a", ["b", "a", ""], True),
    ("G F a & F[0,3] b", ["a"], False),
    ("G F a & F[0,3] b", ["a", "", "b"], True),
    ("F G a & F[0,3] b", ["a", "a"], False),
    ("F G a & F[0,3] b", ["a", "a,b", "a"], True),
    ("F G a & F[0,3] b", ["b", "", "a"], True),
    ("(G[2,5] !b) U[0,3] (G[0,3] b)", ["a", "a,b"], True),
    ("G[1,1] a", [""], True),
    ("G[1,1] a", ["", ""], False),
    ("X a", ["a"], False),
    ("!X a", ["a"], True),
    ("F[2,4] true", ["", ""], False),
    ("F[2,4] true", ["", "", ""], True),
    ("G (a -> F b)", ["a", "b", "a"], False),
    ("G (a -> F b)", ["a", "b", ""], True),
    ("G F (a & F b)", ["a", "b", ""], True),  # a round: a, then b (issue 44)
    ("G F (a & F b)", ["b", "a", ""], False),
    ("G F (a & F b)", ["a,b"], True),
    ("G F (a & F b) & G !(a & b)", ["a", "", "b", "a"], True),
    ("G F (a & X b)", ["a", "a", "a"], False),
    ("G F (a & X b)", ["a", "b", "a"], True),
    ("G F (a & G[0,1] b)", ["a,b", "b", ""], False),  # a weak window: read as LTLf
    ("G F (a & G[0,1] b)", ["", "a,b"], True),
]


def _trace(letters: Sequence[str]) -> list[Letter]:
    return [frozenset(p for p in text.split(",") if p) for text in letters]


# -- the monitor, exhaustively ---------------------------------------------------------------------


def _monitor_successes(
    monitor: TaskMonitor, longest: int
) -> Iterator[tuple[tuple[int, ...], bool]]:
    """Every word of letter indices of length 1..``longest`` with the monitor's success of an
    episode that read it and stopped, taking the best epsilon jumps (none at the end)."""

    def best(state: MonitorState, word: tuple[int, ...], rest: tuple[int, ...]) -> bool:
        if not rest:
            return monitor.success(state)
        outcome = monitor.step(state, monitor.letter(LETTERS[rest[0]]))
        found = outcome.success if outcome.terminated else best(outcome.state, word, rest[1:])
        for index in range(len(monitor.jumps(state.q))):
            jumped = monitor.jump(state, index)
            assert jumped is not None
            found = found or (
                jumped.success if jumped.terminated else best(jumped.state, word, rest)
            )
        return found

    for n in range(1, longest + 1):
        for word in itertools.product(range(len(LETTERS)), repeat=n):
            yield word, best(monitor.reset(), word, word)


def _disagreements(formula: ast.Formula, automaton: DigitalAutomaton) -> list[str]:
    monitor = TaskMonitor(automaton, Rewards())
    found = []
    for word, success in _monitor_successes(monitor, LONGEST):
        expected = episode_success(formula, [LETTERS[i] for i in word])
        if success != expected:
            found.append(f"{to_text(formula)} on {[sorted(LETTERS[i]) for i in word]}: {success}")
    return found


def _family(rng: random.Random, family: str) -> ast.Formula:
    """A random formula of one of the families the reading is checked on."""
    if family == "bounded":
        return random_formula(rng, rng.randint(1, 4), ATOMS, True, 3)
    if family == "unbounded":
        return random_formula(rng, rng.randint(1, 3), ATOMS, False, 2)
    deadline = to_text(random_formula(rng, rng.randint(1, 3), ATOMS, True, 3))
    a, b = rng.sample(ATOMS, 2)
    if family == "requests":
        parts = [f"G ({a} -> F {b})", f"G ({a} -> F[0,2] {b})", deadline]
    else:
        parts = [f"G F {a}", f"G F ({a} & !{b})", f"G F {b}", deadline, f"G !({a} & {b})"]
    if family == "eventual":
        parts = [f"G F ({a} & F {b})", f"G F ({a} U {b})", f"G F ({a} & X {b})",
                 f"G (F ({a} & F[1,2] {b}) | F !{a})", f"G F ({a} & G[0,1] {b})",
                 f"G ({a} -> F {b})", deadline, f"G F {b}"]  # fmt: skip
    chosen = rng.sample(parts, rng.randint(1, len(parts)))
    if family == "recurrences" and not any(p.startswith("G F") for p in chosen):
        chosen.append(f"G F {a}")
    if family == "eventual" and not any(p.startswith("G F (") for p in chosen):
        chosen.append(f"G F ({a} & F {b})")
    return parse(" & ".join(f"({p})" for p in chosen))


def _formulas(seed: int, count: int) -> Iterator[tuple[ast.Formula, DigitalAutomaton]]:
    """``count`` formulas of each family, over both propositions; an unbounded formula whose
    automaton needs epsilon jumps is left to the persistence cases (docs/episodes.md: after a
    jump the episode reads the guess)."""
    rng = random.Random(seed)
    for family in ("bounded", "unbounded", "requests", "recurrences", "eventual"):
        made = 0
        while made < count:
            formula = _family(rng, family)
            if ast.atoms(formula) != ATOMS:
                continue
            automaton = translate(formula)
            if automaton.epsilon and family not in ("recurrences", "eventual"):
                continue
            made += 1
            yield formula, automaton


PERSISTENCE = [
    "F G a",
    "F G a & F[0,3] b",
    "G F a | F G b",
    "F G (a | b) & G !(a & b)",
    "F G a | F[0,2] (b & X b)",
    "(a U b) & F G !a",
]


@pytest.mark.parametrize("text", [case[0] for case in ISSUE_CASES[:1]] + PERSISTENCE)
def test_the_monitor_reads_persistence_as_the_reference_does(text: str) -> None:
    formula = parse(text)
    assert _disagreements(formula, translate(formula)) == []


@pytest.mark.parametrize(("text", "letters", "expected"), ISSUE_CASES)
def test_the_issue_reproductions(text: str, letters: list[str], expected: bool) -> None:
    formula, trace = parse(text), _trace(letters)
    assert episode_success(formula, trace) == expected
    monitor = TaskMonitor(translate(formula), Rewards())
    word = tuple(LETTERS.index(letter) for letter in trace)
    found = dict(_monitor_successes(monitor, len(word)))
    assert found[word] == expected


def test_the_monitor_agrees_with_the_reference_on_every_short_trace() -> None:
    failures = [
        f for formula, automaton in _formulas(42, 6) for f in _disagreements(formula, automaton)
    ]
    assert failures[:5] == []


@pytest.mark.slow
def test_the_monitor_agrees_with_the_reference_on_many_formulas() -> None:
    failures = [
        f for formula, automaton in _formulas(7, 60) for f in _disagreements(formula, automaton)
    ]
    assert failures[:5] == []


# -- the checker, the exact evaluation and the wrapper ---------------------------------------------


class Chooser(gym.Env[int, int]):
    """An env whose action is the next letter: a deterministic policy is a trace."""

    def __init__(self) -> None:
        size = len(LETTERS)
        self.observation_space = spaces.Discrete(size)
        self.action_space = spaces.Discrete(size)
        self.P = {s: {a: [(1.0, a, 0.0, False)] for a in range(size)} for s in range(size)}
        self.initial_state_distrib = np.eye(size)[0]
        self.state = 0

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[int, dict[str, Any]]:
        super().reset(seed=seed)
        self.state = 0
        return 0, {}

    def step(self, action: int) -> tuple[int, float, bool, bool, dict[str, Any]]:
        self.state = int(action)
        return self.state, 0.0, False, False, {}


LABELS = {p: {"obs": [i for i, letter in enumerate(LETTERS) if p in letter]} for p in ATOMS}


def _world(formula: ast.Formula, horizon: int) -> World:
    file = EnvWorldFile.model_validate(
        {
            "env": {"id": "Chooser-v0"},
            "labels": LABELS,
            "spec": {"formula": to_text(formula)},
            "horizon": horizon,
        }
    )
    return build_world(
        file,
        Chooser(),
        name="chooser",
        spec=to_text(formula),
        spec_source="<test>",
        propositions=ATOMS,
    )


def _simulated(world: World, product: Product, word: tuple[int, ...]) -> bool:
    """The vectorised simulator's success of the episode that plays ``word``."""
    sim = VecProduct(tables(product, world), 1, np.random.default_rng(0))
    for action in (*word[1:], 0):
        step = sim.step(np.array([action]))
        if step.terminated[0] or step.truncated[0]:
            return bool(step.success[0])
    raise AssertionError("the episode did not end at its horizon")


def _trace_policy(product: Product, word: tuple[int, ...]) -> np.ndarray:
    """The time-dependent choices that play ``word`` after its first letter (the start)."""
    horizon = len(word)
    masks = 1 << product.num_sets
    live = product.world_state >= 0
    choices = np.full((horizon, 2, masks, product.num_states), -1, dtype=np.int64)
    for r in range(1, horizon + 1):  # r steps left: the letter at position horizon - r + 1
        action = word[horizon - r + 1] if r > 1 else 0
        choices[r - 1][:, :, live] = product.choice_ptr[:-1][live] + action
    return choices


@pytest.mark.parametrize("seed", range(3))
def test_pmax_horizon_the_exact_evaluation_the_simulator_and_the_wrapper_agree(
    seed: int,
) -> None:
    rng = random.Random(seed)
    for formula, automaton in itertools.islice(_formulas(100 + seed, 2), 8):
        for horizon in range(1, 5):
            world = _world(formula, horizon)
            product = build_product(world, automaton)
            words = [
                (0, *rest) for rest in itertools.product(range(len(LETTERS)), repeat=horizon - 1)
            ]
            successes = {w: episode_success(formula, [LETTERS[i] for i in w]) for w in words}
            best, _ = pmax_horizon(product, horizon)
            assert best == float(any(successes.values())), (to_text(formula), horizon)
            if automaton.epsilon:
                continue
            for word in rng.sample(words, min(4, len(words))):
                exact = policy_success(product, _trace_policy(product, word), horizon)
                assert exact == float(successes[word]), (to_text(formula), word)
                env = TaskWrapper(Chooser(), automaton, LABELS, horizon=horizon)
                env.reset(seed=0)
                info: dict[str, Any] = {}
                for action in (*word[1:], 0):
                    _, _, terminated, truncated, info = env.step(action)
                    if terminated or truncated:
                        break
                assert info["success"] == successes[word], (to_text(formula), word)
                assert _simulated(world, product, word) == successes[word], to_text(formula)


# -- mitlc check on the issue's worlds -------------------------------------------------------------

LINE = """name: line
grid: {rows: 1, cols: 3}
blocked: BLOCKED
labels: {a: [[0, 2]], b: [[0, 0]]}
start: [0, 0]
actions: [left, right, stay]
motion: {intended: 1.0, sideways: 0.0}
spec: {formula: "G F a"}
reward: {satisfied: 1, accept: 1, violated: 0, move: 0}
horizon: HORIZON
"""


def _pmax_horizon(tmp_path: Any, formula: str, horizon: int, blocked: bool) -> float:
    from typer.testing import CliRunner

    from mitlc.cli import app

    world = tmp_path / f"line-{horizon}-{blocked}.yaml"
    text = LINE.replace("HORIZON", str(horizon)).replace("BLOCKED", "[[0, 1]]" if blocked else "[]")
    world.write_text(text)
    result = CliRunner().invoke(app, ["check", str(world), "-e", formula])
    assert result.exit_code == 0, result.output
    (line,) = [x for x in result.output.splitlines() if x.startswith("pmax_horizon")]
    return float(line.split()[1])


@pytest.mark.parametrize("horizon", [1, 2, 3, 4, 6, 10])
def test_check_gives_the_reading_on_the_issue_worlds(tmp_path: Any, horizon: int) -> None:
    """``a`` unreachable: ``G F a`` never succeeds, nor ``F G b & F[0,3] a`` at any horizon
    (it once gave 1.0 at horizons 1-3); reachable in two moves (read at the third letter)."""
    assert _pmax_horizon(tmp_path, "G F a", horizon, blocked=True) == 0.0
    assert _pmax_horizon(tmp_path, "F G b & F[0,3] a", horizon, blocked=True) == 0.0
    reachable = float(horizon >= 3)
    assert _pmax_horizon(tmp_path, "G F a", horizon, blocked=False) == reachable
    assert _pmax_horizon(tmp_path, "G F a & G F b", horizon, blocked=False) == reachable
    assert _pmax_horizon(tmp_path, "G F a & F[0,3] b", horizon, blocked=False) == reachable


def test_rounds_are_reported_beside_success(tmp_path: Any) -> None:
    """A patrol between ``a`` and ``b`` (two moves apart), 12 steps: a learned policy completes
    rounds, which ``metrics.jsonl`` and ``eval --json`` report beside the success rate."""
    import json

    from typer.testing import CliRunner

    from mitlc.cli import app

    world = tmp_path / "patrol.yaml"
    world.write_text(LINE.replace("HORIZON", "12").replace("BLOCKED", "[]"))
    run = tmp_path / "run"
    runner = CliRunner()
    train = ["train", str(world), "-e", "G F a & G F b", "--algo", "q", "--out", str(run)]
    result = runner.invoke(app, [*train, "--set", "q.episodes=3000"])
    assert result.exit_code == 0, result.output
    rows = [json.loads(x) for x in (run / "metrics.jsonl").read_text().splitlines()]
    assert rows and all("rounds" in row for row in rows)
    assert rows[-1]["rounds"] > 0
    result = runner.invoke(app, ["eval", str(run), "--json", "--episodes", "200"])
    assert result.exit_code == 0, result.output
    summary = json.loads(result.output[result.output.index("{") :])
    assert summary["success_rate"] == 1.0 and summary["mean_rounds"] >= 2.0
