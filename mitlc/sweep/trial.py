"""One trial of a sweep: ``mitlc train`` then ``mitlc eval``, in its own run directory,
resumable at any point.

The trial's run directory is ``DIR/trials/<trial id>/`` (a mitlc run directory:
:mod:`mitlc.learn.run`). :func:`run_trial` picks up wherever an earlier attempt stopped: a
finished trial (``result.json``) is returned as it is; a run with a checkpoint resumes from it
(exactly, for mitlc's learners: the same final figures as an uninterrupted run with the seed);
a run that trained to the end is evaluated; a run that died before its first checkpoint starts
over. ``result.json`` is written atomically, last: its presence means the trial is done.

The score of a trial is its greedy success over the exact optimum of the same event
(``pmax_horizon``) where the world is finite and an MDP: the exact success of the policy where
it is known (a memoryless policy on an MDP), else the Monte-Carlo rate
(:func:`mitlc.learn.evaluation.montecarlo.monte_carlo`, through
:func:`mitlc.learn.evaluation.evaluate.evaluate`). For
a POMDP the optimum is the fully observable upper bound; for a world that is not finite there
is none, and the score is the raw success rate (``score_kind`` says which). An optimum of
exactly 0 is an exact optimum all the same: no policy succeeds, so every policy attains it and
scores 1 (:func:`score`).
"""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

from mitlc.inputs import MAX_RECORD_BYTES, read_capped
from mitlc.sweep.spec import SweepError, Trial

RESULT, TRIAL = "result.json", "trial.json"
TRIALS = "trials"
OVER_OPTIMUM, NO_OPTIMUM = "success / optimum", "success rate (no exact optimum)"
"""The two kinds of score (``score_kind``)."""


def trial_directory(root: Path, trial: Trial) -> Path:
    """Where ``trial`` runs, under the sweep's directory ``root``."""
    return Path(root) / TRIALS / trial.trial_id


def read_record(path: Path) -> Any:
    """The JSON value in ``path``, a record of the sweep's directory, read within
    :data:`~mitlc.inputs.MAX_RECORD_BYTES`: a :class:`SweepError` when it cannot be read (not a
    regular file, too large), :class:`ValueError` when it is not UTF-8 JSON."""
    try:
        data = read_capped(path, MAX_RECORD_BYTES, "a sweep's record")
    except OSError as err:
        raise SweepError(f"{path}: {err.strerror or err}") from None
    return json.loads(data.decode("utf-8"))


def read_result(directory: Path) -> dict[str, Any] | None:
    """The trial's result, if it finished."""
    path = directory / RESULT
    if not path.exists():
        return None
    data: dict[str, Any] = read_record(path)
    return data


def run_trial(
    trial: Trial,
    root: Path,
    *,
    progress: Callable[[Any], None] | None = None,
) -> dict[str, Any]:
    """Train and evaluate ``trial`` under ``root`` (see the module docstring); its result."""
    from mitlc.files import write_atomically
    from mitlc.learn.config import config_for
    from mitlc.learn.evaluation.evaluate import evaluate
    from mitlc.learn.run import train
    from mitlc.learn.rundir import checkpoint
    from mitlc.learn.rundir.files import SUMMARY, read_json
    from mitlc.learn.setting import CONFIG
    from mitlc.worlds.door import open_world

    directory = trial_directory(root, trial)
    done = read_result(directory)
    if done is not None:
        return done
    directory.mkdir(parents=True, exist_ok=True)
    _write(directory / TRIAL, trial.to_data(), write_atomically)
    (directory / "worker.pid").write_text(f"{os.getpid()}\n", encoding="utf-8")
    world = open_world(trial.world)  # the one read and build of the world file
    config, _ = config_for(world, trial.overrides)
    if not (directory / SUMMARY).is_file():
        resume = checkpoint.exists(directory) and (directory / CONFIG).is_file()
        if not resume:  # died before its first checkpoint, or never started: start over
            _clear(directory)
        train(trial.world, config, directory, resume=resume, progress=progress, world=world)
    evaluation = evaluate(directory, episodes=trial.eval_episodes, seed=trial.seed)
    summary = read_json(directory / SUMMARY)
    learned = evaluation.exact if evaluation.exact is not None else evaluation.success_rate
    optimum = evaluation.optimum
    value, kind = score(learned, optimum)
    result = {
        **trial.to_data(),
        "trial_id": trial.trial_id,
        "setting": trial.setting,
        "algo": config.algo,
        "success_rate": evaluation.success_rate,
        "interval95": list(evaluation.interval),
        "exact": evaluation.exact,
        "optimum": optimum,
        "optimum_kind": evaluation.summary()["optimum_kind"],
        "score": value,
        "score_kind": kind,
        "train_episodes": summary["episodes"],
        "train_steps": summary["steps"],
        "train_seconds": summary["seconds"],
        "eval_episodes": evaluation.episodes,
        "mean_rounds": evaluation.mean_rounds,
    }
    _write(directory / RESULT, result, write_atomically)
    return result


def score(learned: float, optimum: float | None) -> tuple[float, str]:
    """A trial's score and what it is: ``learned / optimum`` where the world has an exact
    optimum (an optimum of 0 is attained by every policy: 1), else the raw success rate
    ``learned``."""
    if optimum is None:
        return learned, NO_OPTIMUM
    return (learned / optimum if optimum > 0 else 1.0), OVER_OPTIMUM


def _write(path: Path, data: Any, write: Callable[[Path, bytes], None]) -> None:
    write(path, (json.dumps(data, indent=2, sort_keys=True) + "\n").encode())


def _clear(directory: Path) -> None:
    """Remove what a run that never checkpointed left (not the trial's own files)."""
    for entry in directory.iterdir():
        if entry.name in (TRIAL, "worker.pid"):
            continue
        if entry.is_dir():
            shutil.rmtree(entry)
        else:
            entry.unlink()
