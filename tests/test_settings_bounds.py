"""Every numeric setting is bounded (issue 26): the table of ``docs/limits_settings.md`` against
:mod:`mitlc.learn.bounds`, every setting of the code in the table, and the cases a fuzzer found
(each refused in one line, exit 1, before anything is built or trained)."""

from __future__ import annotations

import dataclasses
import json
import re
import time
import typing
from pathlib import Path

import pytest
from typer.testing import CliRunner

from mitlc.cli import app
from mitlc.learn import bounds
from mitlc.learn.bounds import OPTIONS, PRODUCTS, SWEEP, TRAINING
from mitlc.learn.config import (
    ConfigError,
    QConfig,
    TrainConfig,
    config_for,
    from_data,
    resolve,
    to_data,
    validate,
)
from mitlc.worlds.door import open_world
from tests.conftest import ROOT

runner = CliRunner()
CASE1 = str(ROOT / "specs" / "paper" / "case1.yaml")
FROZEN = str(ROOT / "specs" / "gym" / "frozenlake4x4.yaml")
DOC = ROOT / "docs" / "limits_settings.md"
QUICK = 5.0
"""Seconds within which a refusal comes (nothing is built or trained; a loaded machine)."""


# -- the documented table against the code -----------------------------------------------------


def doc_tables() -> dict[str, dict[str, tuple[str, str]]]:
    """Each ``## heading`` of the doc: its table's rows, name -> (range, reason)."""
    tables: dict[str, dict[str, tuple[str, str]]] = {}
    heading = ""
    for line in DOC.read_text(encoding="utf-8").splitlines():
        if line.startswith("## "):
            heading = line[3:].strip()
        row = re.fullmatch(r"\| `([^`]+)` \| ([^|]+) \| (.+) \|", line)
        if row is not None:
            name, limits, reason = row.groups()
            assert name not in tables.get(heading, {}), f"{name} is listed twice"
            tables.setdefault(heading, {})[name] = (limits.strip(), reason.strip())
    return tables


def expected_tables() -> dict[str, dict[str, tuple[str, str]]]:
    """The same tables from :mod:`mitlc.learn.bounds`."""
    return {
        "Training settings": {
            f"training.{k}": (b.range_text(), b.reason) for k, b in TRAINING.items()
        },
        "Products of settings": {p.formula: (str(p.limit), p.reason) for p in PRODUCTS},
        "Sweep files": {k: (b.range_text(), b.reason) for k, b in SWEEP.items()},
        "Command-line options": {
            f"mitlc {k}": (b.range_text(), b.reason) for k, b in OPTIONS.items()
        },
    }


def test_the_documented_table_is_the_codes() -> None:
    documented, expected = doc_tables(), expected_tables()
    assert set(documented) == set(expected)
    for heading, rows in expected.items():
        assert set(documented[heading]) == set(rows), heading
        for name, (limits, reason) in rows.items():
            assert documented[heading][name] == (limits, reason), name
            assert reason, name


def numeric_fields(cls: type, path: str = "") -> dict[str, object]:
    """Every int or float field of the settings (``q.num_envs``) with its default."""
    found: dict[str, object] = {}
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        where = f"{path}{f.name}"
        kind = hints[f.name]
        if dataclasses.is_dataclass(kind):
            found.update(numeric_fields(kind, f"{where}."))  # type: ignore[arg-type]
        elif kind in (int, float):
            found[where] = getattr(cls(), f.name)
    return found


def test_every_numeric_setting_has_a_bound_that_holds_its_default() -> None:
    fields = numeric_fields(TrainConfig)
    assert set(fields) == set(TRAINING)
    for name, default in fields.items():
        assert TRAINING[name].problem(default) is None, name  # type: ignore[arg-type]
    assert all(product.first in TRAINING for product in PRODUCTS)
    validate(TrainConfig())  # the products of the defaults too


@pytest.mark.parametrize("world", sorted((ROOT / "specs").glob("*/*.yaml")), ids=str)
def test_every_shipped_world_keeps_to_the_bounds(world: Path) -> None:
    if world.parent.name == "sweeps":
        return
    config_for(open_world(world), {})  # no ConfigError


def test_the_documented_budgets_keep_to_the_bounds() -> None:
    for overrides in (
        {"algo": "q", "episodes": 1_200_000, "q.num_envs": 1024},
        {"algo": "sb3-ppo", "sb3.steps": 300_000, "sb3.num_envs": 8, "sb3.n_steps": 128},
        {"algo": "sb3-sac", "sb3.steps": 300_000},
        {"algo": "dqn", "dqn.num_envs": 32, "dqn.target_update": 25, "episodes": 10_000},
    ):
        resolve({}, overrides, discount=0.99, pomdp=False)


# -- the cases found by fuzzing: refused in one line, exit 1, quickly ---------------------------


def refused(args: list[str], message: str) -> str:
    """Run ``mitlc ARGS``: exit 1, one line holding ``message``, no traceback, quickly."""
    start = time.perf_counter()
    result = runner.invoke(app, args)
    seconds = time.perf_counter() - start
    assert result.exit_code == 1, (args, result.output)
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], (args, result.output)
    assert "Traceback" not in result.output and seconds < QUICK, (args, seconds)
    return lines[0]


TRAIN_CASES = {
    "q.num_envs": (CASE1, ["--set", "q.num_envs=1000000000"],
                   "training.q.num_envs: expected at most 65536, got 1000000000"),
    "dqn.batch_size": (CASE1, ["--algo", "dqn", "--set", "dqn.batch_size=100000000"],
                       "training.dqn.batch_size: expected at most 65536, got 100000000"),
    "sb3.hidden": (FROZEN, ["--algo", "sb3-ppo", "--set", "sb3.hidden=1000000"],
                   "training.sb3.hidden: expected at most 4096, got 1000000"),
    "sb3.num_envs": (FROZEN, ["--algo", "sb3-ppo", "--set", "sb3.num_envs=100000"],
                     "training.sb3.num_envs: expected at most 256, got 100000"),
    "--episodes 2^63": (CASE1, ["--episodes", str(2**63)],
                        f"--episodes: expected at most 100000000, got {2**63}"),
    "section episodes": (CASE1, ["--set", "q.episodes=1000000000"],
                         "training.q.episodes: expected at most 100000000"),
    "--seed": (CASE1, ["--seed", str(2**64)], "--seed: expected a value in [0, "),
    "network product": (CASE1, ["--set", "dqn.hidden=4096", "--set", "dqn.layers=100"],
                        "training.dqn.layers: dqn.layers x dqn.hidden^2 is 1677721600"),
}  # fmt: skip


@pytest.mark.parametrize("case", sorted(TRAIN_CASES))
def test_train_refuses_an_unbounded_setting_before_it_starts(tmp_path: Path, case: str) -> None:
    world, args, message = TRAIN_CASES[case]
    out = tmp_path / "run"
    refused(["train", world, "--out", str(out), "--quiet", *args], message)
    assert not out.exists()


def test_the_python_api_refuses_settings_built_out_of_bounds(tmp_path: Path) -> None:
    from mitlc.learn.run import train

    config = TrainConfig(q=QConfig(num_envs=10**9))
    with pytest.raises(ConfigError, match=r"^training\.q\.num_envs: expected at most 65536"):
        train(CASE1, config, tmp_path / "run")
    assert not (tmp_path / "run").exists()


def saved_run(directory: Path, **dqn: int) -> Path:
    """A run directory whose ``config.json`` has ``dqn`` settings (never trained)."""
    data = to_data(TrainConfig(algo="dqn"))
    data["dqn"].update(dqn)
    directory.mkdir()
    text = json.dumps({"world": CASE1, "spec": "F a", "train": data})
    (directory / "config.json").write_text(text)
    return directory


def test_a_saved_config_out_of_bounds_is_refused_by_eval_and_resume(tmp_path: Path) -> None:
    run = saved_run(tmp_path / "run", hidden=30000)
    with pytest.raises(ConfigError, match=r"^dqn\.hidden: expected at most 4096, got 30000"):
        from_data(json.loads((run / "config.json").read_text())["train"])
    message = "config.json: train.dqn.hidden: expected at most 4096, got 30000"
    refused(["eval", str(run)], message)
    refused(["train", CASE1, "--out", str(run), "--resume", "--quiet"], message)


OPTION_CASES = {
    "eval --episodes": (["eval", "RUN", "--episodes", "1000000000"],
                        "--episodes: expected at most 1000000, got 1000000000"),
    "eval --episodes 0": (["eval", "RUN", "--episodes", "0"],
                          "--episodes: expected a positive value, got 0"),
    "plot --trajectories": (["plot", "RUN", "--trajectories", "1000"],
                            "--trajectories: expected a value in [0, 100], got 1000"),
    "sweep --reps": (["sweep", "SWEEP", "--reps", "1000000000000"],
                     "--reps: expected a value in [100, 50000], got 1000000000000"),
    "report --reps": (["report", "DIR", "--reps", "99"], "--reps: expected a value in [100, "),
    "report --seed": (["report", "DIR", "--seed", "-1"], "--seed: expected a value in [0, "),
}  # fmt: skip


@pytest.mark.parametrize("case", sorted(OPTION_CASES))
def test_an_option_out_of_bounds_is_refused_first(tmp_path: Path, case: str) -> None:
    args, message = OPTION_CASES[case]
    run = saved_run(tmp_path / "run")
    sweep = tmp_path / "sweep.yaml"
    sweep.write_text(f"worlds: [{CASE1}]\nlearners: {{q: {{algo: q}}}}\nseeds: 1\n")
    names = {"RUN": str(run), "SWEEP": str(sweep), "DIR": str(tmp_path / "sweep")}
    refused([names.get(a, a) for a in args], message)
    assert not (tmp_path / "sweep").exists() and sorted(p.name for p in run.iterdir()) == [
        "config.json"
    ]


# -- sweep files ------------------------------------------------------------------------------

SWEEP_FILE = f"""name: bounds
worlds: [{CASE1}]
learners:
  q: {{algo: q}}
seeds: 2
"""
AXES = ("q.alpha", "q.alpha_end", "q.initial_value", "discount.gamma")
"""Four grid axes: of 1,000 values each, 10^12 points."""

SWEEP_CASES = {
    "eval_episodes": ("eval_episodes: 1000000000\n",
                      "eval_episodes: expected at most 1000000, got 1000000000"),
    "episodes": (f"episodes: {2**63 - 1}\n", "episodes: expected at most 100000000"),
    "max_failures": ("max_failures: 1000000\n", "max_failures: expected a value in [0, 100]"),
    "cpus_per_trial": ("cpus_per_trial: 0\n", "cpus_per_trial: expected a positive value"),
    "seeds": ("seeds: 1000000000000\n", "seeds: expected a count above 0 (at most 10,000)"),
    "learner settings": ("learners: {q: {algo: q, set: {q.num_envs: 1000000000}}}\n",
                         "learners.q.set.q.num_envs: training.q.num_envs: expected at most"),
    "grid value": ("grid: {dqn.hidden: [64, 100000]}\n",
                   "grid.dqn.hidden: training.dqn.hidden: expected at most 4096"),
    "grid of 10^12 points": (
        "grid: {" + ", ".join(f"{axis}: {[i / 1000 for i in range(1000)]}" for axis in AXES)
        + "}\n", "2,000,000,000,000 trials: more than 10,000 (mitlc's limit)"),
}  # fmt: skip


def sweep_text(extra: str) -> str:
    """The sweep file with ``extra`` (which replaces its learners or its seeds if it has them)."""
    text = SWEEP_FILE
    if extra.startswith("learners:"):
        text = text.replace("learners:\n  q: {algo: q}\n", "")
    if extra.startswith("seeds:"):
        text = text.replace("seeds: 2\n", "")
    return text + extra


@pytest.mark.parametrize("case", sorted(SWEEP_CASES))
def test_a_sweep_file_out_of_bounds_is_refused(tmp_path: Path, case: str) -> None:
    from mitlc.sweep.spec import SweepError, load_sweep

    extra, message = SWEEP_CASES[case]
    path = tmp_path / "sweep.yaml"
    path.write_text(sweep_text(extra))
    start = time.perf_counter()
    with pytest.raises(SweepError) as caught:
        load_sweep(path)
    assert time.perf_counter() - start < QUICK, case
    text = str(caught.value)
    assert len(text.splitlines()) == 1 and text.startswith(f"{path}:"), text
    assert message in text, text


def test_the_sweep_command_refuses_a_sweep_file_out_of_bounds(tmp_path: Path) -> None:
    pytest.importorskip("ray")
    pytest.importorskip("rliable")
    path = tmp_path / "sweep.yaml"
    path.write_text(SWEEP_FILE + "eval_episodes: 1000000000\n")
    out = tmp_path / "out"
    line = refused(["sweep", str(path), "--out", str(out)], "eval_episodes: expected at most")
    assert line.startswith(f"{path}:6:16: ") and not out.exists()


def test_a_bound_names_its_problem() -> None:
    positive = bounds.Bound(1, 65536, "why")
    assert positive.problem(0) == "expected a positive value, got 0"
    assert positive.problem(100000000) == "expected at most 65536, got 100000000"
    assert positive.problem(65536) is None and positive.range_text() == "[1, 65536]"
    unit = bounds.Bound(0, 1, "why", open_low=True)
    assert unit.problem(0.0) == "expected a positive value, got 0.0" and unit.problem(1) is None
    assert unit.range_text() == "(0, 1]"
    assert bounds.Bound(0, 1, "why").problem(1.5) == "expected a value in [0, 1], got 1.5"
    assert unit.problem(float("nan")) == "expected a finite number, got nan"
    with pytest.raises(bounds.OutOfRange, match=r"^--reps: expected a value in \[100, 50000\]"):
        bounds.check_option("sweep", "--reps", 10**12)
