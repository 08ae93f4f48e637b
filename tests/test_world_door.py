"""The one door for worlds (issue 43, item 1): every command reads the world file once and
makes at most one probe env beside the envs its learner runs, whatever the kind of world.

Counted from the outside: every ``os.open``/``open`` of the world file, and every
``gymnasium.make``, while ``mitlc check``, ``train``, ``eval`` and ``plot`` run in-process.
"""

from __future__ import annotations

import builtins
import importlib
import io
import os
from collections import Counter
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import gymnasium
import pytest
from typer.testing import CliRunner

from mitlc.cli import app
from mitlc.learn.config import config_for
from mitlc.worlds.door import is_finite, open_world, read_world

ROOT = Path(__file__).parents[1]
runner = CliRunner()

CART = """
env: {id: CartPole-v1}
labels:
  tilted: [{box: {index: [2], low: [-0.25], high: [-0.1]}},
           {box: {index: [2], low: [0.1], high: [0.25]}}]
spec: {formula: "G[0,20] !tilted"}
horizon: 20
reward: {satisfied: 1, accept: 1, violated: 0, move: 0}
training: {dqn: {num_envs: 2, episodes: 2, warmup_steps: 16}}
"""


class Tally:
    """Opens of one file, and envs made, while a command runs."""

    def __init__(self, world: Path) -> None:
        self.world = str(world.resolve())
        self.reads = 0
        self.makes: Counter[str] = Counter()

    def saw(self, path: Any) -> None:
        if isinstance(path, str | Path) and str(Path(path).resolve()) == self.world:
            self.reads += 1


@contextmanager
def tally(world: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Tally]:
    counts = Tally(world)
    real_os_open, real_open, real_make = os.open, builtins.open, gymnasium.make

    def os_open(path: Any, *args: Any, **kwargs: Any) -> int:
        counts.saw(path)
        return real_os_open(path, *args, **kwargs)

    def py_open(path: Any, *args: Any, **kwargs: Any) -> Any:
        counts.saw(path)
        return real_open(path, *args, **kwargs)

    def make(env_id: Any, *args: Any, **kwargs: Any) -> Any:
        counts.makes[str(getattr(env_id, "id", env_id))] += 1
        return real_make(env_id, *args, **kwargs)

    spread = importlib.import_module("mpe2.simple_spread_v3")
    real_parallel = spread.parallel_env

    def parallel_env(*args: Any, **kwargs: Any) -> Any:
        counts.makes["mpe2.simple_spread_v3"] += 1
        return real_parallel(*args, **kwargs)

    with monkeypatch.context() as patch:
        patch.setattr(spread, "parallel_env", parallel_env)
        patch.setattr(os, "open", os_open)
        patch.setattr(builtins, "open", py_open)
        patch.setattr(io, "open", py_open)
        patch.setattr(gymnasium, "make", make)
        yield counts


def worlds(tmp_path: Path) -> dict[str, Path]:
    cart = tmp_path / "cart.yaml"
    cart.write_text(CART)
    return {
        "grid": ROOT / "specs" / "paper" / "case1.yaml",
        "pomdp": ROOT / "specs" / "paper" / "case2.yaml",
        "finite-env": ROOT / "specs" / "gym" / "frozenlake4x4.yaml",
        "open-env": cart,
        "plane": ROOT / "specs" / "continuous" / "case1.yaml",
        "team": ROOT / "specs" / "teams" / "two-robots.yaml",
        "pettingzoo": ROOT / "specs" / "teams" / "mpe-spread.yaml",
    }


BUDGET = {
    "grid": ["--episodes", "200", "--set", "q.num_envs=8"],
    "pomdp": ["--episodes", "200", "--set", "q.num_envs=8", "--algo", "q"],
    "finite-env": ["--episodes", "200", "--set", "q.num_envs=8"],
    "open-env": [],
    "plane": ["--set", "dqn.episodes=2", "--set", "dqn.warmup_steps=16",
              "--set", "dqn.num_envs=2"],
    "team": ["--episodes", "200", "--set", "q.num_envs=8", "--set", "team=independent"],
    "pettingzoo": ["--set", "sb3.steps=256", "--set", "sb3.num_envs=1", "--set", "sb3.n_steps=64",
                   "--set", "eval_episodes=4"],
}  # fmt: skip
LEARNER_ENVS = {"open-env": 2, "plane": 0, "pettingzoo": 1}
"""The gymnasium envs each learner runs (``num_envs``); finite worlds run the simulator."""


@pytest.mark.parametrize("kind", list(BUDGET))
def test_train_eval_and_plot_read_the_world_once_and_make_one_probe_at_most(
    kind: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    world = worlds(tmp_path)[kind]
    out = tmp_path / "run"
    commands = {
        "train": ["train", str(world), "--out", str(out), "--quiet", "--no-eval", *BUDGET[kind]],
        "eval": ["eval", str(out), "--episodes", "4"],
        "plot": ["plot", str(out), "--out", str(tmp_path / "plots")],
    }
    for name, argv in commands.items():
        with tally(world, monkeypatch) as counts:
            result = runner.invoke(app, argv)
        assert result.exit_code == 0, (name, result.output)
        assert counts.reads == 1, f"{kind} {name}: the world file read {counts.reads} times"
        made = sum(counts.makes.values())
        allowed = LEARNER_ENVS.get(kind, 0) + (
            1 if kind.endswith("env") or kind == "pettingzoo" else 0
        )
        if name == "train" or kind not in ("open-env", "pettingzoo"):
            assert made <= allowed, f"{kind} {name}: {dict(counts.makes)} made"
        if kind == "finite-env":
            assert made == 1  # the probe that tells it is finite, and nothing else


@pytest.mark.parametrize("kind", ["grid", "pomdp", "finite-env"])
def test_check_reads_the_world_once(
    kind: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    world = worlds(tmp_path)[kind]
    with tally(world, monkeypatch) as counts:
        result = runner.invoke(app, ["check", str(world), "--no-pomdp-bounds"])
    assert result.exit_code == 0, result.output
    assert counts.reads == 1
    assert sum(counts.makes.values()) == (1 if kind == "finite-env" else 0)


def test_the_declaration_is_of_its_kind_and_the_world_answers_for_itself(
    tmp_path: Path,
) -> None:
    found = {name: read_world(path) for name, path in worlds(tmp_path).items()}
    assert {name: d.kind for name, d in found.items()} == {
        "grid": "grid", "pomdp": "grid", "finite-env": "env", "open-env": "env", "plane": "plane",
        "team": "team", "pettingzoo": "pettingzoo",
    }  # fmt: skip
    built = {name: d.build() for name, d in found.items()}
    finite = {name for name, w in built.items() if is_finite(w)}
    assert finite == {"grid", "pomdp", "finite-env", "team"}
    algos = {name: config_for(w, {})[0].algo for name, w in built.items()}
    assert algos == {
        "grid": "q", "pomdp": "drqn", "finite-env": "q", "open-env": "dqn", "plane": "dqn",
        "team": "q", "pettingzoo": "sb3-ppo",
    }  # fmt: skip
    assert built["grid"].drawing is not None and built["finite-env"].drawing is None
    assert built["open-env"].drawing is None and built["plane"].drawing is built["plane"]
    assert built["open-env"].training["dqn"]["num_envs"] == 2


def test_a_task_given_in_place_of_the_files_is_built_in_the_same_one_read(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    world = worlds(tmp_path)["grid"]
    with tally(world, monkeypatch) as counts:
        built = open_world(world, "F[0,9] b")
    assert counts.reads == 1 and built.spec == "F[0,9] b" and built.spec_source == "<spec>"


def test_the_tally_sees_every_read_and_make(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The counting itself can fail: two reads are two, and an env world's build makes one."""
    paths = worlds(tmp_path)
    with tally(paths["open-env"], monkeypatch) as counts:
        read_world(paths["open-env"])
        read_world(paths["open-env"]).build()
    assert counts.reads == 2 and counts.makes == Counter({"CartPole-v1": 1})
