"""One episode, one meaning (issue 22): the success of an episode that stops with its task
pending is the formula's value on the finite trace it read, and every path agrees on it.

* Random toy-text envs with terminating states (a ``P`` table, as FrozenLake's) x random
  formulas (persistence and bounded deadlines among them) x random policies (jumps included) x
  horizons shorter and longer than the task's deadlines: :class:`mitlc.gym.TaskWrapper` around
  the env itself, the vectorised simulator of the converted world's product and the exact
  evaluation of the policy give the same success, and for deterministic envs the same rewards,
  verdicts and terminated/truncated flags step by step.
* Random bounded formulas over random traces through the wrapper around an env whose
  observation is the letter: ``info["success"]`` is the finite-trace semantics of the formula
  on the letters read (:mod:`mitlc.semantics.finite`, itself checked against rtamt).
"""

from __future__ import annotations

import random
import warnings
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces

from mitlc.automata import DigitalAutomaton, translate
from mitlc.check.solve import pmax_horizon
from mitlc.gym import EpisodeCutWarning, TaskWrapper
from mitlc.learn.envs.vec import VecProduct, tables
from mitlc.learn.evaluation.exact import policy_success
from mitlc.product import build_product
from mitlc.product.explicit import SATISFIED, VIOLATED, Product
from mitlc.semantics import evaluate_finite
from mitlc.syntax import ast, parse, to_text
from mitlc.task import VERDICT_NAMES
from mitlc.task.horizon import decision_steps, temporal_depth
from mitlc.worlds.gym_world import EnvWorldFile, build_world
from mitlc.worlds.model import IntArray, World
from tests.strategies import horizon as depth_oracle
from tests.strategies import random_formula, random_trace
from tests.test_semantics_rtamt import _parse_rtamt, _rtamt_robustness, _to_rtamt

RTAMT_CHECKS = 80
"""Of the random (formula, trace) pairs, how many are also given to rtamt itself."""

Step = tuple[float, str, bool, bool, bool]
"""(reward, verdict, terminated, truncated, success) of one step."""

REWARDS = {"accept": 3.0, "satisfied": 10.0, "violated": -7.0, "move": 0.0}


class ToyText(gym.Env[int, int]):
    """A random toy-text env: ``P[s][a]`` lists ``(probability, next, reward, terminated)``;
    entering a terminal state ends the episode (and only entering one does)."""

    def __init__(self, rng: random.Random, deterministic: bool) -> None:
        n, m = rng.randint(3, 6), rng.randint(2, 3)
        self.terminal = set(rng.sample(range(1, n), rng.randint(0, 2)))
        self.start = 0
        self.P: dict[int, dict[int, list[tuple[float, int, float, bool]]]] = {}
        for s in range(n):
            self.P[s] = {}
            for a in range(m):
                if s in self.terminal:
                    self.P[s][a] = [(1.0, s, 0.0, True)]
                    continue
                count = 1 if deterministic else rng.randint(1, min(3, n))
                succ = sorted(rng.sample(range(n), count))
                weights = [rng.randint(1, 4) for _ in succ]
                self.P[s][a] = [
                    (w / sum(weights), t, 0.0, t in self.terminal)
                    for w, t in zip(weights, succ, strict=True)
                ]
        self.initial_state_distrib = np.eye(n)[self.start]
        self.observation_space = spaces.Discrete(n)
        self.action_space = spaces.Discrete(m)
        self.state = self.start

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[int, dict[str, Any]]:
        super().reset(seed=seed)
        self.state = self.start
        return self.state, {}

    def step(self, action: int) -> tuple[int, float, bool, bool, dict[str, Any]]:
        entries = self.P[self.state][int(action)]
        pick = self.np_random.choice(len(entries), p=[e[0] for e in entries])
        _, self.state, reward, terminated = entries[pick]
        return self.state, reward, terminated, False, {}


def labels_of(rng: random.Random, env: ToyText, props: tuple[str, ...]) -> dict[str, Any]:
    """Each proposition holds in a random non-empty set of observations."""
    n = int(env.observation_space.n)
    return {p: {"obs": sorted(rng.sample(range(n), rng.randint(1, n - 1)))} for p in props}


def world_of(env: ToyText, labels: dict[str, Any], formula: str, horizon: int) -> World:
    """The finite world mitlc reads off the env's table (terminal states absorbing)."""
    file = EnvWorldFile.model_validate(
        {
            "env": {"id": "ToyText-v0"},
            "labels": labels,
            "spec": {"formula": formula},
            "horizon": horizon,
            "reward": REWARDS,
        }
    )
    props = tuple(sorted(labels))
    return build_world(
        file, env, name="toy", spec=formula, spec_source="<test>", propositions=props
    )


def specs(rng: random.Random, count: int) -> list[ast.Formula]:
    out = [
        parse("F G a"),
        parse("G !b"),
        parse("!b U[0,4] a"),
        parse("F[0,3] (a & F[0,3] b)"),
        parse("G (a -> F[0,2] b)"),
        parse("G F a | F G b"),
    ]
    while len(out) < count:
        f = random_formula(rng, rng.randint(1, 4), ["a", "b"], rng.random() < 0.5, 4)
        if ast.atoms(f) == ("a", "b"):
            out.append(f)
    return out


def random_policy(product: Product, rng: np.random.Generator) -> IntArray:
    """A random choice index (world action or jump) per ``[mask, product state]``; -1 at the
    absorbing states."""
    counts = np.diff(product.choice_ptr)
    masks = 1 << product.num_sets
    actions = (rng.random((masks, product.num_states)) * counts).astype(np.int64)
    actions[:, product.world_state < 0] = -1
    actions[:, product.initial] = np.maximum(actions[:, product.initial], 0)
    return actions


def wrapper_episode(env: TaskWrapper, product: Product, policy: IntArray, seed: int) -> list[Step]:
    ids = {
        (int(s), int(q)): x
        for x, (s, q) in enumerate(zip(product.world_state, product.automaton_state, strict=True))
        if s >= 0
    }
    obs, _ = env.reset(seed=seed)
    steps: list[Step] = []
    while True:
        verdict = env.automaton.verdict(env.automaton_state)
        absorbing = {"violated": VIOLATED, "satisfied": SATISFIED}
        x = absorbing[verdict] if verdict in absorbing else ids[(int(obs["env"]), obs["automaton"])]
        obs, reward, terminated, truncated, info = env.step(int(policy[env.frontier, x]))
        steps.append((float(reward), info["verdict"], terminated, truncated, info["success"]))
        if terminated or truncated:
            return steps


def simulator_episodes(
    world: World, product: Product, policy: IntArray, count: int, seed: int
) -> list[list[Step]]:
    """``count`` episodes of the vectorised simulator, each slot's first."""
    t = tables(product, world)
    sim = VecProduct(t, count, np.random.default_rng(seed))
    episodes: list[list[Step]] = [[] for _ in range(count)]
    ended = np.zeros(count, dtype=bool)
    while not ended.all():
        step = sim.step(np.maximum(policy[sim.mask, sim.state], 0))
        for i in np.flatnonzero(~ended).tolist():
            nxt = int(step.next_state[i])
            episodes[i].append(
                (
                    float(step.reward[i]),
                    VERDICT_NAMES[int(t.verdict[nxt])],
                    bool(step.terminated[i]),
                    bool(step.truncated[i]),
                    bool(step.success[i]),
                )
            )
        ended |= step.done
    return episodes


def setting(
    rng: random.Random, formula: ast.Formula, deterministic: bool
) -> tuple[ToyText, dict[str, Any], DigitalAutomaton, World, Product, int]:
    env = ToyText(rng, deterministic)
    automaton = translate(formula)
    labels = labels_of(rng, env, automaton.propositions)
    depth = temporal_depth(formula)
    horizon = rng.randint(1, 2 * (depth or 4) + 2)  # shorter and longer than the deadlines
    world = world_of(env, labels, to_text(formula), horizon)
    return env, labels, automaton, world, build_product(world, automaton), horizon


@pytest.mark.parametrize("seed", range(6))
def test_wrapper_simulator_and_exact_evaluation_agree_step_by_step(seed: int) -> None:
    rng = random.Random(seed)
    for formula in specs(rng, 14):
        env, labels, automaton, world, product, horizon = setting(rng, formula, True)
        policy = random_policy(product, np.random.default_rng(seed))
        wrapped = TaskWrapper(
            env, automaton, labels, rewards=REWARDS, horizon=horizon, env_end="step"
        )
        in_env = wrapper_episode(wrapped, product, policy, seed)
        (in_sim,) = simulator_episodes(world, product, policy, 1, seed)
        assert in_env == in_sim, (to_text(formula), horizon)
        exact = policy_success(
            product, np.where(policy >= 0, product.choice_ptr[:-1] + policy, -1), horizon
        )
        assert exact == float(in_sim[-1][4]), (to_text(formula), horizon)


@pytest.mark.parametrize("seed", range(3))
def test_success_rates_agree_with_the_exact_value_on_stochastic_envs(seed: int) -> None:
    rng = random.Random(100 + seed)
    for formula in specs(rng, 4):
        env, labels, automaton, world, product, horizon = setting(rng, formula, False)
        policy = random_policy(product, np.random.default_rng(seed))
        choices = np.where(policy >= 0, product.choice_ptr[:-1] + policy, -1)
        exact = policy_success(product, choices, horizon)
        episodes = 1500
        tolerance = 4.5 * np.sqrt(max(exact * (1 - exact), 1e-4) / episodes) + 1e-9
        for env_end in ("step", "auto"):
            wrapped = TaskWrapper(
                env, automaton, labels, rewards=REWARDS, horizon=horizon, env_end=env_end
            )
            if env_end == "auto" and wrapped.max_jumps:
                continue  # "auto" is "step" here
            wins = sum(
                wrapper_episode(wrapped, product, policy, seed * episodes + i)[-1][4]
                for i in range(episodes)
            )
            assert abs(wins / episodes - exact) <= tolerance, (to_text(formula), env_end)
        sim = simulator_episodes(world, product, policy, episodes, seed)
        won = sum(e[-1][4] for e in sim)
        assert abs(won / episodes - exact) <= tolerance, to_text(formula)


# -- the finite-trace semantics through the wrapper ------------------------------------------------


class Letters(gym.Env[int, int]):
    """An env whose observation is the letter: it plays a fixed word, whatever the action."""

    def __init__(self, word: list[int], size: int) -> None:
        self.word = word
        self.observation_space = spaces.Discrete(size)
        self.action_space = spaces.Discrete(1)
        self.t = 0

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[int, dict[str, Any]]:
        super().reset(seed=seed)
        self.t = 0
        return self.word[0], {}

    def step(self, action: int) -> tuple[int, float, bool, bool, dict[str, Any]]:
        self.t += 1
        return self.word[min(self.t, len(self.word) - 1)], 0.0, False, False, {}


def test_success_is_the_finite_trace_semantics_of_the_letters_read() -> None:
    rng = random.Random(22)
    atoms = ("a", "b")
    labels = {"a": {"obs": [1, 3]}, "b": {"obs": [2, 3]}}
    checked = 0
    while checked < 300:
        formula = random_formula(rng, rng.randint(1, 4), list(atoms), True, 4)
        if ast.atoms(formula) != atoms:
            continue
        automaton = translate(formula)
        for _ in range(4):
            horizon = rng.randint(1, 12)
            trace = random_trace(rng, horizon + 1, atoms)
            word = [sum(1 << i for i, p in enumerate(atoms) if p in letter) for letter in trace]
            env = TaskWrapper(Letters(word, 4), automaton, labels, horizon=horizon)
            env.reset(seed=0)
            done, read = False, 0
            while not done:
                _, _, terminated, truncated, info = env.step(0)
                read, done = read + 1, terminated or truncated
            # success: the value on the letters read (a decided task's verdict agrees with it)
            expected = evaluate_finite(formula, trace[:read])[0]
            assert info["success"] == expected, (to_text(formula), trace[:read])
            if checked < RTAMT_CHECKS:  # and rtamt's, directly, on the first of them
                spec = _parse_rtamt(_to_rtamt(formula))
                assert (_rtamt_robustness(spec, trace[:read])[0] > 0) == info["success"]
            if truncated:
                assert read == horizon and info["verdict"] == "pending"
            checked += 1


def test_a_next_step_obligation_on_a_letter_never_read() -> None:
    """No departure from LTLf's ends (issue 42): ``X a`` and ``F[2,2] a`` still open at the end
    fail (strong), ``G[2,2] a`` and ``!X !a`` hold (weak, as rtamt reads the window)."""
    labels = {"a": {"obs": [1]}}
    for text, expected in (("X a", False), ("F[2,2] a", False), ("G[2,2] a", True),
                           ("!X !a", True)):  # fmt: skip
        env = TaskWrapper(Letters([1, 1, 1], 2), translate(parse(text)), labels, horizon=1)
        env.reset(seed=0)
        _, _, terminated, truncated, info = env.step(0)
        assert truncated and not terminated and info["success"] == expected, text


def test_the_temporal_depth_is_the_oracles_and_decides_the_formula() -> None:
    rng = random.Random(5)
    for _ in range(300):
        formula = random_formula(rng, rng.randint(1, 4), ["a", "b"], rng.random() < 0.7, 4)
        depth = temporal_depth(formula)
        assert depth == depth_oracle(formula)
        if depth is None:
            assert decision_steps(formula) is None
            continue
        prefix = random_trace(rng, depth + 1, ["a", "b"])
        value = evaluate_finite(formula, prefix)[0]
        for _ in range(3):  # every extension of the decided prefix agrees
            longer = prefix + random_trace(rng, rng.randint(1, 5), ["a", "b"])
            assert evaluate_finite(formula, longer)[0] == value, to_text(formula)


# -- the cases of the issue, one by one ------------------------------------------------------------


CLIFF = {"goal": {"obs": [47]}}


def test_a_deadline_still_open_at_the_horizon_fails_in_check_and_in_the_wrapper(
    tmp_path: Any,
) -> None:
    """CliffWalking (the goal 13 steps away), ``F[0,30] goal`` within 10 steps: 0, not 1."""
    from typer.testing import CliRunner

    from mitlc.cli import app

    world = tmp_path / "cliff.yaml"
    world.write_text(
        "env: {id: CliffWalking-v1}\nlabels: {goal: {obs: [47]}}\n"
        "spec: {formula: 'F[0,30] goal'}\nhorizon: 10\n"
    )
    out = CliRunner().invoke(app, ["check", str(world), "--json"])
    assert out.exit_code == 0, out.output
    assert '"pmax_horizon": 0.0' in out.stdout
    assert "horizon (10 steps) is shorter than the 31 steps" in out.stderr
    env = TaskWrapper(gym.make("CliffWalking-v1"), "F[0,100] goal", CLIFF, horizon=10)
    env.reset(seed=0)
    for _ in range(10):  # up, into the wall: turning on the spot
        _, _, terminated, truncated, info = env.step(0)
    assert truncated and not terminated
    assert (info["verdict"], info["success"], info["is_success"]) == ("pending", False, False)


class Duration(gym.Env[int, int]):
    """An env that ends its own episodes after ``duration`` steps (truncated), as highway-env
    does, with ``info["crashed"]`` never set."""

    def __init__(self, duration: int = 30) -> None:
        self.duration = duration
        self.observation_space = spaces.Discrete(2)
        self.action_space = spaces.Discrete(2)
        self.t = 0

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[int, dict[str, Any]]:
        super().reset(seed=seed)
        self.t = 0
        return 0, {"crashed": False}

    def step(self, action: int) -> tuple[int, float, bool, bool, dict[str, Any]]:
        self.t += 1
        return int(action), 0.0, False, self.t >= self.duration, {"crashed": False}


@pytest.mark.parametrize(
    ("spec", "horizon", "verdict", "success"),
    [
        ("G[0,100] !crashed", 101, "satisfied", True),  # the window closes at step 101
        ("F[0,100] arrived", 101, "violated", False),
        ("G[0,100] !crashed", 60, "pending", True),  # still open at the horizon: holds
        ("F[0,100] arrived", 60, "pending", False),  # still open at the horizon: fails
    ],
)
def test_an_env_that_ends_itself_ends_the_world_not_the_task(
    spec: str, horizon: int, verdict: str, success: bool
) -> None:
    labels = {"crashed": {"info": "crashed"}, "arrived": {"obs": [1]}}
    env = TaskWrapper(Duration(), spec, labels, horizon=horizon)
    env.reset(seed=0)
    with pytest.warns(EpisodeCutWarning, match="truncated its episode at step 30"):
        for t in range(30):
            _, _, terminated, truncated, info = env.step(0)
            assert info["env_ended"] == (t == 29)
    # no jumps: the rest of the episode is read within the step that ended the env
    assert info["step"] == horizon
    assert (terminated, truncated) == (verdict != "pending", verdict == "pending")
    assert (info["verdict"], info["success"]) == (verdict, success)


def test_an_outer_time_limit_judges_the_cut_episode_by_the_same_rule() -> None:
    env = gym.make(
        "mitlc/Task-v0",
        env_id="CliffWalking-v1",
        spec="F[0,100] goal",
        labels=CLIFF,
        horizon=200,
        max_episode_steps=10,
    )
    env.reset(seed=0)
    for _ in range(10):
        _, _, terminated, truncated, info = env.step(0)
    assert truncated and not terminated and not info["success"]


LAKE = {"goal": {"obs": [15]}, "hole": {"obs": [5, 7, 11, 12]}}
TO_GOAL = [2, 2, 1, 1, 1, 2]  # right, right, down, down, down, right: 0 1 2 6 10 14 15


def _lake_world(formula: str, horizon: int) -> tuple[Any, DigitalAutomaton, World, Product]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        inner = gym.make("FrozenLake-v1", is_slippery=False)
    file = EnvWorldFile.model_validate(
        {"env": {"id": "FrozenLake-v1"}, "labels": LAKE, "spec": {"formula": formula},
         "horizon": horizon}
    )  # fmt: skip
    automaton = translate(parse(formula))
    world = build_world(
        file, inner, name="lake", spec=formula, spec_source="<t>",
        propositions=automaton.propositions,
    )  # fmt: skip
    return inner, automaton, world, build_product(world, automaton)


def test_persistence_after_the_env_ends_can_take_its_jump() -> None:
    """FrozenLake, ``F G goal``, 20 steps: walk to the goal, jump into the accepting part, and
    step on: success, as the product's optimum (1.0) says."""
    inner, automaton, _, product = _lake_world("F G goal", 20)
    assert pmax_horizon(product, 20)[0] == 1.0
    env = TaskWrapper(inner, automaton, LAKE, horizon=20)
    env.reset(seed=0)
    for action in TO_GOAL:
        _, _, terminated, truncated, info = env.step(action)
    assert info["env_ended"] and not (terminated or truncated)
    jumps = np.flatnonzero(env.action_masks())[4:]
    assert len(jumps) >= 1
    env.step(int(jumps[0]))
    while not (terminated or truncated):
        _, _, terminated, truncated, info = env.step(0)
    assert info["success"] and info["rounds"] > 0


def test_a_safety_task_pending_at_the_horizon_is_truncated_on_every_path() -> None:
    """FrozenLake, ``G !hole``, 10 steps, walking to the goal: truncated and a success in the
    wrapper and in the product's simulator alike."""
    inner, automaton, world, product = _lake_world("G !hole", 10)
    env = TaskWrapper(inner, automaton, LAKE, horizon=10, env_end="step")
    env.reset(seed=0)
    results = [env.step(a) for a in TO_GOAL]
    while not (results[-1][2] or results[-1][3]):
        results.append(env.step(0))
    assert len(results) == 10 and results[-1][3] and not results[-1][2]
    assert results[-1][4]["success"] and results[-1][4]["step"] == 10
    path = dict(zip([0, 1, 2, 6, 10, 14], TO_GOAL, strict=True))
    policy = np.zeros((1, product.num_states), dtype=np.int64)
    for x, s in enumerate(product.world_state.tolist()):
        policy[0, x] = path.get(s, 0) if s >= 0 else -1
    (in_sim,) = simulator_episodes(world, product, policy, 1, 0)
    in_env = [(r, i["verdict"], te, tr, i["success"]) for _, r, te, tr, i in results]
    assert in_sim == in_env


class Located(gym.Env[int, int]):
    """A two-cell env whose ``info`` carries its position as an array, as a plane world's."""

    def __init__(self) -> None:
        self.observation_space = spaces.Discrete(2)
        self.action_space = spaces.Discrete(2)
        self.cell = 0

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[int, dict[str, Any]]:
        super().reset(seed=seed)
        self.cell = 0
        return 0, self._info()

    def step(self, action: int) -> tuple[int, float, bool, bool, dict[str, Any]]:
        self.cell = int(action)
        return self.cell, 0.0, False, False, self._info()

    def _info(self) -> dict[str, Any]:
        return {"position": np.array([0.5 + self.cell, 2.0]), "cell": self.cell, "raw": object()}


def test_a_resumed_wrapper_keeps_the_envs_last_info(tmp_path: Any) -> None:
    """After ``load_state_dict`` (through a data-only checkpoint) an invalid jump's ``info``
    still has the env's last entries; what a checkpoint cannot hold is left out."""
    from mitlc.learn.rundir import checkpoint

    labels = {"a": {"obs": [1]}}
    env = TaskWrapper(Located(), "F G a", labels, horizon=10)
    env.reset(seed=0)
    env.step(1)
    env.step(2)  # the first jump, into the accepting part, which has none
    checkpoint.save(tmp_path, 1, {"env": env.state_dict()})
    fresh = TaskWrapper(Located(), "F G a", labels, horizon=10)
    fresh.reset(seed=0)
    fresh.load_state_dict(checkpoint.load(tmp_path).state["env"])
    invalid = int(np.flatnonzero(~fresh.action_masks())[0])
    _, _, _, _, info = fresh.step(invalid)
    assert info["invalid_action"] and info["cell"] == 1 and "raw" not in info
    assert np.array_equal(info["position"], [1.5, 2.0])
