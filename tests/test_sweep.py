"""Sweeps (issue 14): sweep files and their field-path errors, the report's statistics against
rliable's own, and sweeps run on Ray locally: a tiny one, one interrupted and resumed, and one
whose trial worker is killed and retried from its checkpoint."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rliable")

from mitlc.sweep import stats
from mitlc.sweep.spec import SweepError, load_sweep
from mitlc.sweep.trial import RESULT, run_trial, trial_directory
from tests.conftest import ROOT

WORLDS = f"[{ROOT}/specs/paper/case1.yaml, {ROOT}/specs/gym/frozenlake4x4.yaml]"
TINY = f"""
name: tiny
worlds: {WORLDS}
learners:
  q: {{algo: q, set: {{q.num_envs: 64}}}}
  q-fast: {{algo: q, set: {{q.num_envs: 64, q.alpha: 0.8}}}}
seeds: 2
episodes: 1500
eval_episodes: 100
"""


def write(tmp_path: Path, text: str, name: str = "sweep.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


# -- the sweep file ----------------------------------------------------------------------------


def test_a_sweep_file_becomes_one_trial_per_world_learner_point_and_seed(tmp_path: Path) -> None:
    text = TINY.replace("seeds: 2", "seeds: [3, 5]") + "grid: {discount.gamma: [0.9, 0.99]}\n"
    sweep = load_sweep(write(tmp_path, text))
    assert len(sweep.trials) == 2 * 2 * 2 * 2
    first = sweep.trials[0]
    assert first.world_name == "case1-5x5" and first.seed == 3
    assert first.overrides == {"algo": "q", "q.num_envs": 64, "discount.gamma": 0.9,
                               "episodes": 1500, "seed": 3}  # fmt: skip
    assert first.setting == "q[discount.gamma=0.9]"
    assert len({t.trial_id for t in sweep.trials}) == len(sweep.trials)


def test_the_shipped_sweep_file_loads() -> None:
    sweep = load_sweep(ROOT / "specs" / "sweeps" / "case1-learners.yaml")
    assert len(sweep.trials) == 2 * 2 * 10
    assert {t.world_name for t in sweep.trials} == {"case1-5x5", "frozenlake-4x4"}


BAD = {
    "unknown world": ("worlds: [nowhere.yaml]", "worlds[0]: unknown world: no file 'nowhere.yaml'"),
    "unknown setting path": (
        "q: {algo: q, set: {q.num_envs: 64}}",
        "learners.q.set.q.num_env",
    ),
    "empty grid": ("", "grid.q.alpha: expected a non-empty list of values, got []"),
    "bad seeds": ("seeds: 2", "seeds: expected a count above 0"),
    "unknown field": ("name: tiny", "seed: unknown field"),
    "bad algo": ("q-fast: {algo: q,", "learners.q-fast.algo: expected one of q, dqn"),
    "bad value": ("", "grid.q.alpha: training.q.alpha"),
}
CHANGED = {
    "unknown world": lambda t: t.replace(f"worlds: {WORLDS}", "worlds: [nowhere.yaml]"),
    "unknown setting path": lambda t: t.replace("{q.num_envs: 64}}", "{q.num_env: 64}}", 1),
    "empty grid": lambda t: t + "grid: {q.alpha: []}\n",
    "bad seeds": lambda t: t.replace("seeds: 2", "seeds: -2"),
    "unknown field": lambda t: t.replace("name: tiny", "name: tiny\nseed: 3"),
    "bad algo": lambda t: t.replace("q-fast: {algo: q,", "q-fast: {algo: ppo,"),
    "bad value": lambda t: t + "grid: {q.alpha: [fast]}\n",
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_a_bad_sweep_file_is_reported_with_its_field_path(tmp_path: Path, case: str) -> None:
    path = write(tmp_path, CHANGED[case](TINY))
    with pytest.raises(SweepError) as caught:
        load_sweep(path)
    message = str(caught.value)
    assert BAD[case][1] in message, message
    assert message.startswith(f"{path}:"), message
    line = message.split(":")[1]
    assert line.isdigit() and int(line) > 0, message


def test_the_command_line_reports_a_bad_sweep_file_in_one_line(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from mitlc.cli import app

    path = write(tmp_path, CHANGED["empty grid"](TINY))
    done = CliRunner().invoke(app, ["sweep", str(path), "--out", str(tmp_path / "out")])
    assert done.exit_code == 1 and "grid.q.alpha" in done.output
    assert "Traceback" not in done.output and not (tmp_path / "out").exists()


# -- the statistics ------------------------------------------------------------------------------


def fixed_scores() -> dict[str, np.ndarray]:
    rng = np.random.default_rng(7)
    ties = np.round(rng.random((9, 3)), 1)  # repeated values
    return {"plain": rng.random((10, 1)), "tasks": rng.random((7, 4)), "ties": ties}


def test_the_metrics_are_rliables() -> None:
    from rliable import metrics

    scores = fixed_scores()
    for values in scores.values():
        assert stats.iqm(values) == pytest.approx(metrics.aggregate_iqm(values))
        assert stats.median(values) == pytest.approx(metrics.aggregate_median(values))
        assert stats.mean(values) == pytest.approx(metrics.aggregate_mean(values))
        assert stats.optimality_gap(values) == pytest.approx(
            metrics.aggregate_optimality_gap(values)
        )
    pairs = [("ties", "ties"), ("plain", "plain")]
    x, y = scores["ties"], np.round(np.random.default_rng(8).random((5, 3)), 1)
    for a, b in [(x, y), (y, x), (x, x), *[(scores[p], scores[q]) for p, q in pairs]]:
        assert stats.probability_of_improvement(a, b) == pytest.approx(
            metrics.probability_of_improvement(a, b)
        )


def test_the_intervals_are_rliables_stratified_bootstrap() -> None:
    """Same resamples (same seed), same statistics: the same intervals as rliable's own
    aggregate functions give."""
    from rliable import library as rly
    from rliable import metrics

    from mitlc.sweep.report import STATISTICS, interval_estimates
    from mitlc.sweep.scores import quiet

    scores = fixed_scores()
    ours = interval_estimates(scores, reps=300, seed=3)

    def theirs_aggregate(x: np.ndarray) -> np.ndarray:
        return np.array([
            metrics.aggregate_iqm(x), metrics.aggregate_median(x), metrics.aggregate_mean(x),
            metrics.aggregate_optimality_gap(x),
        ])  # fmt: skip

    with quiet(3):
        points, intervals = rly.get_interval_estimates(
            scores, theirs_aggregate, reps=300, random_state=np.random.RandomState(3)
        )
    for name in scores:
        for k, stat in enumerate(STATISTICS):
            point, low, high = ours[name][stat]
            assert point == pytest.approx(points[name][k])
            assert low == pytest.approx(intervals[name][0][k])
            assert high == pytest.approx(intervals[name][1][k])
            assert low <= point + 1e-12 and point <= high + 1e-12
    assert interval_estimates(scores, reps=300, seed=3) == ours  # reproducible


# -- sweeps on Ray -------------------------------------------------------------------------------


def mitlc(*args: str, **kwargs: object) -> subprocess.Popen[str]:
    env = {**os.environ, "PYTHONPATH": str(ROOT), "PYTHONWARNINGS": "ignore"}
    return subprocess.Popen([sys.executable, "-m", "mitlc", *args], cwd=ROOT, env=env,
                            text=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            **kwargs)  # type: ignore[call-overload]  # fmt: skip


def test_a_tiny_sweep_runs_locally_and_reports(tmp_path: Path) -> None:
    """Two worlds x two learners x two seeds on Ray on this machine: every trial's run
    directory, result and the report; a trial equals the same trial run alone."""
    sweep_file = write(tmp_path, TINY)
    out = tmp_path / "out"
    process = mitlc("sweep", str(sweep_file), "--out", str(out), "--reps", "200")
    stdout, stderr = process.communicate(timeout=600)
    assert process.returncode == 0, stderr[-3000:]
    assert "8 of 8 trials finished" in stdout
    assert "trials: 8/8 done" in stderr
    sweep = load_sweep(sweep_file)
    for trial in sweep.trials:
        result = json.loads((trial_directory(out, trial) / RESULT).read_text())
        assert result["score_kind"] == "success / optimum" and 0 <= result["score"] <= 1.0001
        assert (trial_directory(out, trial) / "config.json").is_file()
    report = (out / "report.md").read_text()
    assert "## case1-5x5" in report and "## frozenlake-4x4" in report
    assert "q-fast > q" in report and "## Across worlds" in report
    for name in ("performance_profile.png", "learning_curves.png", "report.json"):
        assert (out / name).stat().st_size > 0
    alone = run_trial(sweep.trials[0], tmp_path / "alone")
    first = json.loads((trial_directory(out, sweep.trials[0]) / RESULT).read_text())
    for key in ("success_rate", "exact", "train_episodes", "train_steps", "optimum"):
        assert alone[key] == first[key], key
    again = mitlc("sweep", str(sweep_file), "--out", str(out))
    _, stderr = again.communicate(timeout=120)
    assert again.returncode == 1 and "a sweep is already there (use --resume" in stderr


def wait_for(condition: object, timeout: float) -> None:
    start = time.monotonic()
    while not condition():  # type: ignore[operator]
        if time.monotonic() - start > timeout:
            raise AssertionError("timed out")
        time.sleep(0.2)


LONG = f"""
name: long
worlds: [{ROOT}/specs/paper/case1.yaml]
learners:
  q: {{algo: q, set: {{q.num_envs: 64, checkpoint_every: 2000, log_every: 1000}}}}
seeds: 2
episodes: 60000
eval_episodes: 200
max_failures: 2
"""


def test_a_killed_trial_is_retried_from_its_checkpoint_and_ends_as_an_unkilled_one(
    tmp_path: Path,
) -> None:
    """Kill a trial's worker process (SIGKILL) after its first checkpoint: Tune retries it,
    it resumes from the checkpoint, and its final figures equal those of the same trial run
    without interruption."""
    sweep_file = write(tmp_path, LONG.replace("seeds: 2", "seeds: 1"))
    sweep = load_sweep(sweep_file)
    out = tmp_path / "out"
    trial = sweep.trials[0]
    directory = trial_directory(out, trial)
    process = mitlc("sweep", str(sweep_file), "--out", str(out), "--reps", "100")
    try:
        wait_for(lambda: (directory / "checkpoint.json").is_file(), 300)
        pid = int((directory / "worker.pid").read_text())
        killed_at = json.loads((directory / "checkpoint.json").read_text())["steps"]
        os.kill(pid, signal.SIGKILL)
        _, stderr = process.communicate(timeout=600)
    finally:
        process.kill()
    assert process.returncode == 0, stderr[-3000:]
    assert "1 retried" in stderr, stderr[-2000:]
    result = json.loads((directory / RESULT).read_text())
    assert result["train_steps"] > killed_at
    alone = run_trial(trial, tmp_path / "alone")
    for key in ("success_rate", "exact", "train_episodes", "train_steps"):
        assert alone[key] == result[key], key


def test_an_interrupted_sweep_resumes_and_skips_finished_trials(tmp_path: Path) -> None:
    sweep_file = write(tmp_path, LONG.replace("episodes: 60000", "episodes: 20000"))
    sweep = load_sweep(sweep_file)
    out = tmp_path / "out"
    first, second = (trial_directory(out, t) for t in sweep.trials)
    process = mitlc("sweep", str(sweep_file), "--out", str(out), "--reps", "100",
                    start_new_session=True)  # fmt: skip
    try:
        wait_for(lambda: (first / "checkpoint.json").is_file()
                 or (second / "checkpoint.json").is_file(), 300)  # fmt: skip
        os.killpg(process.pid, signal.SIGKILL)  # the driver and its Ray workers
        process.communicate(timeout=60)
    finally:
        process.kill()
    done_before = {d.name: (d / RESULT).stat().st_mtime_ns for d in (first, second)
                   if (d / RESULT).is_file()}  # fmt: skip
    assert len(done_before) < 2
    ray_cli = Path(sys.executable).with_name("ray")  # the venv's, not necessarily on PATH
    subprocess.run([str(ray_cli), "stop", "--force"], capture_output=True, check=False)
    resumed = mitlc("sweep", str(sweep_file), "--out", str(out), "--resume", "--reps", "100")
    stdout, stderr = resumed.communicate(timeout=600)
    assert resumed.returncode == 0, stderr[-3000:]
    assert "2 of 2 trials finished" in stdout
    for name, mtime in done_before.items():
        assert (out / "trials" / name / RESULT).stat().st_mtime_ns == mtime  # skipped
    for trial, directory in zip(sweep.trials, (first, second), strict=True):
        alone = run_trial(trial, tmp_path / "alone")
        result = json.loads((directory / RESULT).read_text())
        for key in ("success_rate", "exact", "train_episodes", "train_steps"):
            assert alone[key] == result[key], key


def test_the_report_uses_the_raw_success_where_no_optimum_exists(tmp_path: Path) -> None:
    """A world without an exact optimum is reported on its raw success rate and left out of
    the across-worlds statistics; the tables and figures are written."""
    from mitlc.sweep.report import report

    rng = np.random.default_rng(0)
    for world, optimum in (("grid", 0.9), ("plane", None), ("lake", 0.7)):
        for setting in ("a", "b"):
            for seed in range(4):
                success = float(rng.random())
                trial_id = f"{world}--{setting}--s{seed}"
                folder = tmp_path / "trials" / trial_id
                folder.mkdir(parents=True)
                (folder / "metrics.jsonl").write_text("".join(
                    json.dumps({"episodes": 100 * k, "success_rate": success * k / 5}) + "\n"
                    for k in range(1, 6)))  # fmt: skip
                (folder / RESULT).write_text(json.dumps({
                    "world_name": world, "setting": setting, "seed": seed, "trial_id": trial_id,
                    "optimum": optimum, "success_rate": success,
                    "score": success / optimum if optimum else success,
                    "score_kind": "success / optimum" if optimum else
                    "success rate (no exact optimum)",
                }))  # fmt: skip
    written = report(tmp_path, reps=200)
    data = written.data
    assert data["worlds"]["plane"]["score_kind"] == "success rate (no exact optimum)"
    assert data["worlds"]["grid"]["score_kind"] == "success / optimum"
    assert data["across_worlds"]["worlds"] == ["grid", "lake"]
    scores = data["worlds"]["lake"]["settings"]["a"]["scores"]
    assert data["worlds"]["lake"]["settings"]["a"]["mean"][0] == pytest.approx(np.mean(scores))
    markdown = (tmp_path / "report.md").read_text()
    assert "Score: success rate (no exact optimum)." in markdown
    assert {p.name for p in written.files} == {
        "report.json",
        "report.md",
        "performance_profile.png",
        "learning_curves.png",
    }


def test_report_of_a_directory_without_finished_trials_is_one_line(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from mitlc.cli import app

    done = CliRunner().invoke(app, ["report", str(tmp_path)])
    assert done.exit_code == 1 and "no finished trials" in done.output
    broken = tmp_path / "trials" / "x"
    broken.mkdir(parents=True)
    (broken / RESULT).write_text("{not json")
    done = CliRunner().invoke(app, ["report", str(tmp_path)])
    assert done.exit_code == 1 and f"{broken / RESULT}: not a trial's result" in done.output


NEVER = (
    (ROOT / "specs" / "paper" / "case1.yaml")
    .read_text()
    .replace("spec: case1.mitl", 'spec: {formula: "F[0,3] a"}')
)
"""Case 1 with a task no policy meets: ``a`` is 5 moves from the start, the task asks for it
within 3 steps (an exact optimum of 0)."""


def test_an_optimum_of_zero_is_an_exact_optimum(tmp_path: Path) -> None:
    """A finite world whose optimum is exactly 0 has an exact optimum (every policy attains
    it: score 1), not "no exact optimum"; the report keeps it among the exact worlds."""
    from mitlc.sweep.report import report
    from mitlc.sweep.trial import NO_OPTIMUM, OVER_OPTIMUM, score

    assert score(0.0, 0.0) == (1.0, OVER_OPTIMUM)
    assert score(0.3, 0.6) == (0.5, OVER_OPTIMUM) and score(0.3, None) == (0.3, NO_OPTIMUM)
    (tmp_path / "never.yaml").write_text(NEVER.replace("name: case1-5x5", "name: never"))
    sweep_file = write(tmp_path, TINY.replace(WORLDS, f"[{tmp_path / 'never.yaml'}, "
                                              f"{ROOT}/specs/gym/frozenlake4x4.yaml]")
                       .replace("episodes: 1500", "episodes: 300"))  # fmt: skip
    out = tmp_path / "out"
    for trial in load_sweep(sweep_file).trials:
        result = run_trial(trial, out)
        if trial.world_name == "never":
            assert result["optimum"] == 0.0 and result["optimum_kind"] == "exact"
            assert result["score"] == 1.0 and result["score_kind"] == OVER_OPTIMUM
            assert result["success_rate"] == 0.0 and result["exact"] == 0.0
    data = report(out, reps=100).data
    assert data["worlds"]["never"]["score_kind"] == OVER_OPTIMUM
    assert data["across_worlds"]["worlds"] == ["frozenlake-4x4", "never"]


def test_a_patrols_rounds_per_episode_reach_the_report(tmp_path: Path) -> None:
    """Trials of a recurring task report their evaluation's mean rounds; the report keeps them
    per seed and the table shows their mean where any world has some."""
    from mitlc.sweep.report import report

    for setting, rounds in (("a", [2.0, 3.0]), ("b", [0.5, 1.5])):
        for seed, mean_rounds in enumerate(rounds):
            trial_id = f"patrol--{setting}--s{seed}"
            folder = tmp_path / "trials" / trial_id
            folder.mkdir(parents=True)
            (folder / "metrics.jsonl").write_text(
                json.dumps({"episodes": 100, "success_rate": 0.5}) + "\n"
            )
            (folder / RESULT).write_text(json.dumps({
                "world_name": "patrol", "setting": setting, "seed": seed, "trial_id": trial_id,
                "optimum": 1.0, "success_rate": 0.5, "score": 0.5 + 0.1 * seed,
                "score_kind": "success / optimum", "mean_rounds": mean_rounds,
            }))  # fmt: skip
    data = report(tmp_path, reps=100).data
    assert data["worlds"]["patrol"]["settings"]["a"]["rounds"] == [2.0, 3.0]
    markdown = (tmp_path / "report.md").read_text()
    assert "mean rounds per episode" in markdown
    assert "| 2.50 |" in markdown and "| 1.00 |" in markdown
