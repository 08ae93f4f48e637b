"""The learning commands: mitlc train and mitlc eval, their files and their errors."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from typer.testing import CliRunner

from mitlc.cli import app
from tests.conftest import ROOT

runner = CliRunner()
CASE1 = str(ROOT / "specs" / "paper" / "case1.yaml")
SMALL = ["--episodes", "3000", "--set", "q.num_envs=64", "--quiet"]


def test_train_writes_a_run_and_reports_it_beside_the_optimum(tmp_path: Path) -> None:
    out = tmp_path / "run"
    result = runner.invoke(app, ["train", CASE1, "--out", str(out), *SMALL])
    assert result.exit_code == 0, result.output
    assert "optimum          0.974021" in result.output and "learned, exact" in result.output
    names = {p.name for p in out.iterdir()}
    steps = json.loads((out / "checkpoint.json").read_text())["steps"]
    latest = f"checkpoint_{steps:012d}_steps"
    assert {"config.json", "metrics.jsonl", "summary.json", ".lock", "checkpoint.json"} < names
    assert {f"{latest}.json", f"{latest}.npz"} < names and not any(".pkl" in n for n in names)
    assert len([n for n in names if n.endswith("_steps.json")]) == 2  # keep_checkpoints
    config = json.loads((out / "config.json").read_text())
    assert config["train"]["q"]["num_envs"] == 64 and config["train"]["episodes"] == 3000
    assert "(!a U[5,10] a) & (!b U[15,20] b)" in config["spec"]
    lines = (out / "metrics.jsonl").read_text().splitlines()
    assert len(lines) >= 50 and json.loads(lines[-1])["episodes"] >= 3000
    report = runner.invoke(app, ["eval", str(out), "--episodes", "2000", "--json"])
    assert report.exit_code == 0, report.output
    data = json.loads(report.output)
    assert data["episodes"] == 2000 and data["optimum_kind"] == "exact"
    assert data["interval95"][0] <= data["success_rate"] <= data["interval95"][1]


def test_train_refuses_to_overwrite_and_resumes(tmp_path: Path) -> None:
    out = str(tmp_path / "run")
    assert runner.invoke(app, ["train", CASE1, "--out", out, *SMALL, "--no-eval"]).exit_code == 0
    again = runner.invoke(app, ["train", CASE1, "--out", out, *SMALL])
    assert again.exit_code == 1 and "a run is already there (use --resume" in again.output
    more = runner.invoke(
        app, ["train", CASE1, "--out", out, "--resume", "--episodes", "4000", "-q", "--no-eval"]
    )
    assert more.exit_code == 0, more.output
    assert "trained 4,0" in more.output


def test_errors_exit_1_without_a_traceback(tmp_path: Path) -> None:
    cases = [
        (["train", CASE1, "--set", "q.alpah=1"], "training.q.alpah: unknown setting"),
        (["train", CASE1, "--set", "alpha"], "expected KEY=VALUE"),
        (["train", CASE1, "--algo", "ppo"], "training.algo: expected one of q, dqn, drqn"),
        (["train", str(tmp_path / "none.yaml")], "none.yaml"),
        (["train", CASE1, "--resume"], "--resume needs --out"),
        (["eval", str(tmp_path)], "not a run directory (no config.json)"),
        (["eval", str(tmp_path), "--episodes", "0"], "--episodes: expected a positive value"),
    ]
    for args, message in cases:
        result = runner.invoke(app, args)
        assert result.exit_code == 1, (args, result.output)
        assert message in result.output, (args, result.output)
        assert "Traceback" not in result.output


def test_ctrl_c_checkpoints_and_resume_finishes(tmp_path: Path) -> None:
    """A real SIGINT to a running `mitlc train`: it saves a checkpoint, says how to go on,
    exits 130; --resume then finishes the run."""
    out = tmp_path / "run"
    args = [sys.executable, "-m", "mitlc", "train", CASE1, "--out", str(out), "--quiet"]
    process = subprocess.Popen(
        [*args, "--episodes", "50000000", "--set", "log_every=1000", "--no-eval"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=ROOT,
    )
    deadline = time.monotonic() + 60
    while not (out / "config.json").exists() and time.monotonic() < deadline:
        time.sleep(0.1)
    time.sleep(0.5)
    os.kill(process.pid, signal.SIGINT)
    _, err = process.communicate(timeout=60)
    assert process.returncode == 130, err
    assert "checkpoint saved" in err and "--resume" in err
    assert (out / "checkpoint.json").exists() and not (out / "summary.json").exists()
    stopped = json.loads((out / "metrics.jsonl").read_text().splitlines()[-1])["episodes"]
    done = subprocess.run(
        [*args, "--resume", "--episodes", str(stopped + 2000), "--no-eval"],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    assert json.loads((out / "summary.json").read_text())["episodes"] >= stopped + 2000


def test_a_second_run_in_the_same_directory_is_refused(tmp_path: Path) -> None:
    """Two `mitlc train --resume` at once: the second exits 1 naming the first's process; the
    first's metrics stay one line per window."""
    out = tmp_path / "run"
    assert (
        runner.invoke(app, ["train", CASE1, "--out", str(out), *SMALL, "--no-eval"]).exit_code == 0
    )
    args = [sys.executable, "-m", "mitlc", "train", CASE1, "--out", str(out), "--resume", "-q"]
    first = subprocess.Popen(
        [*args, "--episodes", "50000000", "--no-eval"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=ROOT,
    )
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            if (out / ".lock").read_text().startswith(f"{first.pid}\n"):
                break
            time.sleep(0.05)
        second = subprocess.run(
            [*args, "--episodes", "60000000"], capture_output=True, text=True, cwd=ROOT, timeout=60
        )
        assert second.returncode == 1, second.stderr
        assert f"in use by process {first.pid} (python" in second.stderr
        assert "-m mitlc train" in second.stderr and "Traceback" not in second.stderr
    finally:
        os.kill(first.pid, signal.SIGINT)
        first.communicate(timeout=60)
    assert first.returncode == 130
    episodes = [json.loads(line)["episodes"] for line in (out / "metrics.jsonl").open()]
    assert episodes == sorted(set(episodes))


def test_train_set_up_stops_at_its_time_limit(tmp_path: Path) -> None:
    out = tmp_path / "run"
    result = runner.invoke(app, ["train", CASE1, "--out", str(out), "--time-limit", "1e-9"])
    assert result.exit_code == 1
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in result.output
    assert lines[0].startswith("mitlc train stopped at the time limit of 1e-09 s (during ")
    assert lines[0].endswith("raise it with --time-limit SECONDS (0 for none)")
    assert not (out / "config.json").exists()


def test_train_with_a_spec_naming_an_unlabelled_proposition_is_one_line(tmp_path: Path) -> None:
    """`train --spec` with a proposition that labels no cell printed a ValueError as a
    traceback (issue 12, bug 3); `check --spec` reported it properly."""
    spec = tmp_path / "zzz.mitl"
    spec.write_text("F zzz\n")
    out = tmp_path / "run"
    result = runner.invoke(app, ["train", CASE1, "--spec", str(spec), "--out", str(out)])
    assert result.exit_code == 1 and "Traceback" not in result.output
    (line,) = result.output.strip().splitlines()
    assert line.endswith("the task 'F zzz': proposition 'zzz' labels no cell (labels: a, b)")
    assert not (out / "config.json").exists()


def test_out_of_range_numbers_are_refused_without_a_traceback(tmp_path: Path) -> None:
    """Found by trying: a negative seed, NaN, and episode or trajectory counts far past memory
    raised numpy's errors (or drew for ever)."""
    out = tmp_path / "run"
    trained = runner.invoke(app, ["train", CASE1, "--out", str(out), *SMALL, "--no-eval"])
    assert trained.exit_code == 0
    for args, message in [
        (["train", CASE1, "--out", str(tmp_path / "a"), "--set", "seed=-1"], "training.seed"),
        (["train", CASE1, "--out", str(tmp_path / "b"), "--set", "q.alpha=nan"], "finite"),
        (["train", CASE1, "--out", str(tmp_path / "c"), "--set", "eval_episodes=10000000"], "most"),
        (["train", CASE1, "--out", str(tmp_path / "d"), "--seed", "-1"], "--seed"),
        (["eval", str(out), "--episodes", "1000000000000"], "--episodes"),
        (["eval", str(out), "--episodes", "99999999999999999999999"], "--episodes"),
        (["plot", str(out), "--trajectories", "1000000000"], "--trajectories"),
    ]:
        result = runner.invoke(app, args)
        assert result.exit_code in (1, 2), args
        assert "Traceback" not in result.output and message in result.output, args


def test_eval_stops_at_its_time_limit(tmp_path: Path) -> None:
    out = tmp_path / "run"
    trained = runner.invoke(app, ["train", CASE1, "--out", str(out), *SMALL, "--no-eval"])
    assert trained.exit_code == 0
    result = runner.invoke(app, ["eval", str(out), "--time-limit", "1e-9"])
    assert result.exit_code == 1 and "Traceback" not in result.output
    (line,) = result.output.strip().splitlines()
    assert line.startswith("mitlc eval stopped at the time limit of 1e-09 s (during ")
    assert line.endswith("raise it with --time-limit SECONDS (0 for none)")


def test_train_expr_is_recorded_as_a_spec_file_is(tmp_path: Path) -> None:
    tiny = ["--episodes", "20", "--quiet", "--no-eval"]
    inline = tmp_path / "inline"
    result = runner.invoke(app, ["train", CASE1, "-e", "F_[0..10] a", "--out", str(inline), *tiny])
    assert result.exit_code == 0, result.output
    spec = tmp_path / "task.mitl"
    spec.write_text("F_[0..10] a\n", encoding="utf-8")
    filed = tmp_path / "filed"
    result = runner.invoke(app, ["train", CASE1, "--spec", str(spec), "--out", str(filed), *tiny])
    assert result.exit_code == 0, result.output
    recorded = json.loads((inline / "config.json").read_text())["spec"]
    assert recorded == "F[0,10] a"
    assert recorded == json.loads((filed / "config.json").read_text())["spec"]
    # the run goes on with the same formula; another one is refused as a different run
    more = ["--episodes", "200", "--resume", "--quiet", "--no-eval", "--out", str(inline)]
    assert runner.invoke(app, ["train", CASE1, "-e", "F[0,10] a", *more]).exit_code == 0
    other = runner.invoke(app, ["train", CASE1, "-e", "F[0,10] b", *more])
    assert other.exit_code == 1 and "another world or task than the run's" in other.output


def test_train_refuses_spec_and_expr_together_and_points_at_a_bad_expr(tmp_path: Path) -> None:
    spec = tmp_path / "task.mitl"
    spec.write_text("F a\n", encoding="utf-8")
    out = tmp_path / "run"
    both = runner.invoke(app, ["train", CASE1, "--spec", str(spec), "-e", "F a", "--out", str(out)])
    assert both.exit_code == 1 and "Traceback" not in both.output
    assert both.output == "mitlc: give the task once: --spec SPEC or -e FORMULA, not both\n"
    bad = runner.invoke(app, ["train", CASE1, "-e", "F[0,10 a", "--out", str(out)])
    assert bad.exit_code == 1 and "Traceback" not in bad.output
    head, text, caret = bad.output.splitlines()
    assert head.startswith("<expr>:1:8: ") and text.strip() == "F[0,10 a"
    assert caret.strip() == "^" and caret.index("^") == text.index("F") + 7
    assert not out.exists()
