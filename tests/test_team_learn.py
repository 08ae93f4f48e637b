"""Teams learning (issue 43, item 5): independent tabular learners and a shared DQN on a team
world's joint product, reported beside the exact joint optimum; the learned decentralised
policy's exact success agrees with the product's simulator and with the PettingZoo task wrapper
over the team's env; the per-robot shield with theta = 1 makes every learned policy optimal."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner

from mitlc.check.solve import pmax_horizon
from mitlc.cli import app
from mitlc.learn.envs.vec import VecProduct
from mitlc.learn.evaluation.exact import policy_success
from mitlc.learn.learners.team import TeamPolicy
from mitlc.learn.run import load_learner
from mitlc.worlds.team_env import team_task
from tests.conftest import ROOT

runner = CliRunner()

TEAM = """
grid: {rows: 3, cols: 3}
labels: {a: [[0, 2]], b: [[2, 0]]}
actions: [up, down, left, right, stay]
motion: {intended: 0.9, sideways: 0.05}
robots:
  robot_0: {start: [0, 0]}
  robot_1: {start: [2, 2]}
collisions: {label: collide, block: false}
spec: {formula: "F[0,5] a_robot_0 & F[0,5] b_robot_1 & G[0,5] !collide"}
horizon: 6
"""
QUICK = ["--quiet", "--no-eval", "--set", "q.num_envs=256"]


def team_file(tmp_path: Path) -> Path:
    path = tmp_path / "team.yaml"
    path.write_text(TEAM)
    return path


def train(world: Path, out: Path, *args: str) -> None:
    result = runner.invoke(app, ["train", str(world), "--out", str(out), *args])
    assert result.exit_code == 0, result.output


def simulated(policy: TeamPolicy, tables: Any, episodes: int, seed: int) -> float:
    """The policy's success over ``episodes`` episodes of the product's simulator."""
    env = VecProduct(tables, episodes, np.random.default_rng(seed))
    done = np.zeros(episodes, dtype=np.bool_)
    wins = np.zeros(episodes, dtype=np.bool_)
    while not done.all():
        step = env.step(policy.act(env))
        ended = step.done & ~done
        wins |= ended & step.success
        done |= step.done
    return float(wins.mean())


def wrapped(policy: TeamPolicy, setting: Any, episodes: int, seed: int) -> float:
    """The policy's team success over ``episodes`` episodes of the PettingZoo task wrapper
    over the team's env, each robot acting on its own observation and the team task's state."""
    world = setting.model()[0]
    env = team_task(world, setting.automaton)
    robots = world.team.robots
    wins = 0
    for episode in range(episodes):
        obs, infos = env.reset(seed=seed + episode)
        while env.agents:
            own = np.array([[obs[r]["env"] for r in robots]])
            automaton = np.array([obs[robots[0]]["team"]["automaton"]])
            mask = np.array([obs[robots[0]]["team"]["frontier"]])
            valid = np.ones((1, world.num_actions), dtype=np.bool_)
            parts = policy.parts(own, automaton, mask, valid)[0]
            obs, _, _, _, infos = env.step({r: int(parts[i]) for i, r in enumerate(robots)})
        wins += bool(infos[robots[0]]["team_success"])
    return wins / episodes


def test_independent_learners_agree_across_simulator_wrapper_and_exact(tmp_path: Path) -> None:
    out = tmp_path / "run"
    train(team_file(tmp_path), out, "--set", "team=independent", "--episodes", "20000", *QUICK)
    setting, learner = load_learner(out)
    world, product, tables = setting.model()
    policy = learner.policy()
    assert isinstance(policy, TeamPolicy)
    exact = policy_success(product, policy.choices(), world.horizon)
    optimum = pmax_horizon(product, world.horizon)[0]
    assert exact >= 0.9 * optimum  # the decentralised learners learn the team task
    n = 20_000
    sim = simulated(policy, tables, n, seed=3)
    assert abs(sim - exact) <= 4 * math.sqrt(exact * (1 - exact) / n) + 1e-3
    m = 400
    wrap = wrapped(policy, setting, m, seed=11)
    assert abs(wrap - exact) <= 4 * math.sqrt(max(exact * (1 - exact), 0.01) / m)


def test_the_per_robot_shield_with_theta_one_makes_every_learned_policy_optimal(
    tmp_path: Path,
) -> None:
    out = tmp_path / "run"
    train(team_file(tmp_path), out, "--set", "team=independent", "--episodes", "2000",
          "--shield", "1", *QUICK)  # fmt: skip
    setting, _ = load_learner(out)
    assert setting.model()[2].shield is not None
    summary = json.loads((out / "summary.json").read_text())
    assert summary["shield"]["guaranteed_success"] == pytest.approx(
        summary["shield"]["optimum"], abs=1e-9
    )
    rows = [json.loads(line) for line in (out / "metrics.jsonl").read_text().splitlines()]
    assert rows and all(row["blocked_actions"] == 0 for row in rows)
    assert all(row["preventable_violations"] == 0 for row in rows)
    report = runner.invoke(app, ["eval", str(out), "--episodes", "2000", "--json"])
    assert report.exit_code == 0, report.output
    figures = json.loads(report.output)
    assert figures["exact"] == pytest.approx(figures["optimum"], abs=1e-9)


def test_a_shared_dqn_learns_evaluates_and_resumes(tmp_path: Path) -> None:
    world, out = team_file(tmp_path), tmp_path / "run"
    budget = ["--algo", "dqn", "--set", "team=shared", "--quiet", "--no-eval"]
    train(world, out, "--episodes", "3000", *budget)
    report = runner.invoke(app, ["eval", str(out), "--episodes", "500", "--json"])
    assert report.exit_code == 0, report.output
    figures = json.loads(report.output)
    assert figures["exact"] is not None and figures["exact"] >= 0.5 * figures["optimum"]
    train(world, out, "--episodes", "3200", "--resume", *budget)
    resumed = json.loads((out / "summary.json").read_text())
    assert resumed["episodes"] >= 3200


@pytest.mark.parametrize(
    ("world", "args", "message"),
    [
        (ROOT / "specs" / "paper" / "case1.yaml", ["--set", "team=independent"], "one agent"),
        (None, ["--set", "team=shared"], "learns with algo dqn"),
        (None, ["--set", "team=independent", "--algo", "dqn"], "learns with algo q"),
    ],
)
def test_decentralised_settings_that_cannot_learn_are_clear_errors(
    tmp_path: Path, world: Path | None, args: list[str], message: str
) -> None:
    path = world if world is not None else team_file(tmp_path)
    result = runner.invoke(app, ["train", str(path), "--out", str(tmp_path / "r"), *args,
                                 "--episodes", "10", "--quiet"])  # fmt: skip
    assert result.exit_code == 1
    assert message in result.output and "Traceback" not in result.output


def test_the_shipped_team_world_under_its_task_keeps_pettingzoos_conventions() -> None:
    from pettingzoo.test import parallel_api_test, parallel_seed_test

    from mitlc.worlds.door import load_world

    world = load_world(ROOT / "specs" / "teams" / "two-robots.yaml")
    env = team_task(world)
    parallel_api_test(env, num_cycles=40)
    parallel_seed_test(lambda: team_task(world), num_cycles=40)
    assert env.observation_space("robot_0") is env.observation_space("robot_0")
    _, infos = env.reset(seed=0)
    assert infos["robot_0"]["team_verdict"] == "pending" and not infos["robot_0"]["is_success"]
