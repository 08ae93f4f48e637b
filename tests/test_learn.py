"""Learning: settings, the vectorised simulator against exact values, the exact value of a
memoryless policy, tabular Q-learning, runs (checkpoints, resume) and evaluation."""

from __future__ import annotations

import json
import random
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from mitlc.automata import translate
from mitlc.check.solve import pmax_horizon
from mitlc.learn.config import ConfigError, Discount, resolve
from mitlc.learn.envs.vec import Step, VecProduct, tables
from mitlc.learn.evaluation.evaluate import evaluate
from mitlc.learn.evaluation.exact import policy_success
from mitlc.learn.evaluation.montecarlo import monte_carlo, wilson
from mitlc.learn.learners.base import product_potential, step_discounts
from mitlc.learn.learners.qlearning import QLearner, TabularPolicy
from mitlc.learn.run import RunError, load_learner, prepare, train
from mitlc.learn.setting import batches
from mitlc.product.explicit import Product, build_product
from mitlc.syntax import parse, to_text
from mitlc.task.potential import automaton_distance
from mitlc.worlds import Sparse, load_world
from mitlc.worlds.model import IntArray
from tests.conftest import ROOT
from tests.test_check import formulas, random_world

CASE1 = ROOT / "specs" / "paper" / "case1.yaml"
Q_SMALL = {"episodes": 4000, "q": {"num_envs": 64}, "log_every": 500, "checkpoint_every": 1000}


def config(training: dict[str, object] | None = None, **overrides: object):  # type: ignore[no-untyped-def]
    return resolve(training or {}, overrides, discount=0.99, pomdp=False)


# -- settings ----------------------------------------------------------------------------------


def test_defaults_follow_the_algorithm_and_the_world() -> None:
    q = resolve({}, {}, discount=0.9, pomdp=False)
    assert q.algo == "q" and q.discount.gamma == 0.9 and q.episodes == 300_000
    assert q.log_every == 3_000 and q.checkpoint_every == 30_000
    drqn = resolve({}, {"episodes": "500"}, discount=0.99, pomdp=True)
    assert drqn.algo == "drqn" and drqn.episodes == 500 and drqn.log_every == 5


def test_world_settings_then_overrides() -> None:
    c = resolve({"q": {"alpha": 0.3}, "seed": 4}, {"q.alpha": "0.25"}, discount=0.99, pomdp=False)
    assert c.q.alpha == 0.25 and c.seed == 4 and c.q.epsilon_end == 0.1


def test_a_learner_section_budget_wins_when_that_learner_runs() -> None:
    training = {"algo": "q", "episodes": 300_000, "dqn": {"episodes": 4_000, "lr": 0.01}}
    assert resolve(training, {}, discount=0.99, pomdp=False).episodes == 300_000
    dqn = resolve(training, {"algo": "dqn"}, discount=0.99, pomdp=False)
    assert dqn.episodes == 4_000 and dqn.dqn.lr == 0.01 and dqn.log_every == 40
    given = resolve(training, {"algo": "dqn", "episodes": "700"}, discount=0.99, pomdp=False)
    assert given.episodes == 700


@pytest.mark.parametrize(
    ("training", "overrides", "message"),
    [
        ({"q": {"alpah": 1}}, {}, r"training\.q\.alpah: unknown setting \(expected one of"),
        ({"algo": "ppo"}, {}, r"training\.algo: expected one of q, dqn, drqn, sb3-ppo, .*'ppo'"),
        ({}, {"q.alpha": "fast"}, r"training\.q\.alpha: expected a number, got 'fast'"),
        ({}, {"seed": "1.5"}, r"training\.seed: expected an integer, got '1.5'"),
        ({"discount": {"gamma": 1.5}}, {}, r"training\.discount\.gamma: expected a value in"),
        ({"episodes": 0}, {}, r"training\.episodes: expected a positive value, got 0"),
        ({"q": 3}, {}, r"training\.q: expected a mapping, got 3"),
        ({"dqn": {"episodes": -2}}, {}, r"training\.dqn\.episodes: expected a positive value"),
        ({"q": {"episodes": "x"}}, {}, r"training\.q\.episodes: expected a number, got 'x'"),
        ({}, {"dqn.double": "maybe"}, r"training\.dqn\.double: expected true or false"),
    ],
)
def test_bad_settings_name_their_path(
    training: dict[str, object], overrides: dict[str, object], message: str
) -> None:
    with pytest.raises(ConfigError, match=message):
        resolve(training, overrides, discount=0.99, pomdp=False)


# -- the simulator and the exact value of a policy --------------------------------------------


def restrict(product: Product, chosen: IntArray) -> Product:
    """The product with one choice per state: ``chosen[x]``."""
    t = product.transitions
    counts = t.indptr[chosen + 1] - t.indptr[chosen]
    index = np.concatenate([np.arange(t.indptr[c], t.indptr[c + 1]) for c in chosen.tolist()])
    return replace(
        product,
        choice_ptr=np.arange(product.num_states + 1),
        action=product.action[chosen],
        marks=product.marks[chosen],
        transitions=Sparse(
            np.concatenate([[0], np.cumsum(counts)]), t.targets[index], t.probs[index]
        ),
    )


def random_policy(product: Product, rng: np.random.Generator, jumps: bool = True) -> IntArray:
    """A random choice of each state (the absorbing states keep their one choice); with
    ``jumps`` off, a world action."""
    low, high = product.choice_ptr[:-1], product.choice_ptr[1:]
    if not jumps:
        owner = np.repeat(np.arange(product.num_states), np.diff(product.choice_ptr))
        high = np.bincount(owner[product.action >= 0], minlength=product.num_states) + low
    chosen: IntArray = low + (rng.random(product.num_states) * (high - low)).astype(np.int64)
    return chosen


@pytest.mark.parametrize("seed", range(6))
def test_policy_success_is_the_optimum_of_the_restricted_product(seed: int) -> None:
    """With one choice per state, pmax_horizon (checked against Storm elsewhere) is the
    policy's value: an independent recursion for the same number. (Jumps stay out: a state
    left with a jump only is outside what pmax_horizon takes; the simulator test below covers
    policies that jump.)"""
    rng = random.Random(seed)
    for formula in formulas(seed, 12):
        world = random_world(rng, to_text(formula))
        product = build_product(world, translate(formula))
        chosen = random_policy(product, np.random.default_rng(seed), jumps=False)
        choices = np.tile(
            np.where(product.world_state >= 0, chosen, -1), (1 << product.num_sets, 1)
        )
        expected, _ = pmax_horizon(restrict(product, chosen), world.horizon, keep_history=False)
        assert policy_success(product, choices, world.horizon) == pytest.approx(expected, abs=1e-12)


@pytest.mark.parametrize("spec", ["G F a & G F b", "F G a", "(!a U[2,4] a) & (!b U[3,6] b)"])
def test_simulator_success_matches_the_exact_value(spec: str) -> None:
    """20,000 episodes of a random memoryless policy in the simulator, measured by the one
    Monte-Carlo estimate (:func:`mitlc.learn.evaluation.montecarlo.monte_carlo`), succeed as often
    as its
    exact value says: within 4.5 standard errors, and inside the estimate's 95% Wilson
    interval (deterministic: the seeds are fixed)."""
    world = random_world(random.Random(7), spec)
    world = replace(world, horizon=10)
    product = build_product(world, translate(parse(spec)))
    chosen = random_policy(product, np.random.default_rng(3))
    choices = np.tile(np.where(product.world_state >= 0, chosen, -1), (1 << product.num_sets, 1))
    exact = policy_success(product, choices, world.horizon)
    t = tables(product, world)
    action_of = np.zeros(product.num_choices, dtype=np.int64)
    for x in range(product.num_states):
        for a in np.flatnonzero(t.valid[x]).tolist():
            action_of[t.choice[x, a]] = a

    class Fixed(TabularPolicy):
        def act(self, env: VecProduct) -> IntArray:
            picked: IntArray = action_of[chosen[env.state]]
            return picked

    n = 20_000
    setting = replace(prepare(CASE1, config()), tables=t)
    estimate = monte_carlo(batches(setting, 11), Fixed(t, np.zeros((1, 1, 1))), n)
    error = max(np.sqrt(exact * (1 - exact) / n), 1e-3)
    assert estimate.trials == n and abs(estimate.rate - exact) < 4.5 * error, (estimate, exact)
    low, high = estimate.interval
    assert low <= exact <= high, (estimate, exact)


def test_simulator_rewards_pay_each_set_once_a_round() -> None:
    world = random_world(random.Random(3), "G F a & G F b")
    product = build_product(world, translate(parse("G F a & G F b")))
    t = tables(product, world)
    env = VecProduct(t, 200, np.random.default_rng(0))
    rng = np.random.default_rng(1)
    for _ in range(40):
        before, state = env.mask.copy(), env.state.copy()
        actions = (rng.random(t.valid[state].shape) * t.valid[state]).argmax(axis=1)
        step = env.step(actions)
        marks = t.marks[t.choice[state, actions]]
        new = marks & ~before
        paid = np.array([bin(m).count("1") for m in new.tolist()])
        assert step.reward.tolist() == (world.rewards.accept * paid).tolist()
        seen = before | marks
        assert step.next_mask.tolist() == np.where(seen == 3, 0, seen).tolist()
        assert (step.accepting == (paid > 0)).all()


def test_invalid_actions_are_refused() -> None:
    world = random_world(random.Random(1), "F G a")
    t = tables(build_product(world, translate(parse("F G a"))), world)
    env = VecProduct(t, 1, np.random.default_rng(0))
    x, a = np.argwhere(~t.valid[2:])[0]
    env.state = np.array([x + 2])
    with pytest.raises(ValueError, match="not valid"):
        env.step(np.array([a]))
    with pytest.raises(ValueError, match="not valid"):
        env.step(np.array([t.num_actions]))


# -- rewards, discounts, shaping ---------------------------------------------------------------


def test_accepting_discount_applies_on_accepting_steps_only() -> None:
    step = Step(
        reward=np.array([100.0, 0.0]),
        accepting=np.array([True, False]),
        terminated=np.array([False, False]),
        truncated=np.array([False, False]),
        next_state=np.array([2, 3]),
        next_mask=np.array([0, 0]),
        next_observation=np.array([0, 0]),
        success=np.array([False, False]),
        episode_return=np.zeros(2),
        episode_steps=np.zeros(2, dtype=np.int64),
        next_automaton=np.array([1, 1]),
        next_valid=np.ones((2, 5), dtype=np.bool_),
    )
    both = step_discounts(step.accepting, Discount(mode="accepting", gamma=0.999, gamma_accept=0.9))
    assert both.tolist() == [0.9, 0.999]
    assert step_discounts(step.accepting, Discount(gamma=0.95)).tolist() == [0.95, 0.95]


def test_distance_to_acceptance() -> None:
    automaton = translate(parse("(!a U[2,3] a)"))
    distance = automaton_distance(automaton)
    assert distance[automaton.initial] == 3.0  # two letters of waiting, then a: satisfied
    satisfied = [q for q, s in enumerate(automaton.states) if s.verdict == "satisfied"]
    violated = [q for q, s in enumerate(automaton.states) if s.verdict == "violated"]
    assert all(distance[q] == 0 for q in satisfied)
    assert all(distance[q] == distance.max() for q in violated)
    world = random_world(random.Random(2), "(!a U[2,3] a)")
    product = build_product(world, automaton)
    phi = product_potential(tables(product, world), world, automaton, 2.0)
    assert phi[0] == phi[1] == 0.0
    # C (the largest d, a violated state's 4, plus the weights 0.5 and 0.25) less three letters
    # from acceptance, less at most half a step for the world's distance to a, nothing yet of
    # the deadline spent; scaled by 2
    c = 4.0 + 0.5 + 0.25
    assert 2 * (c - 3.0 - 0.5) <= phi[product.initial] <= 2 * (c - 3.0)


# -- tabular Q-learning, runs, evaluation ------------------------------------------------------


def test_q_learning_reaches_the_optimum_on_case1() -> None:
    """60,000 episodes (about a second): the greedy policy's exact success is within 2% of
    the optimum (a learner that learned nothing scores 0.64)."""
    setting = prepare(CASE1, config({"episodes": 60_000}))
    rng = np.random.default_rng(0)
    learner = QLearner(setting.tables, setting.config, rng)
    env = VecProduct(setting.tables, learner.num_envs, np.random.default_rng(1))
    episodes = 0
    while episodes < 60_000:
        episodes += int(learner.train_step(env, episodes / 60_000).done.sum())
    exact = policy_success(setting.product, learner.policy().choices(), 30)
    optimum, _ = pmax_horizon(setting.product, 30, keep_history=False)
    assert exact >= 0.98 * optimum


def lines(path: Path) -> list[dict[str, object]]:
    out = []
    for line in path.read_text().splitlines():
        data = json.loads(line)
        del data["seconds"]
        out.append(data)
    return out


def test_resume_reaches_what_an_uninterrupted_run_reaches(tmp_path: Path) -> None:
    settings = config(Q_SMALL)
    straight = train(CASE1, settings, tmp_path / "straight")
    calls = iter(range(10_000))
    stopped = train(CASE1, settings, tmp_path / "split", should_stop=lambda: next(calls) == 20)
    assert stopped.stopped and 0 < stopped.episodes < 4000
    assert not (tmp_path / "split" / "summary.json").exists()
    resumed = train(CASE1, settings, tmp_path / "split", resume=True)
    assert not resumed.stopped and resumed.episodes == straight.episodes
    assert lines(tmp_path / "split" / "metrics.jsonl") == lines(
        tmp_path / "straight" / "metrics.jsonl"
    )
    a = evaluate(tmp_path / "straight", episodes=500)
    b = evaluate(tmp_path / "split", episodes=500)
    assert a.successes == b.successes and a.exact == b.exact


def test_same_seed_same_run_other_seed_other_run(tmp_path: Path) -> None:
    runs = [
        train(CASE1, config(Q_SMALL, seed=s), tmp_path / str(i)) for i, s in enumerate([1, 1, 2])
    ]
    metrics = [lines(r.directory / "metrics.jsonl") for r in runs]
    assert metrics[0] == metrics[1] != metrics[2]


def test_run_directories_are_protected(tmp_path: Path) -> None:
    train(CASE1, config(Q_SMALL), tmp_path / "run")
    with pytest.raises(RunError, match="a run is already there"):
        train(CASE1, config(Q_SMALL), tmp_path / "run")
    with pytest.raises(RunError, match="only --episodes may change"):
        train(CASE1, config(Q_SMALL, seed=9), tmp_path / "run", resume=True)
    with pytest.raises(RunError, match=r"no config\.json"):
        evaluate(tmp_path / "nothing")
    more = train(CASE1, config({**Q_SMALL, "episodes": 6000}), tmp_path / "run", resume=True)
    assert more.episodes >= 6000


def test_episodes_on_resume_is_the_runs_total(tmp_path: Path) -> None:
    """A resumed run ends at the first step with at least ``episodes`` ended: between N and
    N + num_envs - 1; asking for no more than the checkpoint has is refused."""
    calls = iter(range(10_000))
    stopped = train(CASE1, config(Q_SMALL), tmp_path / "run", should_stop=lambda: next(calls) == 20)
    assert 0 < stopped.episodes < 4000
    with pytest.raises(
        RunError, match=f"already has {stopped.episodes:,} episodes.*the run's total"
    ):
        train(CASE1, config(Q_SMALL, episodes=stopped.episodes), tmp_path / "run", resume=True)
    for total in (stopped.episodes + 1, 2400, 5000):
        result = train(CASE1, config(Q_SMALL, episodes=total), tmp_path / "run", resume=True)
        assert total <= result.episodes < total + 64
        assert lines(tmp_path / "run" / "metrics.jsonl")[-1]["episodes"] == result.episodes
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["episodes"] == result.episodes


def test_resume_drops_metrics_written_after_the_checkpoint(tmp_path: Path) -> None:
    settings = config(Q_SMALL)
    train(CASE1, settings, tmp_path / "straight")
    calls = iter(range(10_000))
    train(CASE1, settings, tmp_path / "run", should_stop=lambda: next(calls) == 20)
    metrics = tmp_path / "run" / "metrics.jsonl"
    metrics.write_text(metrics.read_text() + '{"episodes": 99999, "succ')  # killed mid-line
    train(CASE1, settings, tmp_path / "run", resume=True)
    assert lines(metrics) == lines(tmp_path / "straight" / "metrics.jsonl")


def test_wilson_interval() -> None:
    low, high = wilson(5, 10)
    assert (round(low, 4), round(high, 4)) == (0.2366, 0.7634)
    assert wilson(0, 10)[0] == 0.0 and wilson(10, 10)[1] == pytest.approx(1.0)
    assert round(wilson(0, 10)[1], 4) == 0.2775
    assert wilson(0, 0) == (0.0, 1.0)


def test_measured_success_matches_the_policys_exact_value(tmp_path: Path) -> None:
    """The greedy policy's Monte-Carlo success over 20,000 episodes agrees with its exact
    value (the Markov chain it induces) within 4.5 standard errors."""
    train(CASE1, config({**Q_SMALL, "episodes": 20_000}), tmp_path / "run")
    report = evaluate(tmp_path / "run", episodes=20_000)
    assert report.exact is not None and 0.3 < report.exact < 1.0
    error = np.sqrt(report.exact * (1 - report.exact) / 20_000)
    assert abs(report.success_rate - report.exact) < 4.5 * error
    assert report.optimum == pytest.approx(0.974021, abs=1e-6)


def test_learners_of_the_true_cell_refuse_a_pomdp(tmp_path: Path) -> None:
    case2 = ROOT / "specs" / "paper" / "case2.yaml"
    with pytest.raises(RunError, match=r"dqn learns on the true cell.*use drqn or q"):
        train(case2, config(Q_SMALL, algo="dqn"), tmp_path / "dqn")
    with pytest.raises(RunError, match=r"q\.crm on a POMDP"):
        train(case2, config({**Q_SMALL, "q": {"crm": True}}, algo="q"), tmp_path / "crm")


class Blindfolded:
    """Episodes whose true state a policy may not read (what a POMDP's agent sees)."""

    def __init__(self, env: VecProduct) -> None:
        self.env, self.num_envs = env, env.num_envs

    def __getattr__(self, name: str) -> object:
        if name == "state":
            raise AssertionError("the policy read the true state")
        return getattr(self.env, name)


def test_q_on_a_pomdp_learns_on_what_the_agent_sees(tmp_path: Path) -> None:
    """Tabular Q on case 2 (a noisy POMDP) reads the observation and the automaton state, never
    the cell, and comes within 10% of the exact observation-based lower bound."""
    case2 = ROOT / "specs" / "paper" / "case2.yaml"
    run = tmp_path / "q"
    train(case2, config({"episodes": 150_000, "seed": 3}, algo="q"), run)
    report = evaluate(run, episodes=4_000)
    assert report.pomdp and report.lower is not None and report.exact is None
    assert report.success_rate >= 0.9 * report.lower
    setting, learner = load_learner(run)
    product = setting.model()
    env = VecProduct(product[2], 64, np.random.default_rng(0))
    policy = learner.policy()
    for _ in range(30):
        env.step(policy.act(Blindfolded(env)))


CORRIDOR = """
name: corridor
grid: {rows: 1, cols: 3}
labels: {a: [[0, 1]], b: [[0, 2]]}
start: [0, 0]
actions: [right, stay]
motion: {intended: 1.0, sideways: 0.0}
spec: {formula: "G F a & G !b"}
reward: {satisfied: 1, accept: 1, violated: 0, move: 0}
horizon: 10
discount: 0.9
"""


@pytest.mark.parametrize(("stay_at_a", "expected"), [(False, 0.0), (True, 1.0)])
def test_a_violation_after_a_completed_round_is_a_failure(
    tmp_path: Path, stay_at_a: bool, expected: float
) -> None:
    """The corridor start, a, b with `G F a & G !b`: "always right" completes a round at `a`,
    then reaches `b` (violated) within the horizon: a failure for the exact evaluation, the
    optimum of the restricted product and the simulator alike (the exact evaluation said 1.0).
    Staying at `a` succeeds in all three."""
    path = tmp_path / "corridor.yaml"
    path.write_text(CORRIDOR)
    world = load_world(path)
    product = build_product(world, translate(parse(world.spec)))
    t = tables(product, world)
    right, stay = 0, 1
    at_a = product.world_state == 1
    action = np.where(at_a & stay_at_a, stay, right)  # per product state
    chosen = np.array(
        [
            t.choice[x, action[x]] if product.world_state[x] >= 0 else product.choice_ptr[x]
            for x in range(product.num_states)
        ]
    )
    choices = np.tile(np.where(product.world_state >= 0, chosen, -1), (1 << product.num_sets, 1))
    assert product.num_sets == 1
    assert policy_success(product, choices, world.horizon) == expected
    assert pmax_horizon(restrict(product, chosen), world.horizon, keep_history=False)[0] == expected
    env = VecProduct(t, 64, np.random.default_rng(0))
    ended = succeeded = 0
    while ended < 256:
        step = env.step(np.where(t.world_state[env.state] >= 0, action[env.state], 0))
        ended += int(step.done.sum())
        succeeded += int(step.success[step.done].sum())
    assert succeeded / ended == expected
