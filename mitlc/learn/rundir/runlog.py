"""What every training run (mitlc's learners or a backend's) keeps and writes as it goes: its
counters (:class:`Tally`), a ``metrics.jsonl`` line per window (:func:`log_window`), its
progress for a display (:class:`Progress`), its result (:class:`RunResult`)."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from mitlc.files import write_atomically
from mitlc.learn.config import TrainConfig
from mitlc.learn.rundir.files import read_metrics_rows


@dataclass(frozen=True, slots=True)
class Progress:
    """Where a run stands, for a progress display."""

    episodes: int
    total: int
    steps: int
    success_rate: float
    """Over the episodes since the last metrics line (or the last line's, right after one)."""
    mean_return: float
    epsilon: float
    seconds: float


@dataclass(frozen=True, slots=True)
class RunResult:
    """A finished (or stopped) run."""

    directory: Path
    config: TrainConfig
    episodes: int
    steps: int
    seconds: float
    stopped: bool
    """The caller asked the run to stop before its episodes were done."""
    never_held: tuple[str, ...] = ()
    """The task's propositions that no letter read in the run made true (worlds learned
    through the task wrapper; :mod:`mitlc.learn.held`)."""


class Tally:
    """Episodes, steps and the current metrics window."""

    def __init__(self) -> None:
        self.episodes = self.steps = 0
        self.window_count = self.window_success = 0
        self.window_return = 0.0
        self.last_rate = self.last_return = 0.0
        self.seconds = 0.0
        # Over the whole run: episodes that ended violated; with a shield, the actions taken
        # that it blocks and the violated episodes that took one (runs saved before: 0).
        self.violations = self.blocked = self.preventable = 0
        self.shielded = False
        self.window_cost = 0.0
        self.costed = False
        self.window_rounds = 0.0

    def count(self, step: Any) -> None:
        """Add the violations, and with a shield the blocked actions, of a step (a
        :class:`~mitlc.learn.envs.vec.Step` or an open world's)."""
        violated = step.terminated & ~step.success
        self.violations += int(violated.sum())
        paid = getattr(step, "episode_cost", None)
        if paid is not None:
            self.costed = True
            self.window_cost += float(paid[step.done].sum())
        rounds = getattr(step, "episode_rounds", None)
        if rounds is not None:
            self.window_rounds += float(np.asarray(rounds)[step.done].sum())
        if getattr(step, "blocked", None) is not None:
            self.shielded = True
            self.blocked += int(step.blocked.sum())
            self.preventable += int((violated & step.strayed).sum())

    def state_dict(self) -> dict[str, Any]:
        return dict(vars(self))

    def load_state_dict(self, saved: dict[str, Any]) -> None:
        counts = ("episodes", "steps", "window_count", "window_success")
        if any(saved[name] < 0 for name in counts):
            raise ValueError(f"negative counts among {', '.join(counts)}")
        vars(self).update(saved)


def log_window(metrics: Any, tally: Tally, epsilon: float) -> None:
    if tally.window_count:
        tally.last_rate = tally.window_success / tally.window_count
        tally.last_return = tally.window_return / tally.window_count
    line = {
        "episodes": tally.episodes,
        "steps": tally.steps,
        "success_rate": round(tally.last_rate, 6),
        "return": round(tally.last_return, 6),
        "epsilon": round(epsilon, 6),
        "seconds": round(tally.seconds, 3),
        "violations": tally.violations,
    }
    if tally.costed:
        line["cost"] = round(tally.window_cost / max(tally.window_count, 1), 6)
    line["rounds"] = round(tally.window_rounds / max(tally.window_count, 1), 6)
    if tally.shielded:
        line["blocked_actions"] = tally.blocked
        line["preventable_violations"] = tally.preventable
    metrics.write(json.dumps(line) + "\n")
    metrics.flush()
    tally.window_count = tally.window_success = 0
    tally.window_return = tally.window_cost = tally.window_rounds = 0.0


def summary_of(
    tally: Tally, shield: dict[str, Any] | None, unseen: tuple[str, ...]
) -> dict[str, Any]:
    """A finished run's ``summary.json``, for every learner: its counts and last window, the
    violations, with a shield its guarantees (``shield``: its summary) and the blocked actions
    and preventable violations, and the propositions ``unseen`` in training."""
    summary: dict[str, Any] = {
        "episodes": tally.episodes,
        "steps": tally.steps,
        "seconds": round(tally.seconds, 3),
        "success_rate": tally.last_rate,
        "mean_return": tally.last_return,
        "violations": tally.violations,
    }
    if tally.shielded:
        summary["shield"] = shield
        summary["blocked_actions"] = tally.blocked
        summary["preventable_violations"] = tally.preventable
    if unseen:
        summary["never_held"] = list(unseen)
    return summary


def progress_of(tally: Tally, total: int, epsilon: float) -> Progress:
    rate, mean = tally.last_rate, tally.last_return
    if tally.window_count:
        rate = tally.window_success / tally.window_count
        mean = tally.window_return / tally.window_count
    return Progress(tally.episodes, total, tally.steps, rate, mean, epsilon, tally.seconds)


def write_json(path: Path, data: Any) -> None:
    """``data`` as indented, sorted JSON, written atomically."""
    write_atomically(path, (json.dumps(data, indent=2, sort_keys=True) + "\n").encode())


def truncate_metrics(path: Path, episodes: int) -> None:
    """Drop lines written after the checkpoint a resumed run starts from."""
    if not path.exists():
        return
    kept = [row for row in read_metrics_rows(path) if row["episodes"] <= episodes]
    write_atomically(path, "".join(json.dumps(row) + "\n" for row in kept).encode())
