"""Shaping from the task and the labels (:mod:`mitlc.task.potential`): potential-based, so the
optimal policies of the learners' discounted objective do not move (checked exactly by value
iteration on finite products), with distances from the labels' regions and positions."""

from __future__ import annotations

import random
import re
from dataclasses import replace

import numpy as np
import pytest

from mitlc.automata import translate
from mitlc.labels import compile_labels
from mitlc.labels.distance import distances
from mitlc.labels.values import Moment
from mitlc.learn.envs.vec import Tables, tables
from mitlc.learn.learners.base import product_potential
from mitlc.product.explicit import build_product
from mitlc.syntax import parse
from mitlc.task import rules
from mitlc.task.potential import task_potential, world_distances
from mitlc.worlds import load_world
from mitlc.worlds.model import Rewards
from tests.conftest import ROOT
from tests.test_check import random_world


def optimal_q(t: Tables, gamma: float, phi: np.ndarray | None) -> np.ndarray:
    """The optimal discounted action values of the product's MDP (the learners' objective:
    rewards of :mod:`mitlc.task.rules`, no bootstrap where the task is decided), with the
    shaping ``gamma * phi(x') - phi(x)`` added where ``phi`` is given; -inf for invalid."""
    assert t.num_sets <= 1, "one acceptance set at most: the frontier is then memoryless"
    num_x, width = t.choice.shape
    # the cumulative restarts at each choice: recover each transition's probability
    probs = np.empty(len(t.targets))
    for c in range(len(t.indptr) - 1):
        lo, hi = t.indptr[c], t.indptr[c + 1]
        within = t.cumulative[lo:hi] - c
        probs[lo:hi] = np.diff(np.concatenate([[0.0], within]))
    verdict = t.verdict[t.targets]
    new = (t.marks != 0).astype(np.int64) if t.num_sets else np.zeros(len(t.targets), np.int64)
    choice_of = np.repeat(np.arange(len(t.indptr) - 1), np.diff(t.indptr))
    reward = rules.reward(new, verdict, t.rewards) + t.reward_move * t.moves[choice_of]
    live = ~rules.terminated(verdict)
    source = np.full(len(t.indptr) - 1, -1)
    for x in range(num_x):
        for a in range(width):
            if t.choice[x, a] >= 0:
                source[t.choice[x, a]] = x
    if phi is not None:
        reward = reward + gamma * phi[t.targets] - phi[source[choice_of]]
    value = np.zeros(num_x)
    for _ in range(5000):
        gain = reward + gamma * np.where(live, value[t.targets], 0.0)
        per_choice = np.bincount(choice_of, probs * gain, minlength=len(t.indptr) - 1)
        q = np.where(t.choice >= 0, per_choice[np.maximum(t.choice, 0)], -np.inf)
        updated = q.max(axis=1)
        if np.max(np.abs(updated - value)) < 1e-12:
            break
        value = updated
    return q


@pytest.mark.parametrize("seed", range(6))
def test_shaping_keeps_the_optimal_policies_exactly(seed: int) -> None:
    """Ng, Harada and Russell's theorem on finite products: with the task's potential
    ``Q*_shaped(x, a) = Q*(x, a) - phi(x)`` for every valid action, so the greedy policies
    (the optimum the learners approach) are the same."""
    rng = random.Random(seed)
    spec = rng.choice(["!a U[2,6] b", "F[0,5] (a & F[0,4] b)", "(!a U[1,4] a) & F[0,8] b",
                       "G (a -> F[0,3] b)"])  # fmt: skip
    world = random_world(rng, spec)
    world = replace(world, rewards=Rewards(1.0, 1.0, 0.0, -0.01))
    automaton = translate(parse(spec))
    product = build_product(world, automaton)
    t = tables(product, world)
    phi = product_potential(t, world, automaton, 2.0)
    live = phi[t.world_state >= 0]
    assert (phi[t.world_state < 0] == 0.0).all() and (live >= 0).all() and (live > 0).any()
    plain, shaped = optimal_q(t, 0.9, None), optimal_q(t, 0.9, phi)
    valid = t.choice >= 0
    assert np.allclose((shaped + phi[:, None])[valid], plain[valid], atol=1e-8)
    live = t.world_state >= 0
    gaps = np.sort(np.where(valid, plain, -np.inf), axis=1)
    with np.errstate(invalid="ignore"):  # -inf less -inf, where one action is valid
        clear = live & (np.nan_to_num(gaps[:, -1] - gaps[:, -2]) > 1e-6)
    assert (plain.argmax(axis=1)[clear] == shaped.argmax(axis=1)[clear]).all()


def test_case1_potential_pulls_towards_the_proposition_that_advances() -> None:
    """On case 1 (a within [5,10], then b): among the product states of one automaton state
    that waits for a, the potential falls with the fewest steps to a."""
    world = load_world(ROOT / "specs" / "paper" / "case1.yaml")
    automaton = translate(parse(world.spec))
    t = tables(build_product(world, automaton), world)
    phi = product_potential(t, world, automaton, 1.0)
    a = automaton.propositions.index("a")
    advancing = task_potential(automaton).advancing
    holds = np.array(
        [
            [
                (int(world.letters[s]) >> world.propositions.index(p)) & 1
                for s in range(world.num_states)
            ]
            for p in automaton.propositions
        ]
    )
    steps = world_distances(world.transitions.indptr, world.transitions.targets,
                            world.num_actions, holds.astype(bool))[a]  # fmt: skip
    live = t.world_state >= 0
    counts = np.bincount(t.automaton_state[live], minlength=len(automaton.states))
    waiting = [q for q in np.argsort(-counts) if advancing[q, a] and counts[q] >= 10]
    assert waiting
    xs = np.flatnonzero(live & (t.automaton_state == waiting[0]))
    far = steps[t.world_state[xs]]
    assert np.corrcoef(far, phi[xs])[0, 1] < -0.99
    assert far[np.argmax(phi[xs])] == far.min()


def test_advancing_propositions_of_a_sequence() -> None:
    automaton = translate(parse("!a U[0,10] (a & F[0,10] b)"))
    potential = task_potential(automaton)
    a, b = automaton.propositions.index("a"), automaton.propositions.index("b")
    q0 = automaton.initial
    assert potential.advancing[q0, a] and not potential.advancing[q0, b]
    after_a, _ = automaton.successor(q0, 1 << a)
    assert potential.advancing[after_a, b] and not potential.advancing[after_a, a]
    # time spent raises the urgency, which lowers the potential
    waited, _ = automaton.successor(after_a, 0)
    assert potential.urgency[waited] > potential.urgency[after_a]
    later, sooner = potential.at(np.array([waited, after_a]), np.full((2, 2), np.nan), 1.0)
    assert later < sooner


def test_distances_of_regions_and_positions() -> None:
    """A box and a disc over the observation, an attribute position with ``equals`` and a
    number with ``above``: the Euclidean distance to where each holds, 0 inside."""
    from gymnasium import spaces

    class Thing:
        pos = (3, 1)
        speed = 2.0

    space = spaces.Box(-10.0, 10.0, (2,), dtype=np.float64)
    labeller = compile_labels(
        {
            "box": {"box": {"index": [0, 1], "low": [1.0, 1.0], "high": [2.0, 2.0]}},
            "disc": {"disc": {"index": [0, 1], "center": [0.0, 0.0], "radius": 1.0}},
            "at": {"attr": "pos", "equals": [0, 1]},
            "fast": {"attr": "speed", "above": 5.0},
            "odd": {"attr": "pos"},
        },
        space,
    )
    moment = Moment(Thing(), None, False)
    found = distances(labeller, ["box", "disc", "at", "fast", "odd"], np.array([4.0, 0.0]), {},
                      moment)  # fmt: skip
    assert found[0] == pytest.approx(np.hypot(2.0, 1.0))
    assert found[1] == pytest.approx(3.0)
    assert found[2] == pytest.approx(3.0)
    assert found[3] == pytest.approx(3.0)
    assert found[4] is None
    inside = distances(labeller, ["box", "disc"], np.array([1.5, 1.5]), {}, moment)
    assert inside[0] == 0.0 and inside[1] == pytest.approx(np.hypot(1.5, 1.5) - 1.0)


class Grid:
    """A MiniGrid-like env: objects in a flat list, the agent's position."""

    def __init__(self) -> None:
        wall = type("Wall", (), {"type": "wall", "cur_pos": (0, 0)})()
        key = type("Key", (), {"type": "key", "cur_pos": (4, 1)})()
        self.grid = type("G", (), {"grid": [None, wall, key]})()
        self.agent_pos = (1, 1)
        self.carrying = None


def test_a_guide_measures_from_the_agent_to_an_object_found_on_the_grid() -> None:
    """``toward`` with a selection ``grid.grid[type=key]``: the distance from the agent to the
    key until the form holds, then 0; the form's truth is its own."""
    from gymnasium import spaces

    from mitlc.labels.probe import attr_problems

    declared = {"key": {"attr": "carrying.type", "equals": "key",
                        "toward": {"from": {"attr": "agent_pos"},
                                   "to": {"attr": "grid.grid[type=key].cur_pos"}}}}  # fmt: skip
    labeller = compile_labels(declared, spaces.Discrete(3))
    env = Grid()
    assert attr_problems(labeller, env) == []
    moment = Moment(env, None, False)
    assert labeller(0, {}, moment) == frozenset()
    assert distances(labeller, ["key"], 0, {}, moment) == [pytest.approx(3.0)]
    env.carrying = env.grid.grid.pop()  # picked up: off the grid, and the form holds
    env.carrying.type = "key"
    assert labeller(0, {}, moment) == {"key"}
    assert distances(labeller, ["key"], 0, {}, moment) == [0.0]


def test_a_guide_to_nothing_is_reported_at_its_field() -> None:
    from gymnasium import spaces

    from mitlc.labels import LabelDeclarationError
    from mitlc.labels.probe import attr_problems

    ball = {"from": {"attr": "agent_pos"}, "to": {"attr": "grid.grid[type=ball].cur_pos"}}
    wrong = {"key": {"attr": "carrying", "toward": ball}}
    labeller = compile_labels(wrong, spaces.Discrete(3))
    (problem,) = attr_problems(labeller, Grid())
    assert problem.startswith("labels.key.toward.to.attr: no entry of env.unwrapped.grid.grid")
    assert "has type = 'ball'" in problem
    not_position = {"key": {"attr": "carrying", "toward": {"from": {"attr": "agent_pos"},
                                                            "to": {"attr": "grid"}}}}  # fmt: skip
    (problem,) = attr_problems(compile_labels(not_position, spaces.Discrete(3)), Grid())
    assert "labels.key.toward.to.attr" in problem and "not a position" in problem
    for body, message in [
        ({"from": {"attr": "agent_pos"}}, "expected {from:"),
        ({"from": {"obs": 1}, "to": {"attr": "a"}}, "toward.from: expected"),
        ({"from": {"attr": "a[=1]"}, "to": {"attr": "b"}}, "cannot read"),
    ]:
        with pytest.raises(LabelDeclarationError, match=re.escape(message)):
            compile_labels({"k": {"attr": "carrying", "toward": body}}, spaces.Discrete(3))
