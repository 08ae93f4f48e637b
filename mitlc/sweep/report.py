"""The report of a sweep: ``report(directory)``, rliable's statistics over seeds.

Agarwal, Schwarzer, Castro, Courville and Bellemare, "Deep reinforcement learning at the edge
of the statistical precipice", NeurIPS 2021 (the ``rliable`` library): point estimates with 95%
stratified bootstrap confidence intervals (percentile method), over the seeds of each world
and setting (a learner and a grid point):

* the interquartile mean (IQM), the median and the mean of the scores, and the optimality gap
  (the mean shortfall below 1), as :mod:`mitlc.sweep.stats` computes rliable's metrics;
* the same across every world with an exact optimum, each world a task of the stratified
  bootstrap (settings run on all of them, over the seeds they share);
* the probability of improvement of each setting over each other, per world;
* a performance profile (the fraction of runs with a score above tau) with bands, and learning
  curves (the training success rate's IQM over seeds at each logged point) with bands.

A score is the trial's greedy success over the exact optimum of the same event (a true
ceiling of 1, see :mod:`mitlc.sweep.trial`), or, for a world without an exact optimum, the raw
success rate: the tables say which. Written into the directory: ``report.md`` (Markdown
tables), ``report.json`` (every figure), ``performance_profile.png`` and
``learning_curves.png``. The bootstrap draws from ``seed``, so a report is reproducible.
"""

from __future__ import annotations

import itertools
import json
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from mitlc.sweep import stats
from mitlc.sweep.scores import has_optimum, normalised, quiet
from mitlc.sweep.spec import SweepError
from mitlc.sweep.trial import RESULT, TRIALS, read_record

STATISTICS = ("iqm", "median", "mean", "optimality_gap")
REPORT_MD, REPORT_JSON = "report.md", "report.json"
PROFILE_PNG, CURVES_PNG = "performance_profile.png", "learning_curves.png"


@dataclass(frozen=True, slots=True)
class Report:
    """What :func:`report` wrote, and its figures (``data``, as in ``report.json``)."""

    files: tuple[Path, ...]
    data: dict[str, Any]


def interval_estimates(
    scores: dict[str, np.ndarray[Any, Any]], reps: int, seed: int
) -> dict[str, dict[str, list[float]]]:
    """For each setting's ``scores`` (runs x tasks): each statistic of :data:`STATISTICS`
    as ``[point, low, high]``, the 95% stratified bootstrap interval (rliable)."""
    from rliable import library as rly

    with quiet(seed):
        points, intervals = rly.get_interval_estimates(
            scores, stats.aggregates, reps=reps, random_state=np.random.RandomState(seed)
        )
    return {
        name: {
            stat: [
                float(points[name][k]),
                float(intervals[name][0][k]),
                float(intervals[name][1][k]),
            ]
            for k, stat in enumerate(STATISTICS)
        }
        for name in scores
    }


def improvement(
    x: np.ndarray[Any, Any], y: np.ndarray[Any, Any], reps: int, seed: int
) -> list[float]:
    """P(X > Y) of scores ``x`` over ``y`` (runs x tasks) with its 95% interval (rliable)."""
    from rliable import library as rly

    with quiet(seed):
        points, intervals = rly.get_interval_estimates(
            {"pair": (x, y)},
            stats.probability_of_improvement,
            reps=reps,
            random_state=np.random.RandomState(seed),
        )
    low, high = np.ravel(intervals["pair"])
    return [float(points["pair"]), float(low), float(high)]


def _results(directory: Path) -> list[dict[str, Any]]:
    trials = directory / TRIALS
    found = sorted(trials.glob(f"*/{RESULT}")) if trials.is_dir() else []
    if not found:
        raise SweepError(f"{directory}: no finished trials ({TRIALS}/*/{RESULT}): not a sweep "
                         "directory, or no trial has finished yet")  # fmt: skip
    results = []
    for path in found:
        try:
            data = read_record(path)
            float(data["score"])
            str(data["world_name"]), str(data["setting"]), int(data["seed"])
        except (OSError, ValueError, KeyError, TypeError) as err:
            raise SweepError(f"{path}: not a trial's result ({err})") from None
        results.append(data)
    return results


def report(directory: Path, *, reps: int = 2000, seed: int = 0) -> Report:
    """Compute and write the report of the sweep in ``directory`` (see the module docstring);
    ``reps`` and ``seed`` within the bounds of ``mitlc report``'s options
    (:data:`mitlc.learn.bounds.OPTIONS`), else an :class:`~mitlc.learn.bounds.OutOfRange`."""
    from mitlc.files import write_atomically
    from mitlc.learn.bounds import check_option

    check_option("report", "--reps", reps)
    check_option("report", "--seed", seed)
    directory = Path(directory)
    results = _results(directory)
    by_world: dict[str, dict[str, dict[int, dict[str, Any]]]] = defaultdict(
        lambda: defaultdict(dict)
    )
    for r in results:
        by_world[r["world_name"]][r["setting"]][int(r["seed"])] = r
    worlds: dict[str, Any] = {}
    for world, settings in sorted(by_world.items()):
        scores = {name: np.array([[runs[s]["score"]] for s in sorted(runs)])
                  for name, runs in sorted(settings.items())}  # fmt: skip
        kinds = {r["score_kind"] for runs in settings.values() for r in runs.values()}
        estimates = interval_estimates(scores, reps, seed)
        pairs = {
            f"{x} > {y}": improvement(scores[x], scores[y], reps, seed)
            for x, y in itertools.permutations(sorted(scores), 2)
        }
        worlds[world] = {
            "score_kind": " / ".join(sorted(kinds)),
            "settings": {
                name: {
                    "seeds": sorted(runs),
                    "scores": [runs[s]["score"] for s in sorted(runs)],
                    "rounds": [float(runs[s].get("mean_rounds", 0.0)) for s in sorted(runs)],
                    **estimates[name],
                }
                for name, runs in sorted(settings.items())
            },
            "probability_of_improvement": pairs,
        }
    overall = _across(by_world, reps, seed)
    data = {"worlds": worlds, "across_worlds": overall, "reps": reps, "seed": seed}
    files = [directory / REPORT_JSON, directory / REPORT_MD]
    write_atomically(files[0], (json.dumps(data, indent=2, sort_keys=True) + "\n").encode())
    write_atomically(files[1], markdown(data).encode())
    from mitlc.sweep.figures import learning_curves, performance_profile

    figure = performance_profile(by_world, seed)
    if figure is not None:
        write_atomically(directory / PROFILE_PNG, figure)
        files.append(directory / PROFILE_PNG)
    write_atomically(directory / CURVES_PNG, learning_curves(directory, by_world, seed))
    files.append(directory / CURVES_PNG)
    return Report(tuple(files), data)


def _across(
    by_world: dict[str, dict[str, dict[int, dict[str, Any]]]], reps: int, seed: int
) -> dict[str, Any]:
    scores = normalised(by_world)
    if not scores or len(by_world) < 2:
        return {}
    return {"worlds": sorted(w for w, settings in by_world.items() if has_optimum(settings)),
            "settings": interval_estimates(scores, reps, seed)}  # fmt: skip


def _cell(values: list[float]) -> str:
    point, low, high = values
    return f"{point:.3f} [{low:.3f}, {high:.3f}]"


def markdown(data: dict[str, Any]) -> str:
    """The report's tables in Markdown."""
    lines = ["# Sweep report", "",
             f"95% stratified bootstrap intervals (rliable, percentile, {data['reps']:,} "
             f"resamples, seed {data['seed']}).", ""]  # fmt: skip
    head = "| setting | seeds | IQM | median | mean | optimality gap |"
    for world, entry in data["worlds"].items():
        patrols = any(any(s.get("rounds", ())) for s in entry["settings"].values())
        extra = (" mean rounds per episode |", "---|") if patrols else ("", "")
        lines += [f"## {world}", "", f"Score: {entry['score_kind']}.", "", head + extra[0],
                  "|---|---|---|---|---|---|" + extra[1]]  # fmt: skip
        for name, s in entry["settings"].items():
            cells = " | ".join(_cell(s[stat]) for stat in STATISTICS)
            rounds = f" {np.mean(s['rounds']):.2f} |" if patrols else ""
            lines.append(f"| {name} | {len(s['seeds'])} | {cells} |{rounds}")
        if entry["probability_of_improvement"]:
            lines += ["", "| probability of improvement | P(X > Y) |", "|---|---|"]
            for pair, values in entry["probability_of_improvement"].items():
                lines.append(f"| {pair} | {_cell(values)} |")
        lines.append("")
    across = data["across_worlds"]
    if across:
        lines += ["## Across worlds", "",
                  f"Success / optimum, each of {', '.join(across['worlds'])} a task.", "",
                  "| setting | IQM | median | mean | optimality gap |",
                  "|---|---|---|---|---|"]  # fmt: skip
        for name, s in across["settings"].items():
            lines.append(f"| {name} | " + " | ".join(_cell(s[k]) for k in STATISTICS) + " |")
        lines.append("")
    return "\n".join(lines)
