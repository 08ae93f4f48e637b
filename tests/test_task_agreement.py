"""The task monitor is the one definition of a task during an episode: the gymnasium env, the
vectorised simulator and the exact evaluation of a policy, driven over random worlds x random
specs x random policies, give the same rewards, verdicts and success.

Worlds are deterministic (every action has one successor), so one action sequence is one
episode in all three: the env and the simulator must agree step by step, and the exact value of
the policy (0 or 1) must be the episode's success. A stochastic world then checks the exact
value against both samplers' success rates.
"""

from __future__ import annotations

import random
from dataclasses import replace

import numpy as np
import pytest

from mitlc.automata import translate
from mitlc.learn.envs.vec import VecProduct, tables
from mitlc.learn.evaluation.exact import policy_success
from mitlc.product import ProductEnv, build_product
from mitlc.product.explicit import SATISFIED, VIOLATED, Product
from mitlc.syntax import ast, parse, to_text
from mitlc.task import VERDICT_NAMES, TaskMonitor
from mitlc.task.monitor import DENSE_LETTERS
from mitlc.worlds.model import IntArray, Rewards, Sparse, World
from tests.strategies import random_formula

REWARDS = Rewards(accept=3.0, satisfied=10.0, violated=-7.0, move=-0.5)


def random_world(rng: random.Random, props: tuple[str, ...], deterministic: bool) -> World:
    """3-6 states, 2-3 actions (the last one ``stay``, certain), random labels."""
    n, num_actions = rng.randint(3, 6), rng.randint(2, 3)
    indptr, targets, probs = [0], [], []
    for s in range(n):
        for a in range(num_actions):
            if a == num_actions - 1:
                succ, weights = [s], [1]
            elif deterministic:
                succ, weights = [rng.randrange(n)], [1]
            else:
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
        actions=(*(f"a{i}" for i in range(num_actions - 1)), "stay"),
        start=rng.randrange(n),
        transitions=Sparse(np.array(indptr), np.array(targets), np.array(probs)),
        propositions=props,
        letters=letters,
        spec="<random>",
        spec_source="<test>",
        horizon=rng.randint(3, 9),
        discount=0.9,
        rewards=REWARDS,
    )


def specs(seed: int, count: int) -> list[ast.Formula]:
    rng = random.Random(seed)
    out = [parse("G F a & G !b"), parse("F G a"), parse("(!a U[1,3] a) & (!b U[2,5] b)")]
    while len(out) < count:
        f = random_formula(rng, rng.randint(1, 4), ["a", "b"], rng.random() < 0.3, 3)
        if ast.atoms(f):
            out.append(f)
    return out


def random_actions(product: Product, num_actions: int, rng: np.random.Generator) -> IntArray:
    """A random valid action (world action or jump) per ``[mask, product state]``; -1 at the
    absorbing states."""
    counts = np.diff(product.choice_ptr)
    masks = 1 << product.num_sets
    actions = (rng.random((masks, product.num_states)) * counts).astype(np.int64)
    actions[:, product.world_state < 0] = -1
    for x, _ in product.initial_distribution:  # a task decided at the start: one step
        actions[:, x] = np.maximum(actions[:, x], 0)
    return actions


def choices_of(product: Product, actions: IntArray) -> IntArray:
    """The product choices of per-state action indices (-1 stays -1)."""
    chosen: IntArray = np.where(actions >= 0, product.choice_ptr[:-1] + actions, -1)
    return chosen


def env_episode(
    env: ProductEnv, product: Product, actions: IntArray, seed: int
) -> list[tuple[float, str, bool, bool, bool]]:
    """(reward, verdict, terminated, truncated, success) of each step of one env episode."""
    ids = {
        (int(s), int(q)): x
        for x, (s, q) in enumerate(zip(product.world_state, product.automaton_state, strict=True))
        if s >= 0
    }
    env.reset(seed=seed)
    steps = []
    while True:
        verdict = env.automaton.verdict(env.automaton_state)
        absorbing = {"violated": VIOLATED, "satisfied": SATISFIED}
        x = (
            absorbing[verdict]
            if verdict in absorbing
            else ids[(env.world_state, env.automaton_state)]
        )
        _, reward, terminated, truncated, info = env.step(actions[env.frontier, x])
        steps.append((reward, info["verdict"], terminated, truncated, info["success"]))
        if terminated or truncated:
            return steps


def vec_episode(
    world: World, product: Product, actions: IntArray
) -> list[tuple[float, str, bool, bool, bool]]:
    """The same from one episode of the vectorised simulator."""
    t = tables(product, world)
    sim = VecProduct(t, 1, np.random.default_rng(0))
    steps = []
    while True:
        action = actions[sim.mask, sim.state]
        step = sim.step(action)
        nxt = int(step.next_state[0])
        verdict = int(t.verdict[nxt])
        steps.append(
            (
                float(step.reward[0]),
                VERDICT_NAMES[verdict],
                bool(step.terminated[0]),
                bool(step.truncated[0]),
                bool(step.success[0]),
            )
        )
        if step.done[0]:
            return steps


@pytest.mark.parametrize("seed", range(8))
def test_env_simulator_and_exact_evaluation_agree(seed: int) -> None:
    rng = random.Random(seed)
    for formula in specs(seed, 10):
        automaton = translate(formula)
        world = random_world(rng, automaton.propositions, deterministic=True)
        product = build_product(world, automaton)
        actions = random_actions(product, world.num_actions, np.random.default_rng(seed))
        in_env = env_episode(ProductEnv(world, automaton), product, actions, seed)
        in_vec = vec_episode(world, product, actions)
        assert in_env == in_vec, to_text(formula)  # rewards are sums of halves: exact
        exact = policy_success(product, choices_of(product, actions), world.horizon)
        assert exact == float(in_vec[-1][4]), to_text(formula)


@pytest.mark.parametrize("seed", range(3))
def test_stochastic_worlds_success_rates_agree_with_the_exact_value(seed: int) -> None:
    rng = random.Random(100 + seed)
    for formula in specs(100 + seed, 4):
        automaton = translate(formula)
        world = random_world(rng, automaton.propositions, deterministic=False)
        product = build_product(world, automaton)
        actions = random_actions(product, world.num_actions, np.random.default_rng(seed))
        exact = policy_success(product, choices_of(product, actions), world.horizon)
        episodes = 2000
        tolerance = 4.5 * np.sqrt(max(exact * (1 - exact), 1e-4) / episodes) + 1e-9
        env = ProductEnv(world, automaton)
        wins = sum(
            env_episode(env, product, actions, seed * episodes + i)[-1][4] for i in range(episodes)
        )
        assert abs(wins / episodes - exact) <= tolerance, to_text(formula)
        t = tables(product, world)
        sim = VecProduct(t, episodes, np.random.default_rng(seed))
        ended = np.zeros(episodes, dtype=bool)
        won = np.zeros(episodes, dtype=bool)
        while not ended.all():
            step = sim.step(np.maximum(actions[sim.mask, sim.state], 0))
            won |= step.done & step.success & ~ended
            ended |= step.done
        assert abs(won.mean() - exact) <= tolerance, to_text(formula)


def test_the_monitor_batched_and_scalar_forms_agree() -> None:
    """Random letter sequences through :meth:`TaskMonitor.step` one run at a time and through
    :meth:`TaskMonitor.read_batch` for all runs at once."""
    rng = np.random.default_rng(7)
    for formula in specs(7, 12):
        automaton = translate(formula)
        scalar, batch = TaskMonitor(automaton, REWARDS), TaskMonitor(automaton, REWARDS)
        runs, length = 16, 12
        letters = rng.integers(0, 1 << len(automaton.propositions), size=(length, runs))
        q = np.full(runs, automaton.initial, dtype=np.int64)
        frontier, rounds = np.zeros(runs, dtype=np.int64), np.zeros(runs, dtype=np.int64)
        states = [scalar.reset() for _ in range(runs)]
        for t in range(length):
            out = batch.read_batch(q, frontier, rounds, letters[t])
            for i in range(runs):
                one = scalar.step(states[i], int(letters[t, i]))
                states[i] = one.state
                assert (one.state.q, one.state.frontier, one.state.rounds) == (
                    out.q[i],
                    out.frontier[i],
                    out.rounds[i],
                )
                assert (one.reward, one.verdict, one.terminated, one.success) == (
                    out.reward[i],
                    out.verdict[i],
                    out.terminated[i],
                    out.success[i],
                )
            q, frontier, rounds = out.q, out.frontier, out.rounds


def test_a_random_start_is_averaged_over_its_distribution() -> None:
    """A world whose start is drawn: the exact evaluation is the average of the certain starts'
    values, and the simulator draws starts by their probabilities."""
    rng = random.Random(3)
    automaton = translate(parse("G F a & G !b"))
    world = random_world(rng, automaton.propositions, deterministic=False)
    dist = ((0, 0.25), (1, 0.75))
    drawn = replace(world, start=1, start_distribution=dist)
    product = build_product(drawn, automaton)
    assert len(product.initial_distribution) == 2
    actions = random_actions(product, world.num_actions, np.random.default_rng(3))
    value = policy_success(product, choices_of(product, actions), world.horizon)
    parts = []
    for s, _ in dist:
        alone = build_product(replace(world, start=s), automaton)
        x = {
            (int(a), int(b)): i
            for i, (a, b) in enumerate(zip(alone.world_state, alone.automaton_state, strict=True))
        }
        y = {
            (int(a), int(b)): i
            for i, (a, b) in enumerate(
                zip(product.world_state, product.automaton_state, strict=True)
            )
        }
        mapped = np.full_like(actions[:, : alone.num_states], -1)
        for key, i in x.items():
            if key in y:
                mapped[:, i] = actions[:, y[key]]
        parts.append(policy_success(alone, choices_of(alone, mapped), world.horizon))
    assert value == pytest.approx(0.25 * parts[0] + 0.75 * parts[1])
    sim = VecProduct(tables(product, drawn), 40_000, np.random.default_rng(0))
    starts = product.world_state[sim.state]
    assert abs((starts == 1).mean() - 0.75) < 0.01


class _Parity:
    """A hand-made automaton over 22 propositions (more letters than the batched form's dense
    table): state ``k`` counts, modulo 3, the letters in which ``p21`` holds; a letter with
    ``p0`` and ``p1`` both true is a violation; each count back to 0 marks the one set."""

    formula = "<parity>"
    propositions = tuple(f"p{i}" for i in range(22))
    num_sets = 1
    initial = 0

    def successor(self, state: int, letter: int) -> tuple[int, int]:
        if state == 3 or letter & 3 == 3:
            return 3, 0
        after = (state + (letter >> 21 & 1)) % 3
        return after, int(after == 0 and letter >> 21 & 1)

    def verdict(self, state: int) -> str:
        return "violated" if state == 3 else "pending"

    def jumps(self, state: int) -> tuple[int, ...]:
        return ()

    def obligation(self, state: int) -> str:
        return "false" if state == 3 else f"count {state}"

    def end(self, state: int) -> bool:
        return False


def test_the_monitor_handles_alphabets_past_its_dense_table() -> None:
    automaton = _Parity()
    scalar, batch = TaskMonitor(automaton, REWARDS), TaskMonitor(automaton, REWARDS)
    assert 1 << len(automaton.propositions) > DENSE_LETTERS
    rng = np.random.default_rng(11)
    runs = 64
    q = np.zeros(runs, dtype=np.int64)
    frontier, rounds = np.zeros(runs, dtype=np.int64), np.zeros(runs, dtype=np.int64)
    states = [scalar.reset() for _ in range(runs)]
    for _ in range(30):
        letters = rng.integers(0, 1 << 22, size=runs) & ~np.int64(3 if rng.random() < 0.9 else 0)
        out = batch.read_batch(q, frontier, rounds, letters)
        for i in range(runs):
            one = scalar.step(states[i], int(letters[i]))
            states[i] = one.state
            assert (one.state.q, one.state.rounds, one.success) == (
                out.q[i],
                out.rounds[i],
                out.success[i],
            )
        q, frontier, rounds = out.q, out.frontier, out.rounds
    assert rounds.max() > 0 and (q == 3).any()
