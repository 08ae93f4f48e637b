"""What every figure of a run shares: the file names, the learning curve, PNG bytes.

Figures are drawn on :class:`matplotlib.figure.Figure` directly (no pyplot, no display) at a
fixed size and resolution, without the PNG's software tag, so the same run gives the same
bytes.
"""

from __future__ import annotations

from dataclasses import dataclass
from io import BytesIO
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import FuncFormatter

from mitlc.learn.rundir.files import METRIC_FIELDS, METRICS, RunError, read_metrics_rows
from mitlc.worlds.model import FloatArray

LEARNING_CURVE, TRAJECTORIES, AUTOMATON = "learning_curve.png", "trajectories.png", "automaton.png"
EPISODE = "episode.gif"
DPI = 100
CURVE_SIZE = (8.0, 6.0)
"""Inches; at :data:`DPI`, an 800x600 PNG."""


class PlotError(RunError):
    """A run that cannot be drawn: no metrics yet, or a world file that no longer fits it."""


@dataclass(frozen=True, slots=True)
class Metrics:
    """The columns of ``metrics.jsonl``, one entry per logged window."""

    episodes: FloatArray
    success_rate: FloatArray
    mean_return: FloatArray
    epsilon: FloatArray
    violations: FloatArray | None = None
    """The training episodes ended violated so far (runs that record them: all lines)."""
    rounds: FloatArray | None = None
    """The mean rounds of the acceptance sets completed per episode of each window (a
    recurring task's patrols, docs/episodes.md; ``None`` where no line has any)."""


def read_metrics(directory: Path) -> Metrics:
    """The run's metrics; a last line cut short (a killed run) is left out. :class:`PlotError`
    when the file is missing or has no complete line, :class:`RunError` when a line is bad."""
    path = directory / METRICS
    if not path.exists():  # a FIFO or a device there is refused by read_metrics_rows
        raise PlotError(f"{directory}: no {METRICS} (not a run directory, or not started)")
    read = read_metrics_rows(path)
    rows = [[row[name] for name in METRIC_FIELDS] for row in read]
    if not rows:
        raise PlotError(f"{path}: no metrics yet (the run has not logged a window)")
    columns = np.asarray(rows, dtype=np.float64).T
    counts = [row.get("violations") for row in read]
    violations = None
    if all(isinstance(c, int) and not isinstance(c, bool) and c >= 0 for c in counts):
        violations = np.asarray(counts, dtype=np.float64)
    rounds = [row.get("rounds") for row in read]
    patrols = None
    if all(isinstance(r, int | float) and not isinstance(r, bool) for r in rounds):
        found = np.asarray(rounds, dtype=np.float64)
        patrols = found if found.any() else None
    return Metrics(columns[0], columns[1], columns[2], columns[3], violations, patrols)


def png_bytes(figure: Figure) -> bytes:
    """``figure`` as PNG bytes (fixed dpi, no software tag)."""
    buffer = BytesIO()
    figure.savefig(buffer, format="png", dpi=DPI, metadata={"Software": None})
    return buffer.getvalue()


# --- the learning curve ------------------------------------------------------------------------


def learning_curve(metrics: Metrics, title: str) -> Figure:
    """Success rate (with epsilon, and a recurring task's rounds per episode) above, mean
    return below, against the episodes."""
    figure = Figure(figsize=CURVE_SIZE, dpi=DPI, layout="constrained")
    top, bottom = figure.subplots(2, 1, sharex=True)
    marker = "o" if len(metrics.episodes) <= 60 else None
    top.plot(
        metrics.episodes,
        metrics.success_rate,
        color="tab:green",
        marker=marker,
        markersize=3,
        label="success rate",
    )
    top.plot(
        metrics.episodes, metrics.epsilon, color="0.55", linestyle="--", label="ε (exploration)"
    )
    top.set_ylim(-0.02, 1.02)
    top.set_ylabel("success rate")
    top.legend(loc="lower right", frameon=False)
    if metrics.rounds is not None:  # a recurring task: its patrols beside its success
        rounds = top.twinx()
        rounds.plot(metrics.episodes, metrics.rounds, color="tab:purple", linestyle="-.")
        rounds.set_ylabel("rounds per episode (dash-dot)", color="tab:purple")
        rounds.set_ylim(bottom=0)
        rounds.spines[["top"]].set_visible(False)
    bottom.plot(
        metrics.episodes, metrics.mean_return, color="tab:blue", marker=marker, markersize=3
    )
    bottom.set_ylabel("mean return per episode")
    if metrics.violations is not None:
        right = bottom.twinx()
        right.plot(metrics.episodes, metrics.violations, color="tab:red", linestyle=":")
        right.set_ylabel("violations so far (dotted)", color="tab:red")
        right.spines[["top"]].set_visible(False)
    bottom.set_xlabel("episodes")
    bottom.xaxis.set_major_formatter(FuncFormatter(lambda x, _: f"{x:,.0f}"))
    for axes in (top, bottom):
        axes.grid(True, color="0.9")
        axes.spines[["top", "right"]].set_visible(False)
    last = (
        f"last window: success {metrics.success_rate[-1]:.3f}, return {metrics.mean_return[-1]:.1f}"
    )
    if metrics.rounds is not None:
        last += f", rounds {metrics.rounds[-1]:.2f}"
    figure.suptitle(f"{title}\n{last}", fontsize=12)
    return figure
