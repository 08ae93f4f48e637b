"""The PettingZoo world kind (pettingzoo: files): the shipped mpe2 simple_spread example loads
through the one door, passes PettingZoo's API test through its team_env(), and trains, evaluates
and plots end to end through the CLI with a tiny budget; bad files are errors at their fields."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

pytest.importorskip("pettingzoo")
pytest.importorskip("mpe2")
pytest.importorskip("stable_baselines3")

from pettingzoo.test import parallel_api_test
from typer.testing import CliRunner

from mitlc.cli import app
from mitlc.worlds.door import is_finite, open_world, read_world
from mitlc.worlds.pettingzoo_world import TeamEnvTask, TeamWorldError
from mitlc.worlds.source import WorldError

SPREAD = Path(__file__).parent.parent / "specs" / "teams" / "mpe-spread.yaml"


def test_the_example_loads_as_a_team_env_world() -> None:
    declaration = read_world(SPREAD)
    assert declaration.kind == "pettingzoo"
    world = declaration.build()
    assert isinstance(world, TeamEnvTask) and not is_finite(world)
    assert world.default_algo == "sb3-ppo" and world.drawing is None and not world.is_pomdp
    assert world.agents == ("agent_0", "agent_1")
    assert "collide" in world.propositions and "at_0_agent_1" in world.propositions
    with pytest.raises(TeamWorldError, match="sb3-ppo"):
        world.task_env(None)
    with pytest.raises(WorldError, match="not finite"):
        declaration.finite()


def test_the_example_passes_the_parallel_api_test() -> None:
    world = open_world(SPREAD)
    assert isinstance(world, TeamEnvTask)
    parallel_api_test(world.team_env(), num_cycles=60)
    parallel_api_test(world.team_env(), num_cycles=60)  # a fresh one after the probe's


def test_per_agent_tasks_make_the_team_task(tmp_path: Path) -> None:
    text = SPREAD.read_text(encoding="utf-8").replace(
        '  formula: "!collide U[0,40]', '  x: "'
    )  # no team spec: the agents' tasks
    lines = [ln for ln in text.splitlines() if not ln.startswith(("spec:", '  x: "'))]
    lines.append('tasks: {agent_0: "F[0,40] at_0", agent_1: "F[0,40] at_1"}')
    path = tmp_path / "tasks.yaml"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    world = open_world(path)
    assert world.spec == "(F[0,40] at_0_agent_0) & (F[0,40] at_1_agent_1)"


@pytest.mark.parametrize(
    ("edit", "where"),
    [
        (("env: mpe2.simple_spread_v3", "env: mpe2/simple_spread_v3"), ":9:8: pettingzoo.env"),
        (("env: mpe2.simple_spread_v3", "env: no_such_module_xyz"), "no installed module"),
        (("continuous_actions: false", "continuous_actions: false, bogus: 1"), "pettingzoo"),
        (("radius: 0.25}}\n  at_1", "radius: -1}}\n  at_1"), "labels.at_0"),
        (("at_1_agent_1) |", "at_2_agent_1) |"), "spec"),
        (("horizon: 50", "horizon: 50\nhorizont: 3"), "did you mean"),
    ],
)
def test_bad_files_are_errors_at_their_fields(
    tmp_path: Path, edit: tuple[str, str], where: str
) -> None:
    old, new = edit
    text = SPREAD.read_text(encoding="utf-8")
    assert old in text
    path = tmp_path / "bad.yaml"
    path.write_text(text.replace(old, new, 1), encoding="utf-8")
    with pytest.raises(WorldError) as err:
        open_world(path)
    assert where in str(err.value)


def test_train_eval_and_plot_through_the_cli(tmp_path: Path) -> None:
    runner, out = CliRunner(), tmp_path / "run"
    tiny = ["--set", "sb3.steps=512", "--set", "sb3.num_envs=2", "--set", "sb3.n_steps=64"]
    result = runner.invoke(app, ["train", str(SPREAD), "--out", str(out), "-q", "--no-eval", *tiny])
    assert result.exit_code == 0, result.output
    lines = (out / "metrics.jsonl").read_text(encoding="utf-8").splitlines()
    assert lines and "success_rate" in json.loads(lines[-1])
    result = runner.invoke(app, ["eval", str(out), "--episodes", "20", "--json"])
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    assert report["episodes"] == 20 and report["optimum"] is None
    assert 0.0 <= report["interval95"][0] <= report["success_rate"] <= report["interval95"][1]
    assert "mean_rounds" in report
    result = runner.invoke(app, ["plot", str(out)])
    assert result.exit_code == 0, result.output
    assert (out / "learning_curve.png").is_file() and not (out / "trajectories.png").exists()


def test_other_learners_are_refused_by_name(tmp_path: Path) -> None:
    result = CliRunner().invoke(
        app, ["train", str(SPREAD), "--algo", "dqn", "--out", str(tmp_path / "r"), "-q"]
    )
    assert result.exit_code == 1 and "sb3-ppo or sb3-dqn" in result.output
