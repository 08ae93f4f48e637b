"""The on-the-fly product environment: gymnasium's checks, seeding, hand-checked steps, and the
key gate: the finite-horizon optimal policy of the exact checker, run in the environment,
succeeds as often as the checker says."""

from __future__ import annotations

import importlib
import time
import warnings
from dataclasses import replace
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from scipy.sparse import csr_matrix

from mitlc.automata import DigitalAutomaton, DigitalState, translate
from mitlc.automata.ends import holds_after
from mitlc.check.solve import pmax_horizon
from mitlc.product import ENV_ID, ProductEnv, build_product, make_env
from mitlc.syntax import parse
from mitlc.worlds import Rewards, Sparse, World, WorldError
from mitlc.worlds.model import FloatArray
from tests.conftest import ROOT

PAPER = ROOT / "specs" / "paper"
CASE1, CASE2 = PAPER / "case1.yaml", PAPER / "case2.yaml"
LEFT, RIGHT, STAY = 0, 1, 2
REWARDS = Rewards(accept=10.0, satisfied=100.0, violated=-50.0, move=-1.0)


def corridor(labels: dict[str, list[int]], start: int = 0, horizon: int = 10) -> World:
    """A deterministic 1x3 corridor (left, right, stay) with ``labels``: proposition -> cells."""
    props = tuple(sorted(labels))
    rows = [[max(s - 1, 0), min(s + 1, 2), s][a] for s in range(3) for a in range(3)]
    letters = [sum(1 << i for i, p in enumerate(props) if s in labels[p]) for s in range(3)]
    return World(
        name="corridor",
        rows=1,
        cols=3,
        cells=((0, 0), (0, 1), (0, 2)),
        actions=("left", "right", "stay"),
        start=start,
        transitions=Sparse(np.arange(10), np.array(rows), np.ones(9)),
        propositions=props,
        letters=np.array(letters, dtype=np.int64),
        spec="<hand-built>",
        spec_source="<test>",
        horizon=horizon,
        discount=0.9,
        rewards=REWARDS,
    )


def spec_env(world: World, spec: str) -> ProductEnv:
    """The product of ``world`` and the automaton of ``spec``."""
    return ProductEnv(world, translate(parse(spec)))


def run(env: ProductEnv, actions: list[int]) -> list[tuple[Any, ...]]:
    """The step results of ``actions`` from a reset."""
    env.reset(seed=0)
    return [env.step(a) for a in actions]


# -- gymnasium ---------------------------------------------------------------------------------


@pytest.mark.parametrize(("path", "spec"), [(CASE1, None), (CASE2, None), (CASE1, "F G !a")])
def test_check_env(path: Any, spec: str | None) -> None:
    base = make_env(path, spec)
    env = gym.make(ENV_ID, world=base.world, automaton=base.automaton, render_mode="ansi")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped)
    obs, _ = env.reset(seed=1)
    assert obs["automaton"] == base.automaton.initial
    assert isinstance(env.action_space, gym.spaces.Discrete)
    assert env.action_space.n == base.world.num_actions + (1 if spec else 0)
    assert "@" in str(env.render())


def test_registration_survives_reimport() -> None:
    module = importlib.import_module("mitlc.product.env")
    importlib.reload(module)
    assert ENV_ID in gym.registry


def test_unknown_propositions_are_rejected() -> None:
    with pytest.raises(WorldError, match="proposition 'c' labels no cell"):
        make_env(CASE1, "F c")
    with pytest.raises(ValueError, match="not among the world's"):
        spec_env(corridor({"a": [2]}), "F b")


@pytest.mark.parametrize("path", [CASE1, CASE2])
def test_same_seed_same_trajectory(path: Any) -> None:
    def trajectory(seed: int) -> list[Any]:
        env = make_env(path)
        obs, _ = env.reset(seed=seed)
        env.action_space.seed(seed)
        out: list[Any] = [obs]
        for _ in range(40):
            obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
            info = {k: v.tolist() if isinstance(v, np.ndarray) else v for k, v in info.items()}
            out.append((obs, reward, terminated, truncated, info, env.state_index()))
            if terminated or truncated:
                obs, _ = env.reset()
                out.append(obs)
        return out

    assert trajectory(7) == trajectory(7)
    assert trajectory(7) != trajectory(8)


def test_pomdp_observations_follow_the_model() -> None:
    env = make_env(CASE2)
    assert env.world.observations is not None
    space = env.observation_space["world"]
    assert isinstance(space, gym.spaces.Discrete)
    assert space.n == len(env.world.observations.names)
    counts: dict[int, int] = {}
    for seed in range(2000):
        obs, _ = env.reset(seed=seed)
        counts[obs["world"]] = counts.get(obs["world"], 0) + 1
    targets, probs = env.world.observations.model.row(env.world.start)
    assert set(counts) <= set(targets.tolist())
    for t, p in zip(targets.tolist(), probs.tolist(), strict=True):
        assert abs(counts.get(t, 0) / 2000 - p) < 0.03


# -- hand-checked steps ------------------------------------------------------------------------


def test_case1_waiting_violates_after_the_window_of_a() -> None:
    env = make_env(CASE1)
    stay = env.world.actions.index("stay")
    steps = run(env, [stay] * 11)
    assert [s[2] for s in steps] == [False] * 10 + [True]  # position 10 is read at step 11
    obs, reward, _, truncated, info = steps[-1]
    assert info["verdict"] == "violated" and not info["success"] and not truncated
    assert info["step"] == 11 and reward == env.world.rewards.violated
    assert obs["world"] == env.world.start


def test_early_visit_violates_and_costs() -> None:
    env = spec_env(corridor({"a": [2]}, start=1), "!a U[2,3] a")
    (_, r1, t1, _, i1), (_, r2, t2, _, i2) = run(env, [RIGHT, STAY])
    # after one step the window of a is still open: an episode stopped there would fail
    assert (r1, t1, i1["verdict"], i1["success"]) == (-1.0, False, "pending", False)
    assert (r2, t2, i2["verdict"], i2["success"]) == (-50.0, True, "violated", False)


def test_timely_visit_satisfies() -> None:
    env = spec_env(corridor({"a": [2]}), "!a U[2,3] a")
    steps = run(env, [RIGHT, RIGHT, STAY])
    assert [s[1] for s in steps] == [-1.0, -1.0, 100.0]
    assert steps[-1][2] and steps[-1][4]["verdict"] == "satisfied" and steps[-1][4]["success"]


def test_horizon_truncates_a_safe_episode() -> None:
    env = spec_env(corridor({"a": [2]}, horizon=4), "G !a")
    steps = run(env, [LEFT, STAY, STAY, STAY])
    assert [(s[2], s[3]) for s in steps] == [(False, False)] * 3 + [(False, True)]
    assert steps[-1][4]["success"] and steps[-1][4]["step"] == 4
    with pytest.raises(RuntimeError, match="reset"):
        env.step(STAY)


def one_state(num_sets: int, marks: tuple[int, ...], epsilon: bool = False) -> DigitalAutomaton:
    """A hand-built automaton over (a, b); with ``epsilon``: 0 -jump-> 1, and 1 is F G !a's
    accepting state (a leads to the violated sink 2). A stop in the pending state (the
    accepting one) succeeds once every set has been seen (its end code, mitlc.automata.ends)."""
    pending = DigitalState("x", "initial", "pending")
    if not epsilon:
        pending = DigitalState("x", "initial", "pending", holds_after((1 << num_sets) - 1))
        return DigitalAutomaton.from_table(
            "x", "x", ("a", "b"), (pending,), 0, ((0,) * 4,), (marks,), num_sets
        )
    accepting = DigitalState("G !a", "accepting", "pending", holds_after(1))
    sink = DigitalState("false", "initial", "violated")
    return DigitalAutomaton.from_table(
        "F G !a", "F G !a", ("a", "b"), (pending, accepting, sink), 0,
        ((0, 0, 0, 0), (1, 2, 1, 2), (2, 2, 2, 2)), ((0,) * 4, (1, 0, 1, 0), (0,) * 4), 1,
        ((0, 1),),
    )  # fmt: skip


def test_acceptance_frontier_pays_each_set_once_a_round() -> None:
    # letters: 0 none, 1 a, 2 b, 3 ab; a is in set 0, b in set 1.
    env = ProductEnv(corridor({"a": [0], "b": [2]}), one_state(2, (0, 1, 2, 3)))
    steps = run(env, [RIGHT, LEFT, RIGHT, RIGHT, STAY, STAY])  # reads a, -, a, -, b, b
    assert [s[1] for s in steps] == [9, -1, -1, -1, 10, 10]
    assert [s[4]["marks"] for s in steps] == [[0], [], [0], [], [1], [1]]
    assert [s[4]["rounds"] for s in steps] == [0, 0, 0, 0, 1, 1]
    assert [s[4]["success"] for s in steps] == [False] * 4 + [True] * 2
    assert env.frontier == 0b10


def test_jumps_take_no_time_and_invalid_jumps_cost_a_step() -> None:
    env = ProductEnv(corridor({"a": [2], "b": [1]}), one_state(1, (), epsilon=True))
    jump = env.world.num_actions
    env.reset(seed=0)
    assert env.action_space.n == jump + 1 and env.action_masks().tolist() == [True] * 4
    obs, reward, terminated, truncated, info = env.step(jump)
    assert obs == {"world": 0, "automaton": 1, "frontier": 0} and reward == 0.0
    assert info["step"] == 0
    assert not (terminated or truncated or info["invalid_action"]) and env.steps == 0
    assert env.action_masks().tolist() == [True, True, True, False]
    obs, reward, _, _, info = env.step(jump)
    assert obs == {"world": 0, "automaton": 1, "frontier": 0} and reward == 0.0
    assert info["invalid_action"]
    assert env.state_index() == 0 * 3 + 1 and info["step"] == 1
    _, reward, _, _, info = env.step(STAY)  # reads !a in the accepting state: set 0
    assert (reward, info["rounds"], info["step"], info["success"]) == (10.0, 1, 2, True)
    with pytest.raises(ValueError, match="not in"):
        env.step(jump + 1)


# -- the gate: the checker's optimal policy in the environment ---------------------------------


def optimal_actions(env: ProductEnv, history: list[FloatArray]) -> tuple[Any, list[int]]:
    """``table[r][mask][x]``: the env action of a finite-horizon optimal choice in product
    state ``x`` with ``r`` steps remaining and the sets ``mask`` seen (a jump only when it is
    strictly better), and the product id of each flat env state (``-1`` where none)."""
    product = build_product(env.world, env.automaton)
    t, ptr, n = product.transitions, product.choice_ptr, product.num_states
    matrix = csr_matrix((t.probs, t.targets, t.indptr), shape=(product.num_choices, n))
    sources = np.repeat(np.arange(n), np.diff(ptr))
    jump = product.action < 0
    jump_to = t.targets[t.indptr[:-1]][jump]
    env_action = product.action.copy()
    for c in np.flatnonzero(jump).tolist():
        q = int(product.automaton_state[sources[c]])
        target = -1 - int(product.action[c])
        env_action[c] = env.world.num_actions + env.automaton.jumps_from(q).index(target)
    masks = len(history[0])
    table = np.zeros((len(history), masks, n), dtype=np.int64)
    for r in range(1, len(history)):
        for mask in range(masks):
            values = np.empty(product.num_choices)
            seen = mask | product.marks
            for after in np.unique(seen).tolist():
                chosen = (seen == after) & ~jump
                values[chosen] = matrix[chosen] @ history[r - 1][after]
            values[jump] = history[r][mask, jump_to] - 1e-9
            best = np.maximum.reduceat(values, ptr[:-1])
            candidates = np.flatnonzero(values >= best[sources] - 1e-12)
            first = np.full(n, product.num_choices, dtype=np.int64)
            np.minimum.at(first, sources[candidates], candidates)
            table[r, mask] = env_action[np.minimum(first, product.num_choices - 1)]
    ids = np.full(env.num_flat_states, -1, dtype=np.int64)
    live = product.world_state >= 0
    flat = product.world_state[live] * env.num_q + product.automaton_state[live]
    ids[flat] = np.flatnonzero(live)
    return table.tolist(), ids.tolist()


def gate(env: ProductEnv, episodes: int) -> tuple[float, float, float]:
    """Exact and empirical success of the checker's optimal policy, and the seconds the
    episodes took."""
    horizon = env.world.horizon
    exact, history = pmax_horizon(build_product(env.world, env.automaton), horizon)
    table, ids = optimal_actions(env, history)
    started, wins = time.perf_counter(), 0
    for episode in range(episodes):
        env.reset(seed=episode)
        while True:
            action = table[horizon - env.steps][env.frontier][ids[env.state_index()]]
            _, _, terminated, truncated, info = env.step(action)
            if terminated or truncated:
                break
        wins += info["success"]
    return exact, wins / episodes, time.perf_counter() - started


def assert_agrees(exact: float, empirical: float, episodes: int) -> None:
    error = np.sqrt(exact * (1 - exact) / episodes)
    assert abs(empirical - exact) <= 4 * error + 1e-12, (exact, empirical, error)


@pytest.mark.parametrize("episodes", [20_000])
def test_optimal_policy_succeeds_as_checked_case1(episodes: int) -> None:
    exact, empirical, _ = gate(make_env(CASE1), episodes)
    assert 0.9 < exact < 1.0
    assert_agrees(exact, empirical, episodes)


def test_optimal_policy_succeeds_as_checked_with_jumps() -> None:
    # F G a with 8 steps: reach a, jump to the accepting component there, and stay.
    base = make_env(CASE1, "F G a")
    env = ProductEnv(replace(base.world, horizon=8), base.automaton)
    exact, empirical, _ = gate(env, 5_000)
    assert 0.5 < exact < 0.95
    assert_agrees(exact, empirical, 5_000)


def test_an_agent_that_ignores_the_mask_ends_by_the_horizon() -> None:
    """An invalid jump used to be a zero-time no-op that was never truncated: an agent that
    ignores the mask (SB3's DQN does) looped forever; 10,000 of them left the step counter
    at 1. Now each costs a step, so the episode is truncated at the horizon."""
    env = ProductEnv(corridor({"a": [2], "b": [1]}), one_state(1, (), epsilon=True))
    jump = env.world.num_actions
    env.reset(seed=0)
    env.step(jump)  # the one valid jump; from here on it is invalid
    taken, truncated = 0, False
    while not truncated and taken < 10_000:
        _, _, terminated, truncated, info = env.step(jump)
        assert info["invalid_action"] and not terminated
        taken += 1
    assert truncated and taken == env.world.horizon and env.steps == env.world.horizon
    with pytest.raises(RuntimeError, match="reset"):
        env.step(jump)
