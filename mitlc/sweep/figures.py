"""The figures of a sweep's report: the performance profile and the learning curves, each with
its 95% stratified bootstrap band (rliable), as PNG bytes."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from mitlc.inputs import MAX_METRICS_BYTES, read_lines_capped
from mitlc.learn.plots.common import png_bytes
from mitlc.sweep.spec import SweepError
from mitlc.sweep.trial import TRIALS

CURVE_REPS = 1000
"""Bootstrap resamples per learning curve."""
MAX_POINTS = 50
"""The most logged points a learning curve is drawn through (evenly spaced)."""


def iqm_per_point(scores: np.ndarray[Any, Any]) -> np.ndarray[Any, Any]:
    """The IQM over runs and tasks of ``scores`` (runs x tasks x points) at each point
    (:func:`mitlc.sweep.stats.iqm` for every point at once)."""
    flat = np.sort(scores.reshape(-1, scores.shape[-1]), axis=0)
    cut = int(0.25 * len(flat))
    result: np.ndarray[Any, Any] = flat[cut : len(flat) - cut].mean(axis=0)
    return result


def performance_profile(
    by_world: dict[str, dict[str, dict[int, dict[str, Any]]]], seed: int
) -> bytes | None:
    """The fraction of runs (seeds x worlds with an exact optimum) whose success / optimum
    exceeds tau, per setting, with its band; ``None`` without such worlds."""
    from rliable import library as rly

    from mitlc.sweep.scores import TAUS, normalised, quiet

    scores = normalised(by_world)
    if not scores:
        return None
    with quiet(seed):  # create_performance_profile draws from numpy's global generator
        profiles, bands = rly.create_performance_profile(scores, TAUS)
    figure = Figure(figsize=(7.0, 4.2), dpi=100, layout="constrained")
    axes = figure.subplots()
    for name in sorted(profiles):
        line = axes.plot(TAUS, profiles[name], label=name)[0]
        axes.fill_between(TAUS, bands[name][0], bands[name][1], alpha=0.2,
                          color=line.get_color())  # fmt: skip
    axes.set_xlabel("success / exact optimum (tau)")
    axes.set_ylabel("fraction of runs with score > tau")
    axes.set_xlim(0, 1)
    axes.set_ylim(0, 1.02)
    axes.grid(alpha=0.3)
    axes.legend(fontsize=8)
    axes.set_title("Performance profile (95% stratified bootstrap bands)", fontsize=10)
    return png_bytes(figure)


def _curve(directory: Path, trial_id: str) -> tuple[list[float], list[float]]:
    """A trial's logged (episodes, training success rate)."""
    path = directory / TRIALS / trial_id / "metrics.jsonl"
    episodes: list[float] = []
    success: list[float] = []
    if not path.exists():
        return episodes, success
    try:
        for line in read_lines_capped(path, MAX_METRICS_BYTES, "a run's metrics"):
            try:
                row = json.loads(line.decode("utf-8"))
                episodes.append(float(row["episodes"]))
                success.append(float(row["success_rate"]))
            except (ValueError, KeyError, TypeError):
                continue
    except OSError as err:
        raise SweepError(f"{path}: {err.strerror or err}") from None
    return episodes, success


def learning_curves(
    directory: Path, by_world: dict[str, dict[str, dict[int, dict[str, Any]]]], seed: int
) -> bytes:
    """One panel per world: each setting's training success rate (the IQM over its seeds at
    each logged point, over the points every seed logged) with its band."""
    from rliable import library as rly

    from mitlc.sweep.scores import quiet

    count = max(len(by_world), 1)
    cols = min(count, 2)
    rows = math.ceil(count / cols)
    figure = Figure(figsize=(6.0 * cols, 3.6 * rows), dpi=100, layout="constrained")
    panels = np.atleast_1d(figure.subplots(rows, cols, squeeze=False).ravel())
    for axes, (world, settings) in zip(panels, sorted(by_world.items()), strict=False):
        for name, runs in sorted(settings.items()):
            curves = [_curve(directory, runs[s]["trial_id"]) for s in sorted(runs)]
            points = min((len(c[0]) for c in curves), default=0)
            if points == 0:
                continue
            keep = np.unique(np.linspace(0, points - 1, min(points, MAX_POINTS)).astype(int))
            x = np.median(np.array([np.take(c[0], keep) for c in curves]), axis=0)
            y = np.array([np.take(c[1], keep) for c in curves])[:, None, :]  # seeds x 1 x points

            with quiet(seed):
                middle, band = rly.get_interval_estimates(
                    {name: y}, iqm_per_point, reps=CURVE_REPS,
                    random_state=np.random.RandomState(seed),
                )  # fmt: skip
            line = axes.plot(x, middle[name], label=f"{name} ({len(curves)} seeds)")[0]
            axes.fill_between(x, band[name][0], band[name][1], alpha=0.2,
                              color=line.get_color())  # fmt: skip
        axes.set_title(world, fontsize=10)
        axes.set_xlabel("episodes")
        axes.set_ylabel("training success rate (IQM)")
        axes.set_ylim(0, 1.02)
        axes.grid(alpha=0.3)
        axes.legend(fontsize=7)
    for axes in panels[count:]:
        axes.set_visible(False)
    return png_bytes(figure)
