"""Shields in training and evaluation: the simulator keeps to them, the run's records show
that no blocked action was taken (and an audit shows what an unshielded run takes), the exact
success of a shielded learned policy keeps the guarantee, and shields are refused where they
do not apply."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from mitlc.automata import translate
from mitlc.check.shield import shield
from mitlc.cli import app
from mitlc.learn.config import ConfigError
from mitlc.learn.envs.vec import VecProduct, tables
from mitlc.learn.evaluation.evaluate import evaluate
from mitlc.learn.learners.base import random_valid
from mitlc.learn.run import train
from mitlc.product.explicit import build_product
from mitlc.syntax import parse
from tests.conftest import ROOT
from tests.test_learn import config
from tests.test_shield import evaluate as exact_value
from tests.test_shield import product_of, uniform

CASE1 = ROOT / "specs" / "paper" / "case1.yaml"


def uniform_shielded_success(env: VecProduct, rng: np.random.Generator) -> np.ndarray:
    """Each slot's first episode's success, every action drawn uniformly among those the
    simulator allows (its shield's); no step may take a blocked action."""
    done = np.zeros(env.num_envs, dtype=np.bool_)
    success = np.zeros(env.num_envs, dtype=np.bool_)
    while not done.all():
        step = env.step(random_valid(rng, env.valid_actions()))
        assert step.blocked is not None and not step.blocked.any()
        first = step.done & ~done
        success[first] = step.success[first]
        done |= step.done
    return success


@pytest.mark.parametrize("seed", [0, 2, 5])
def test_the_uniform_shielded_policy_in_the_simulator_matches_its_exact_value(seed: int) -> None:
    """20,000 episodes of the policy that picks uniformly among the shield's allowed actions
    (the simulator's ``valid_actions``) succeed as often as the evaluator of tests/test_shield
    says, within 4.5 standard errors, and never take a blocked action (the simulator refuses
    them)."""
    world, product = product_of(seed)
    s = shield(product, world.horizon, theta=0.6)
    t = replace(tables(product, world), shield=s)
    env = VecProduct(t, 20_000, np.random.default_rng(seed))
    success = uniform_shielded_success(env, np.random.default_rng(seed + 1))
    exact = exact_value(product, s, uniform, violation=False)
    n = env.num_envs
    error = max(np.sqrt(exact * (1 - exact) / n), 1e-3)
    assert abs(success.mean() - exact) < 4.5 * error, (success.mean(), exact)
    assert exact >= s.success - 1e-9


def test_shielded_training_takes_no_blocked_action_and_an_audit_sees_them(tmp_path: Path) -> None:
    q = {"episodes": 4000, "log_every": 500, "checkpoint_every": 2000}
    shielded = train(CASE1, config(q, shield=1.0), tmp_path / "shielded")
    audited = train(CASE1, config(q, shield=1.0, shield_audit=True), tmp_path / "audited")
    records = {
        name: [json.loads(line) for line in (run.directory / "metrics.jsonl").open()]
        for name, run in (("shielded", shielded), ("audited", audited))
    }
    assert all(r["blocked_actions"] == 0 for r in records["shielded"])
    assert all(r["preventable_violations"] == 0 for r in records["shielded"])
    # the same learner, not kept to the shield, takes blocked actions while it explores
    assert records["audited"][-1]["blocked_actions"] > 0
    last = records["audited"][-1]
    assert 0 < last["preventable_violations"] <= last["violations"]
    summary = json.loads((shielded.directory / "summary.json").read_text())
    assert summary["shield"]["theta"] == 1.0 and summary["blocked_actions"] == 0


def test_eval_reports_the_exact_success_of_the_shielded_policy(tmp_path: Path) -> None:
    """A policy that learned almost nothing (200 episodes) but acts inside a theta = 0.5
    shield keeps half the optimum, exactly; the same Q table unshielded does not."""
    q = {"episodes": 200, "log_every": 100, "checkpoint_every": 200}
    run = train(CASE1, config(q, shield=0.5), tmp_path / "half")
    report = evaluate(run.directory, episodes=2000)
    assert report.exact is not None and report.optimum is not None
    assert report.exact >= 0.5 * report.optimum - 1e-9
    assert abs(report.success_rate - report.exact) < 0.05


@pytest.mark.parametrize(
    ("world", "args", "message"),
    [
        ("paper/case2.yaml", ["--shield", "1", "--algo", "sb3-maskable-ppo"], "POMDP"),
        ("paper/case1.yaml", ["--shield", "1", "--algo", "sb3-ppo"], "sb3-ppo"),
        ("paper/case1.yaml", ["--shield", "1.5"], "training.shield"),
        ("paper/case1.yaml", ["--shield-violation", "-0.1"], "training.shield_violation"),
    ],
)
def test_shields_are_refused_where_they_do_not_apply(
    world: str, args: list[str], message: str, tmp_path: Path
) -> None:
    result = CliRunner().invoke(
        app, ["train", str(ROOT / "specs" / world), "--out", str(tmp_path / "r"), "-q", *args]
    )
    assert result.exit_code == 1, result.output
    assert message in result.output and "Traceback" not in result.output


def test_an_env_world_is_refused_a_shield() -> None:
    from mitlc.learn.setting import prepare

    world = ROOT / "specs" / "continuous" / "case1.yaml"
    with pytest.raises(ConfigError, match="not finite"):
        prepare(world, config(shield=1.0))


def test_a_product_decided_at_the_start_is_shielded_trivially() -> None:
    world, _ = product_of(1)
    world = replace(world, spec="true")
    product = build_product(world, translate(parse("true")))
    s = shield(product, world.horizon, delta=0.0)
    assert s.success == 1.0 and s.violation == 0.0


def test_the_product_env_masks_are_the_shields_and_it_reports_blocked_actions() -> None:
    """The gymnasium product env (what SB3 learns on) masks exactly what the shield allows at
    the episode's product state, steps left and frontier; a valid action it blocks is
    reported in ``info["shield_blocked"]``; gymnasium's check_env accepts the env."""
    from gymnasium.utils.env_checker import check_env

    from mitlc.product.env import ProductEnv
    from mitlc.product.explicit import build_product as build

    blocked_seen = 0
    for seed in (0, 2, 5):
        world, product = product_of(seed)
        automaton = translate(parse(world.spec))
        product = build(world, automaton)
        s = shield(product, world.horizon, theta=0.8)
        env = ProductEnv(world, automaton, shield=s, product=product)
        check_env(env, skip_render_check=True)
        t = tables(product, world)
        pairs = zip(product.world_state, product.automaton_state, strict=True)
        codes = {(int(w), int(q)): x for x, (w, q) in enumerate(pairs)}
        rng = np.random.default_rng(seed)
        env.reset(seed=seed)
        for _ in range(300):
            masks = env.action_masks()
            x = codes.get((env.world_state, env.automaton_state))
            if x is not None and product.world_state[x] >= 0:
                mask = t.all_sets if env.rounds > 0 else env.frontier
                expected = t.valid[x] & s.allowed(
                    np.array(world.horizon - env.steps), np.array(mask), t.choice[x]
                )
                assert (masks[: t.num_actions] == expected[: len(masks)]).all()
            valid = np.flatnonzero(env.masks_of(env.automaton_state))
            action = int(rng.choice(valid))
            _, _, terminated, truncated, info = env.step(action)
            assert info["shield_blocked"] == (not masks[action])
            blocked_seen += info["shield_blocked"]
            if terminated or truncated:
                env.reset()
    assert blocked_seen > 0  # the random walker strays, and is told so


def test_maskable_ppo_keeps_to_the_shield(tmp_path: Path) -> None:
    pytest.importorskip("sb3_contrib")
    result = CliRunner().invoke(
        app,
        ["train", str(CASE1), "--algo", "sb3-maskable-ppo", "--shield", "1", "--set",
         "sb3.steps=1024", "--set", "sb3.n_steps=256", "--out", str(tmp_path / "r"), "-q",
         "--no-eval"],
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    records = [json.loads(line) for line in (tmp_path / "r" / "metrics.jsonl").open()]
    assert records and all(r["blocked_actions"] == 0 for r in records)
    assert all(r["preventable_violations"] == 0 for r in records)
    summary = json.loads((tmp_path / "r" / "summary.json").read_text())  # as mitlc's runs
    assert summary["shield"]["theta"] == 1.0 and summary["blocked_actions"] == 0
