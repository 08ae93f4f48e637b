"""The clock view (:mod:`mitlc.automata.clocks`): each digital state as the T-LDGBA location and
clock values a run of the T-LDGBA reaches it with, and the task wrapper's and the learners'
observation of it, which must behave as the digital state it stands for."""

from __future__ import annotations

import random
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

from mitlc.automata import translate
from mitlc.automata.clocks import ClockViewError, clock_view, clock_view_of
from mitlc.automata.fold import fold
from mitlc.automata.ldba import translate_terms
from mitlc.gym import TaskWrapper
from mitlc.gym.wrapper import TaskWrapperError
from mitlc.syntax import parse
from tests.strategies import random_formula
from tests.test_fold import simulate

FORMULAS = [
    "!a U[0,100] (a & F[0,100] b)",
    "(!a U[5,10] a) & (!b U[15,20] b)",
    "G (a -> F[0,5] b)",
    "G F[5,10] a",
    "F[0,4] (a & F[0,4] b)",
    "G (a -> F[2,4] b) & F G !c",
    "F a & G F b",
]


def check_view(text_or_formula: Any) -> None:
    """Every digital state's point is one a run of the T-LDGBA reaches it at (so it stands for
    that state, and no other), and the features tell every state apart."""
    formula = parse(text_or_formula) if isinstance(text_or_formula, str) else text_or_formula
    translation = translate_terms(formula)
    view = clock_view(translation)
    timed = fold(translation)
    assert view.num_locations == len(timed.locations)
    assert view.bounds == timed.clock_bounds
    reached = simulate(translation, timed)
    for state in range(len(translation.automaton.states)):
        loc = view.location[state]
        used = timed.locations[loc].clocks
        point = (loc, tuple(view.clocks[state][c] for c in used))
        assert reached.get(point) == state, (state, point)
        unused = [view.clocks[state][c] for c in range(view.num_clocks) if c not in used]
        assert unused == [0] * len(unused)
    features = view.features()
    assert features.shape == (len(translation.automaton.states), view.width)
    assert len({row.tobytes() for row in features}) == len(features), "two states look alike"
    assert features.min() >= 0.0 and features.max() <= 1.0


@pytest.mark.parametrize("text", FORMULAS)
def test_the_clock_view_stands_for_the_digital_state(text: str) -> None:
    check_view(text)


def test_the_clock_view_of_random_formulas() -> None:
    rng = random.Random(5)
    for _ in range(120):
        check_view(random_formula(rng, rng.randint(1, 4), ["a", "b"], bounded=False, max_bound=5))


def test_a_long_deadline_is_a_few_locations_and_one_clock() -> None:
    view = clock_view_of(translate(parse("!a U[0,100] (a & F[0,100] b)")))
    assert len(view.location) > 200 and view.num_locations <= 4 and view.num_clocks == 1
    assert view.width <= 5


def test_an_automaton_not_of_its_source_is_refused() -> None:
    from dataclasses import replace

    automaton = translate(parse("F[0,3] a"))
    other = replace(automaton, source="F[0,4] a")
    with pytest.raises(ClockViewError, match="not its formula's translation"):
        clock_view_of(other)


class Line(gym.Env[np.ndarray, int]):
    """A point on a line of 12 cells: 0 left, 1 stays, 2 right; seeded slips."""

    observation_space = gym.spaces.Box(0.0, 11.0, (1,), dtype=np.float32)
    action_space = gym.spaces.Discrete(3)

    def reset(self, *, seed: int | None = None, options: Any = None) -> tuple[Any, dict[str, Any]]:
        super().reset(seed=seed)
        self.x = 0
        return np.array([self.x], dtype=np.float32), {}

    def step(self, action: int) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        move = int(action) - 1
        if self.np_random.random() < 0.2:
            move = 0
        self.x = min(max(self.x + move, 0), 11)
        return np.array([self.x], dtype=np.float32), 0.0, False, False, {}


LABELS = {
    "a": {"box": {"index": [0], "low": [5.0], "high": [11.0]}},
    "b": {"box": {"index": [0], "low": [0.0], "high": [1.0]}},
}
SPEC = "!a U[0,8] (a & F[0,6] b)"


@pytest.mark.parametrize("flatten", [False, True])
def test_the_wrapper_with_clocks_behaves_as_with_states(flatten: bool) -> None:
    """Any policy (random actions here) meets the same rewards, ends, successes and digital
    states with either observation, and the clocks observation is the view of the state."""
    state = TaskWrapper(Line(), SPEC, LABELS, horizon=20, flatten=flatten)
    clocks = TaskWrapper(Line(), SPEC, LABELS, horizon=20, flatten=flatten, task_obs="clocks")
    assert clocks.clocks is not None
    features = clocks.clocks.features()
    rng = np.random.default_rng(0)
    for episode in range(30):
        o1, i1 = state.reset(seed=episode)
        o2, i2 = clocks.reset(seed=episode)
        done = False
        while not done:
            q = i2["automaton_state"]
            assert q == i1["automaton_state"]
            if flatten:
                assert o2.shape == clocks.observation_space.shape
                assert np.array_equal(o2[1 : 1 + features.shape[1]], features[q])
                assert np.array_equal(o1[0:1], o2[0:1])
            else:
                assert set(o2) == {"env", "location", "clocks", "frontier"}
                assert o2["location"] == clocks.clocks.location[q]
                assert np.allclose(o2["clocks"], features[q, clocks.clocks.num_locations :])
                assert clocks.observation_space.contains(o2)
            action = int(rng.integers(3))
            o1, r1, t1, u1, i1 = state.step(action)
            o2, r2, t2, u2, i2 = clocks.step(action)
            assert (r1, t1, u1, i1["success"]) == (r2, t2, u2, i2["success"])
            done = t1 or u1


def test_the_encoder_reads_the_wrappers_flat_clocks_layout() -> None:
    """mitlc's encoder with the clock features (``scaled=False``: SB3's layout) gives the
    wrapper's flat observation from the Dict one: one definition of the features."""
    from mitlc.learn.learners.encoder import Encoder

    flat = TaskWrapper(Line(), SPEC, LABELS, horizon=20, flatten=True, task_obs="clocks")
    plain = TaskWrapper(Line(), SPEC, LABELS, horizon=20)
    assert flat.clocks is not None
    automaton = plain.automaton
    encoder = Encoder.of_spaces(
        plain.observation_space["env"], len(automaton.states), automaton.num_sets, 3,  # type: ignore[attr-defined]
        scaled=False, task_features=flat.clocks.features(),
    )  # fmt: skip
    for seed in range(5):
        o1, _ = flat.reset(seed=seed)
        o2, _ = plain.reset(seed=seed)
        done = False
        while not done:
            x = encoder(o2["env"][None], np.array([o2["automaton"]]), np.array([o2["frontier"]]))
            assert np.array_equal(x.numpy()[0], o1)
            action = 2 if o2["env"][0] < 6 else 0
            o1, _, terminated, truncated, _ = flat.step(action)
            o2 = plain.step(action)[0]
            done = terminated or truncated


def test_clocks_of_a_lazy_automaton_are_refused() -> None:
    from mitlc.automata import LazyAutomaton

    lazy = LazyAutomaton(parse("F[0,3] a"))
    with pytest.raises(TaskWrapperError, match="lazy automaton"):
        TaskWrapper(Line(), lazy, LABELS, horizon=5, max_automaton_states=10, task_obs="clocks")
    with pytest.raises(TaskWrapperError, match="task_obs"):
        TaskWrapper(Line(), "F a", LABELS, horizon=5, task_obs="clock")  # type: ignore[arg-type]
