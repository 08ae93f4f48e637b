"""The way the shaping pulls, shown to the policy (the task wrapper's ``guide=True``,
``mitlc.gym.guide.TaskGuide.way``, ``mitlc.labels.distance.form_direction``): its direction on
hand-made regions and around a U-shaped wall, which proposition it points to, its place in the
observation, the errors, gymnasium's checker, and a controller that only follows it doing the
PointMaze Medium task."""

from __future__ import annotations

import json
import warnings
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces
from gymnasium.utils.env_checker import check_env

from mitlc.automata import translate
from mitlc.gym import TaskWrapper
from mitlc.gym.arguments import TaskWrapperError, TaskWrapperTypeError
from mitlc.labels import compile_labels
from mitlc.labels.distance import form_direction
from mitlc.labels.occupancy import Occupancy
from mitlc.syntax import parse
from mitlc.task.potential import task_potential

U_MAZE = [[0, 0, 0], [1, 1, 0], [0, 0, 0]]
"""A U: from the top-left cell the straight line to the bottom-left one crosses the wall."""


class Point(gym.Env[np.ndarray, np.ndarray]):
    """A point in the 3 x 3 square that moves by its action (clipped to 0.3 a step), stopped
    by the U's wall."""

    def __init__(self, start: tuple[float, float] = (0.5, 2.5)) -> None:
        self.observation_space = spaces.Box(0.0, 3.0, (2,), dtype=np.float64)
        self.action_space = spaces.Box(-1.0, 1.0, (2,), dtype=np.float64)
        self.start = np.array(start)
        self.at = self.start.copy()

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        self.at = self.start.copy()
        return self.at.copy(), {}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        moved = np.clip(self.at + 0.3 * np.clip(action, -1, 1), 0.0, 2.999)
        if not (1.0 <= moved[1] < 2.0 and moved[0] < 2.0):  # not inside the wall
            self.at = moved
        return self.at.copy(), 0.0, False, False, {}


LABELS = {
    "a": {"box": {"index": [0, 1], "low": [0.0, 0.0], "high": [1.0, 1.0]}},  # bottom-left
    "b": {"disc": {"index": [0, 1], "center": [2.5, 2.5], "radius": 0.3}},  # top-right
}


def _wrapped(spec: str, **options: Any) -> TaskWrapper:
    options.setdefault("occupancy", Occupancy.from_rows(U_MAZE, 1.0, (0.0, 0.0), refine=4))
    options.setdefault("potential", 0.0)
    return TaskWrapper(Point(), spec, LABELS, horizon=60, **options)


def test_a_straight_direction_points_at_the_region() -> None:
    labels = compile_labels(LABELS)
    disc, box = labels.forms[1][0], labels.forms[0][0]
    way = form_direction(disc, np.array([0.5, 2.5]), {})
    assert way == pytest.approx([1.0, 0.0], abs=1e-6)
    way = form_direction(box, np.array([2.0, 2.0]), {})  # toward the box's corner (1, 1)
    assert way == pytest.approx(-np.ones(2) / np.sqrt(2), abs=1e-6)
    assert form_direction(box, np.array([0.5, 0.5]), {}) == pytest.approx([0.0, 0.0])
    assert form_direction(box, np.array([1.5, 0.5]), {}) == pytest.approx([-1.0, 0.0])


def test_the_way_goes_around_the_wall_not_into_it() -> None:
    env = _wrapped("F a", guide=True)
    obs, _ = env.reset(seed=0)
    assert obs["guide"] == pytest.approx([1.0, 0.0], abs=0.05)  # right, along the top row
    straight = _wrapped("F a", guide=True, occupancy="none")
    obs, _ = straight.reset(seed=0)
    assert obs["guide"] == pytest.approx([0.0, -1.0], abs=1e-6)  # down, into the wall


def test_following_the_way_does_the_task_and_the_straight_line_does_not() -> None:
    for occupancy, done in (("auto", True), ("none", False)):
        options: dict[str, Any] = {} if occupancy == "auto" else {"occupancy": "none"}  # a grid
        env = _wrapped("F[0,40] a", guide=True, **options)
        obs, info = env.reset(seed=0)
        for _ in range(60):
            obs, _, terminated, truncated, info = env.step(obs["guide"])
            if terminated or truncated:
                break
        assert info["success"] is done


def test_the_way_points_to_the_proposition_the_potential_pulls_toward() -> None:
    automaton = translate(parse("F (b & F a)"))  # b first: a does not advance the start
    shaping = task_potential(automaton)
    q0 = automaton.initial
    names = list(automaton.propositions)
    far_b = np.array([1.0 if p == "a" else 5.0 for p in names])  # a nearer, but b is owed
    assert shaping.leading(q0, far_b) == names.index("b")
    env = _wrapped("F (b & F a)", guide=True)
    obs, _ = env.reset(seed=0)
    assert obs["guide"] == pytest.approx([1.0, 0.0], abs=0.05)  # b is to the right
    assert shaping.leading(q0, np.array([np.nan, np.nan])) is None


def test_the_way_is_the_last_part_of_the_flat_observation_and_zero_once_decided() -> None:
    env = _wrapped("F a", guide=True, flatten=True)
    space = env.observation_space
    assert isinstance(space, spaces.Box)
    assert list(space.low[-2:]) == [-1.0, -1.0] and list(space.high[-2:]) == [1.0, 1.0]
    obs, _ = env.reset(seed=0)
    assert obs[-2:] == pytest.approx([1.0, 0.0], abs=0.05)
    plain = _wrapped("F a", flatten=True)
    assert plain.observation_space.shape[0] == space.shape[0] - 2  # type: ignore[index]


def test_check_env_passes_with_the_way() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # "different from the unwrapped version"
        check_env(_wrapped("F[0,40] a & F[0,50] b", guide=True), skip_render_check=True)


def test_errors() -> None:
    with pytest.raises(TaskWrapperError, match="guide: the way points along"):
        _wrapped("F a", guide=True, potential=None)
    with pytest.raises(TaskWrapperTypeError, match="guide: expected True or False"):
        _wrapped("F a", guide="yes")
    obs_labels = {"a": {"obs": [0]}}
    env = gym.make("FrozenLake-v1")
    with pytest.raises(TaskWrapperTypeError, match="no declared label has a region"):
        TaskWrapper(env, "F a", obs_labels, horizon=10, potential=0.0, guide=True)


def test_guide_is_refused_by_learners_that_do_not_read_it(tmp_path: Any) -> None:
    from mitlc.learn.config import ConfigError, TrainConfig
    from mitlc.learn.setting import prepare

    with pytest.raises(ConfigError, match=r"guide .* SB3 backends"):
        prepare("specs/paper/case1.yaml", TrainConfig(algo="dqn", guide=True))


@pytest.mark.parametrize("name", ["pointmaze-medium", "pointmaze-large"])
def test_a_controller_that_follows_the_way_does_the_pointmaze_task(name: str) -> None:
    pytest.importorskip("gymnasium_robotics")
    from mitlc.worlds.door import open_world

    world = open_world(f"specs/envs/{name}.yaml")
    env = world.task_env(translate(parse(world.spec)), potential=0.0, flatten=True, guide=True)
    obs, info = env.reset(seed=0)
    for _ in range(world.horizon):
        obs, _, terminated, truncated, info = env.step(np.clip(2.0 * obs[-2:], -1.0, 1.0))
        if terminated or truncated:
            break
    assert info["success"] is True


@pytest.mark.parametrize("crm", ["false", "true"])
def test_a_run_with_the_way_trains_evaluates_and_resumes(tmp_path: Any, crm: str) -> None:
    pytest.importorskip("gymnasium_robotics")
    pytest.importorskip("stable_baselines3")
    from typer.testing import CliRunner

    from mitlc.cli import app

    out = tmp_path / "run"
    world = "specs/envs/pointmaze-medium.yaml"
    small = ["--set", "sb3.steps=340", "--set", "eval_episodes=2"]
    small += ["--set", "sb3.learning_starts=50", "--set", "sb3.guide_warmup=340"]
    small += ["--set", f"sb3.crm={crm}"]  # the counterfactuals show their own way
    runner = CliRunner()
    result = runner.invoke(app, ["train", world, "--out", str(out), *small])
    assert result.exit_code == 0, result.output
    assert '"guide": true' in (out / "config.json").read_text()
    # acting along the way for all 340 steps: both episodes that ended did the task
    last = json.loads((out / "metrics.jsonl").read_text().splitlines()[-1])
    assert last["episodes"] >= 2 and last["success_rate"] == 1.0
    result = runner.invoke(app, ["eval", str(out), "--episodes", "2", "--json"])
    assert result.exit_code == 0, result.output
    more = ["--set", "sb3.steps=400", "--set", "eval_episodes=2", "--set", f"sb3.crm={crm}"]
    result = runner.invoke(app, ["train", world, "--out", str(out), "--resume", *more])
    assert result.exit_code == 0, result.output


def test_acting_along_the_way_pushes_toward_it_within_the_bounds() -> None:
    from mitlc.learn.backends.sb3_guided import way_action, way_size_problem

    rng = np.random.default_rng(0)
    way = np.tile([[1.0, 0.0]], (2000, 1))
    actions = way_action(way, rng)
    assert actions.shape == (2000, 2) and np.all(np.abs(actions) <= 1.0)
    assert actions[:, 0].mean() > 0.99 and abs(actions[:, 1].mean()) < 0.05
    assert 0.25 < actions[:, 1].std() < 0.35  # the noise
    assert way_size_problem((2,), 2) is None
    assert "action has shape (4,)" in str(way_size_problem((4,), 2))


def test_acting_along_the_way_needs_the_way_and_an_off_policy_learner(tmp_path: Any) -> None:
    pytest.importorskip("gymnasium_robotics")
    from typer.testing import CliRunner

    from mitlc.cli import app

    world = "specs/envs/pointmaze-medium.yaml"
    for extra in (["--set", "guide=false"], ["--algo", "sb3-ppo"]):
        out = tmp_path / extra[-1]
        args = ["train", world, "--out", str(out), "--set", "sb3.steps=100", *extra]
        result = CliRunner().invoke(app, args)
        assert result.exit_code == 1 and "guide_warmup acts along the way" in result.output


def test_guide_is_refused_on_a_team_env() -> None:
    pytest.importorskip("mpe2")
    from mitlc.learn.config import ConfigError, TrainConfig
    from mitlc.learn.setting import prepare

    with pytest.raises(ConfigError, match="not on a team's"):
        prepare("specs/teams/mpe-spread.yaml", TrainConfig(algo="sb3-ppo", guide=True))


def _driven(start: tuple[float, float], spec: str) -> TaskWrapper:
    occupancy = Occupancy.from_rows(U_MAZE, 1.0, (0.0, 0.0), refine=4)
    return TaskWrapper(Point(start), spec, LABELS, horizon=60, occupancy=occupancy,
                       potential=0.0, guide=True, flatten=True)  # fmt: skip


def test_a_counterfactual_shows_the_way_of_its_own_task_state() -> None:
    """``sb3.crm`` with the way: a counterfactual of another task state shows the observation
    the wrapper shows in that state at that position (a second wrapper driven there), whose
    way points elsewhere than the experienced state's."""
    pytest.importorskip("stable_baselines3")
    from mitlc.learn.backends.sb3_crm import CounterfactualReplay, FlatTask

    spec = "F (b & F a)"  # b first (top-right), then a (bottom-left)
    lived = _driven((2.5, 0.5), spec)  # the bottom-right cell: b is up, a is left
    obs, _ = lived.reset(seed=0)
    still = np.zeros(2)
    after, reward, terminated, truncated, info = lived.step(still)
    assert after[-2:] == pytest.approx([0.0, 1.0], abs=0.05)  # b owed: up

    other = _driven((2.5, 2.5), spec)  # on b: its first step reads b
    other.reset(seed=0)
    other.step(still)
    other.env.unwrapped.at = np.array([2.5, 0.5])  # type: ignore[attr-defined]  # then it stands where `lived` stands
    shown, *_ = other.step(still)
    assert other.automaton_state != lived.automaton_state
    assert shown[-2:] == pytest.approx([-1.0, 0.0], abs=0.05)  # a owed: left

    memory = CounterfactualReplay(64, lived.observation_space, lived.action_space, "cpu", 1,
                                  task=FlatTask.of(lived))  # fmt: skip
    memory.add(
        obs[None],
        after[None],
        still[None],
        np.array([reward]),
        np.array([terminated or truncated]),
        [info],
    )
    made = memory.next_observations[: memory.pos, 0][memory.counterfactual[: memory.pos, 0]]
    assert len(made) > 0
    assert any(np.array_equal(row, shown) for row in made)
    experienced = memory.next_observations[: memory.pos, 0][~memory.counterfactual[: memory.pos, 0]]
    assert np.array_equal(experienced, after[None])  # the step itself, its way up, as it was
