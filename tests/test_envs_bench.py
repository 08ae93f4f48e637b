"""bench/envs_bench.py's records in git: a finished run's record counts in a later sitting only
where the bench would run the same command now (a budget or setting changed makes it stale),
whatever the machine's interpreter and run directory."""

from __future__ import annotations

import argparse
import dataclasses
import importlib.util
import json
import sys
from pathlib import Path
from typing import Any

import pytest

from tests.conftest import ROOT


@pytest.fixture(scope="module")
def bench() -> Any:
    spec = importlib.util.spec_from_file_location("envs_bench", ROOT / "bench" / "envs_bench.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["envs_bench"] = module
    spec.loader.exec_module(module)
    return module


def options(records: Path, **given: Any) -> argparse.Namespace:
    values = {"record": records, "steps_scale": 1.0, "device": None, "episodes": None,
              "provenance": {"commit": "abc", "cpus": 2}, **given}  # fmt: skip
    return argparse.Namespace(**values)


def a_run(bench: Any, out: Path, task: str = "case1c", arm: str = "mitlc") -> Any:
    return next(r for r in bench.plan(list(bench.TASKS), [1], out) if r.label == f"{task} {arm} s1")


def record_of(bench: Any, run: Any, args: argparse.Namespace, python: str) -> dict[str, Any]:
    line = bench.command(run, args.steps_scale, args.device, bench.crm_on(run))
    line = [python, *line[1:]]
    return {"task": run.task.name, "arm": run.arm.name, "seed": run.seed, "success_rate": 0.5,
            "command": line, "notes": [], "eval_episodes": run.task.eval_episodes}  # fmt: skip


def test_a_record_of_the_same_command_counts_elsewhere(
    bench: Any, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Made on another machine (another interpreter, another --out): it counts, and the bench
    neither trains nor evaluates the run again."""
    args = options(tmp_path / "records")
    run = a_run(bench, tmp_path / "here")
    elsewhere = a_run(bench, tmp_path / "there")
    bench.keep(elsewhere, record_of(bench, elsewhere, args, "/other/python"), args)
    saved = json.loads((tmp_path / "records" / "case1c-mitlc-s1.json").read_text())
    assert saved["commit"] == "abc" and saved["success_rate"] == 0.5
    assert bench.signature(saved["command"]) == bench.signature(
        bench.command(run, 1.0, None, False)
    )
    assert bench.recorded(run, args)["success_rate"] == 0.5
    bench.keep(run, {**saved, "commit": "older"}, args)  # finished in an earlier sitting
    assert bench.recorded(run, args)["commit"] == "older"

    def no(*_: Any) -> Any:
        raise AssertionError("a recorded run was run again")

    monkeypatch.setattr(bench, "train", no)
    monkeypatch.setattr(bench, "evaluate", no)
    bench.execute(run, 1, 1, args)
    assert run.result is not None and run.result["success_rate"] == 0.5


@pytest.mark.parametrize("change", ["budget", "episodes", "seed", "setting"])
def test_a_record_of_another_command_is_stale(bench: Any, tmp_path: Path, change: str) -> None:
    args = options(tmp_path / "records")
    run = a_run(bench, tmp_path / "here")
    record = record_of(bench, run, args, "/usr/bin/python3")
    if change == "budget":
        record["command"] = [w.replace("sb3.steps=150000", "sb3.steps=1000")
                             for w in record["command"]]  # fmt: skip
    elif change == "episodes":
        record["eval_episodes"] = 100
    elif change == "seed":
        record["command"][record["command"].index("--seed") + 1] = "2"
    else:
        record["command"] += ["--set", "shaping=2"]
    assert record["command"] != record_of(bench, run, args, "/usr/bin/python3")["command"] or (
        change == "episodes"
    )
    bench.keep(run, record, args)
    assert bench.recorded(run, args) is None


def test_no_records_at_scaled_budgets(bench: Any, tmp_path: Path) -> None:
    """A record names the command, so a record of a scaled run is stale at full budgets."""
    args = options(tmp_path / "records", steps_scale=0.5)
    run = a_run(bench, tmp_path / "here")
    bench.keep(run, record_of(bench, run, args, "py"), args)
    assert bench.recorded(run, options(tmp_path / "records")) is None
    assert bench.recorded(run, args) is not None
    assert bench.recorded(dataclasses.replace(run, seed=2), args) is None


def test_the_report_is_made_of_the_records_alone(bench: Any, tmp_path: Path) -> None:
    """``--report`` runs nothing: the table holds the recorded arm (with its records' commit)
    and says which runs are missing; a target without its runs is not measured."""
    import subprocess

    args = options(tmp_path / "records")
    for seed in (0, 1, 2):
        run = next(r for r in bench.plan(list(bench.TASKS), [seed], tmp_path / "x")
                   if r.label == f"doorkey mitlc s{seed}")  # fmt: skip
        record = record_of(bench, run, args, "py")
        record.update(algo="sb3-ppo", success_rate=0.9 + seed / 100, interval95=[0.8, 1.0],
                      steps=299_008, wall_s=10.0)  # fmt: skip
        bench.keep(run, record, args)
    done = subprocess.run(
        [sys.executable, str(ROOT / "bench" / "envs_bench.py"), "--report", "--record",
         str(tmp_path / "records"), "--tasks", "doorkey,pointmaze", "--arms", "plain,mitlc"],
        cwd=ROOT, capture_output=True, text=True, check=True,
    )  # fmt: skip
    out = done.stdout
    assert "| doorkey | mitlc | sb3-ppo | 0.910 | s0 0.900 [0.800, 1.000]; s1 0.910" in out
    assert "| doorkey | plain | - | missing |" in out and "(commits abc)" in out
    assert "PASS DoorKey-5x5 >= 0.9" in out
    assert "NOT MEASURED PointMaze_UMaze >= 0.9 within 300,000 steps: 3 of 3 runs missing" in out
    assert not (tmp_path / "x").exists()


def test_the_iqm_is_over_the_tasks_and_seeds_every_arm_has(bench: Any, tmp_path: Path) -> None:
    """A task with an arm still to run leaves the IQM (and is named), and a seed that one arm
    lacks leaves it too, so that the arms stay paired: P(mitlc > plain) is printed."""
    import subprocess

    args = options(tmp_path / "records")
    given = {("doorkey", "plain"): (0, 1), ("doorkey", "mitlc"): (0, 1, 2),
             ("pointmaze", "mitlc"): (0, 1, 2)}  # fmt: skip
    for (task, arm), seeds in given.items():
        for seed in seeds:
            run = next(r for r in bench.plan(list(bench.TASKS), [seed], tmp_path / "x")
                       if r.label == f"{task} {arm} s{seed}")  # fmt: skip
            record = record_of(bench, run, args, "py")
            success = 0.2 * seed if arm == "plain" else 0.9
            record.update(algo="sb3", success_rate=success, interval95=[0.0, 1.0], steps=1,
                          wall_s=1.0)  # fmt: skip
            bench.keep(run, record, args)
    done = subprocess.run(
        [sys.executable, str(ROOT / "bench" / "envs_bench.py"), "--report", "--record",
         str(tmp_path / "records"), "--tasks", "doorkey,pointmaze", "--arms", "plain,mitlc",
         "--reps", "200"],
        cwd=ROOT, capture_output=True, text=True, check=True,
    )  # fmt: skip
    out = done.stdout
    assert "across doorkey (95% stratified bootstrap); not yet: pointmaze:" in out
    assert "plain  0.100 [" in out and "(2 seeds)" in out and "mitlc  0.900 [" in out
    assert "P(mitlc > plain) 1.000" in out


def fake_train(answers: list[tuple[int, str]], calls: list[list[str]]) -> Any:
    """``subprocess.run`` answering each ``mitlc train`` in turn with (exit status, stderr)."""
    import subprocess

    def run(line: list[str], **_: Any) -> subprocess.CompletedProcess[str]:
        calls.append(list(line))
        code, stderr = answers[len(calls) - 1]
        return subprocess.CompletedProcess(line, code, "", stderr)

    return run


def test_an_interrupted_crm_run_is_not_taken_for_a_refusal(
    bench: Any, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A counterfactual run stopped by a signal ends with the resume command, which names its
    ``mitlc-crm`` directory: the bench stops it (to go on later), and never runs it again
    without counterfactuals."""
    run = a_run(bench, tmp_path, "pointmaze", "mitlc-crm")
    resume = (f"stopped at episode 280; checkpoint saved. Continue with:\n  mitlc train "
              f"specs/envs/pointmaze.yaml --out {run.directory / 'run'} --resume\n")  # fmt: skip
    calls: list[list[str]] = []
    monkeypatch.setattr(bench.subprocess, "run", fake_train([(130, resume)], calls))
    with pytest.raises(bench.Interrupted):
        bench.train(run, 1.0, None)
    assert len(calls) == 1 and "sb3.crm=true" in calls[0] and run.notes == []
    assert bench.crm_refusal(130, resume) is None and bench.crm_refusal(1, resume) is None


def test_a_crm_refusal_runs_again_without_it(
    bench: Any, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """mitlc's own refusal (its one-line message, exit 1) is met by a run without ``crm``."""
    from typer.testing import CliRunner

    from mitlc.cli import app

    world = ROOT / "specs" / "paper" / "case1.yaml"
    said = CliRunner().invoke(app, ["train", str(world), "--algo", "sb3-ppo", "--set",
                                    "sb3.crm=true", "--out", str(tmp_path / "x")])  # fmt: skip
    assert said.exit_code == 1 and bench.crm_refusal(1, said.output) is not None
    assert bench.crm_refusal(1, "Traceback (most recent call last):\n" + said.output) is None
    run = a_run(bench, tmp_path, "pointmaze", "mitlc-crm")
    calls: list[list[str]] = []
    monkeypatch.setattr(bench.subprocess, "run", fake_train([(1, said.output), (0, "")], calls))
    bench.train(run, 1.0, None)
    assert "sb3.crm=true" in calls[0] and "sb3.crm=true" not in calls[1]
    assert run.notes[0].startswith("crm refused, run without it (sb3.crm: ")
