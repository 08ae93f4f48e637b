"""Running a sweep on Ray Tune: ``run_sweep(sweep, out, address=..., resume=...)``.

Each trial of the sweep (:mod:`mitlc.sweep.spec`) is one Tune trial of the function
:func:`trainable`, one process with ``cpus_per_trial`` CPUs, which runs
:func:`mitlc.sweep.trial.run_trial` in the trial's own run directory under ``out`` and reports
its progress to Tune (``tune.report``). Without ``address`` Ray starts on this machine with
all its cores; with one (``auto``, ``HOST:PORT``, ``ray://HOST:10001``) it joins that cluster,
whose nodes must all see ``out`` at the same path (a shared file system): the run directories
are where the trials checkpoint, resume and write their results.

Faults: a trial whose worker dies is restarted by Tune (``max_failures`` times,
``tune.FailureConfig``) and resumes from its own last checkpoint. An interrupted sweep goes on
with ``resume=True``: finished trials (their ``result.json``) are skipped, the others resume
from their checkpoints. ``out/sweep.json`` records the sweep's trials, so that ``resume`` with
another sweep file is refused. At the end the report is written (:mod:`mitlc.sweep.report`).
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mitlc.sweep.spec import Sweep, SweepError, Trial
from mitlc.sweep.trial import read_record, read_result, run_trial, trial_directory

SWEEP = "sweep.json"
REPORT_EVERY = 2.0
"""Seconds between a trial's progress reports to Tune."""


@dataclass(frozen=True, slots=True)
class Event:
    """What happened to a trial, for a progress display: ``start``, ``done``, ``error``
    (its worker died or it raised: Tune retries it up to ``max_failures`` times) or
    ``skipped`` (finished before this run)."""

    kind: str
    trial: str


@dataclass(frozen=True, slots=True)
class SweepResult:
    """The trials that finished (their results) and those that failed for good."""

    results: tuple[dict[str, Any], ...]
    failed: tuple[str, ...]


def trainable(config: dict[str, Any]) -> None:
    """One trial in a Ray worker (a Tune function trainable)."""
    from ray import tune

    trial = Trial.from_data(config["trial"])
    last = [0.0]

    def progress(p: Any) -> None:
        now = time.monotonic()
        if now - last[0] >= REPORT_EVERY:
            last[0] = now
            tune.report({"episodes": p.episodes, "steps": p.steps, "success_rate": p.success_rate})

    result = run_trial(trial, Path(config["root"]), progress=progress)
    tune.report({"done": 1, "score": result["score"], "success_rate": result["success_rate"]})


def _record(out: Path, sweep: Sweep, resume: bool) -> None:
    """Write ``out/sweep.json``, or, resuming, check that it is this sweep's."""
    from mitlc.files import write_atomically

    path = out / SWEEP
    ids = [t.trial_id for t in sweep.trials]
    if path.is_file():
        if not resume:
            raise SweepError(f"{out}: a sweep is already there (use --resume, or another --out)")
        saved = read_record(path)
        if saved.get("trials") != ids:
            raise SweepError(f"{out}: --resume with another sweep than the one there "
                             f"({saved.get('file')})")  # fmt: skip
        return
    data = {"name": sweep.name, "file": str(sweep.path.resolve()), "trials": ids}
    write_atomically(path, (json.dumps(data, indent=2) + "\n").encode())


def run_sweep(
    sweep: Sweep,
    out: Path,
    *,
    address: str | None = None,
    resume: bool = False,
    on_event: Callable[[Event], None] | None = None,
) -> SweepResult:
    """Run every trial of ``sweep`` not yet finished under ``out`` (see the module docstring)."""
    out = Path(out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    _record(out, sweep, resume)
    todo = []
    for trial in sweep.trials:
        if read_result(trial_directory(out, trial)) is not None:
            if on_event is not None:
                on_event(Event("skipped", trial.trial_id))
        else:
            todo.append(trial)
    failed: list[str] = []
    if todo:
        failed = _tune(sweep, out, todo, address, on_event)
    results = []
    for trial in sweep.trials:
        result = read_result(trial_directory(out, trial))
        if result is not None:
            results.append(result)
        elif trial.trial_id not in failed:
            failed.append(trial.trial_id)
    return SweepResult(tuple(results), tuple(failed))


def _tune(
    sweep: Sweep,
    out: Path,
    todo: list[Trial],
    address: str | None,
    on_event: Callable[[Event], None] | None,
) -> list[str]:
    """Run ``todo`` on Ray Tune; the ids of the trials that failed for good."""
    os.environ.setdefault("RAY_AIR_NEW_OUTPUT", "0")
    import ray
    from ray import tune

    started_here = not ray.is_initialized()
    if started_here:
        ray.init(address=address, include_dashboard=False, log_to_driver=False,
                 configure_logging=False, runtime_env=_runtime_env())  # fmt: skip
    try:
        tuner = tune.Tuner(
            tune.with_resources(trainable, {"cpu": sweep.cpus_per_trial}),
            param_space={
                "trial": tune.grid_search([t.to_data() for t in todo]),
                "root": str(out),
            },
            # One worker process runs trial after trial (it imports mitlc and torch once).
            tune_config=tune.TuneConfig(trial_dirname_creator=_dirname, reuse_actors=True),
            run_config=tune.RunConfig(
                name=sweep.name,
                storage_path=str(out / "ray"),
                failure_config=tune.FailureConfig(max_failures=sweep.max_failures),
                verbose=0,
                callbacks=[_events(on_event)],
            ),
        )
        grid = tuner.fit()
    finally:
        if started_here:
            ray.shutdown()
    failed = []
    for index in range(len(grid)):
        result: Any = grid[index]
        if result.error is not None and result.config is not None:
            failed.append(Trial.from_data(result.config["trial"]).trial_id)
    return failed


def _dirname(trial: Any) -> str:
    """Tune's directory of a trial: the trial's id (Tune's own names spell the config)."""
    return Trial.from_data(trial.config["trial"]).trial_id


def _runtime_env() -> dict[str, Any]:
    """Workers import mitlc from where this process does (a checkout, not installed)."""
    import mitlc

    root = str(Path(mitlc.__file__).resolve().parents[1])
    paths = [root, *[p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]]
    return {"env_vars": {"PYTHONPATH": os.pathsep.join(dict.fromkeys(paths))}}


def _events(on_event: Callable[[Event], None] | None) -> Any:
    """A Tune callback telling ``on_event`` what happens to each trial."""
    from ray import tune

    def tell(kind: str, trial: Any) -> None:
        if on_event is not None:
            on_event(Event(kind, Trial.from_data(trial.config["trial"]).trial_id))

    class Events(tune.Callback):
        def on_trial_start(self, iteration: int, trials: Any, trial: Any, **info: Any) -> None:
            tell("start", trial)

        def on_trial_complete(self, iteration: int, trials: Any, trial: Any, **info: Any) -> None:
            tell("done", trial)

        def on_trial_error(self, iteration: int, trials: Any, trial: Any, **info: Any) -> None:
            tell("error", trial)

        def on_trial_recover(self, iteration: int, trials: Any, trial: Any, **info: Any) -> None:
            tell("retry", trial)

    return Events()
