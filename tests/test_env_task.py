"""Env worlds that are not finite (``env:`` naming an env without a transition table): loaded
with the wrapper's label forms and field-path errors, learned from the command line by every
learner on a Discrete, a Dict and an (unbounded) Box observation, evaluated without an
optimum, plotted, and resumed."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

import tests.open_envs  # noqa: F401 - registers MitlcTest/Chain-v0 and MitlcTest/DictChain-v0
from mitlc.cli import app
from mitlc.learn.config import resolve
from mitlc.learn.evaluation.evaluate import evaluate
from mitlc.learn.run import train
from mitlc.worlds import WorldError
from mitlc.worlds.door import is_finite, load_env_task, open_world

CHAIN = """
name: chain
env: {id: MitlcTest/Chain-v0}
labels:
  goal: {obs: [5]}
spec: {formula: "F[0,12] goal"}
horizon: 15
discount: 0.95
reward: {satisfied: 1, accept: 1, violated: 0, move: 0}
"""
DICT_CHAIN = CHAIN.replace("MitlcTest/Chain-v0", "MitlcTest/DictChain-v0").replace(
    "goal: {obs: [5]}", "goal: {obs: [5], key: pos}"
)
CART = """
env: {id: CartPole-v1}
labels:
  tilted: [{box: {index: [2], low: [-0.25], high: [-0.1]}},
           {box: {index: [2], low: [0.1], high: [0.25]}}]
spec: {formula: "G[0,20] !tilted"}
horizon: 20
reward: {satisfied: 1, accept: 1, violated: 0, move: 0}
"""


def world(tmp_path: Path, text: str, name: str = "world.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_an_env_without_a_transition_table_loads_with_the_wrappers_label_forms(
    tmp_path: Path,
) -> None:
    cart = load_env_task(world(tmp_path, CART))
    assert cart.propositions == ("tilted",) and cart.horizon == 20
    assert isinstance(cart.labels["tilted"], list) and cart.is_pomdp is False
    assert not is_finite(open_world(tmp_path / "world.yaml"))
    assert is_finite(open_world(Path(__file__).parents[1] / "specs" / "gym" / "frozenlake4x4.yaml"))
    env = cart.task_env("G[0,20] !tilted")
    obs, info = env.reset(seed=0)
    assert set(obs) == {"env", "automaton", "frontier"} and "action_mask" in info


BAD = {
    "index past the Box": (
        CART.replace("index: [2], low: [0.1]", "index: [7], low: [0.1]"),
        "labels.tilted[1].box.index: index 7 is out of range",
    ),
    "obs on a Box": (
        CART.replace("[{box: {index: [2], low: [-0.25], high: [-0.1]}},", "[{obs: [1]},"),
        "labels.tilted[0].obs: needs a Discrete observation",
    ),
    "a malformed form": (
        CART.replace("high: [-0.1]", "high: nope"),
        "labels.tilted[0].box.high",
    ),
    "a move cost": (
        CART.replace("move: 0", "move: -1"),
        "reward.move: an env's actions have no 'stay'",
    ),
    "an unlabelled proposition": (
        CART.replace("G[0,20] !tilted", "G[0,20] !fallen"),
        "proposition 'fallen' is not labelled",
    ),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_a_bad_env_world_is_reported_with_its_field_path(tmp_path: Path, case: str) -> None:
    text, expected = BAD[case]
    with pytest.raises(WorldError) as caught:
        load_env_task(world(tmp_path, text))
    assert expected in str(caught.value), str(caught.value)
    assert str(tmp_path / "world.yaml") in str(caught.value)


def run(tmp_path: Path, text: str, overrides: dict[str, object], out: str) -> Path:
    config = resolve({}, {"log_every": 100, "checkpoint_every": 200, **overrides},
                     discount=0.95, pomdp=False)  # fmt: skip
    train(world(tmp_path, text, f"{out}.yaml"), config, tmp_path / out)
    return tmp_path / out


def test_tabular_q_learns_an_env_with_a_discrete_observation(tmp_path: Path) -> None:
    directory = run(tmp_path, CHAIN, {"algo": "q", "episodes": 3000, "q.num_envs": 16}, "q")
    result = evaluate(directory, episodes=400)
    assert result.optimum is None and result.success_rate >= 0.9


def test_dqn_learns_an_env_with_a_dict_observation(tmp_path: Path) -> None:
    settings = {"algo": "dqn", "episodes": 1500, "dqn.num_envs": 8, "dqn.warmup_steps": 64,
                "dqn.initial_value": 1.0, "dqn.epsilon_decay": 0.5}  # fmt: skip
    directory = run(tmp_path, DICT_CHAIN, settings, "dqn")
    assert evaluate(directory, episodes=200).success_rate >= 0.9


@pytest.mark.parametrize("text", [CHAIN, DICT_CHAIN], ids=["discrete", "dict"])
def test_the_recurrent_dqn_runs_on_an_env_world(tmp_path: Path, text: str) -> None:
    settings = {"algo": "drqn", "episodes": 120, "drqn.num_envs": 4,
                "drqn.warmup_sequences": 8}  # fmt: skip
    directory = run(tmp_path, text, settings, "drqn")
    summary = json.loads((directory / "summary.json").read_text())
    assert summary["episodes"] >= 120
    assert 0.0 <= evaluate(directory, episodes=50).success_rate <= 1.0


def test_the_command_line_trains_evaluates_plots_and_resumes_an_unbounded_box_env(
    tmp_path: Path,
) -> None:
    """CartPole (velocities unbounded): ``train`` picks DQN, ``eval`` reports no optimum,
    ``plot`` draws the curve and the automaton; a resumed run (the env's state cannot be
    saved, so its running episodes start over) reaches the episodes asked for."""
    path = world(tmp_path, CART)
    runner = CliRunner()
    out = tmp_path / "cart"
    common = ["--set", "dqn.num_envs=4", "--set", "dqn.warmup_steps=32", "--quiet", "--no-eval"]
    done = runner.invoke(app, ["train", str(path), "--out", str(out), "--episodes", "60",
                               *common])  # fmt: skip
    assert done.exit_code == 0, done.output
    assert json.loads((out / "config.json").read_text())["train"]["algo"] == "dqn"
    more = runner.invoke(app, ["train", str(path), "--out", str(out), "--episodes", "120",
                               "--resume", *common])  # fmt: skip
    assert more.exit_code == 0, more.output
    assert json.loads((out / "summary.json").read_text())["episodes"] >= 120
    shown = runner.invoke(app, ["eval", str(out), "--episodes", "20", "--json"])
    assert shown.exit_code == 0, shown.output
    report = json.loads(shown.output)
    assert report["optimum"] is None and report["optimum_kind"].startswith("none")
    drawn = runner.invoke(app, ["plot", str(out)])
    assert drawn.exit_code == 0, drawn.output
    assert (out / "learning_curve.png").stat().st_size > 0
    assert (out / "automaton.png").stat().st_size > 0
    checked = runner.invoke(app, ["check", str(path)])
    assert checked.exit_code == 1 and "not a finite world" in checked.output
