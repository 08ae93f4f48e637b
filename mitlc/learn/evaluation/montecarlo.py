"""The one Monte-Carlo estimate of a policy's success, for every kind of world:
``monte_carlo(batches, policy, episodes) -> Estimate``.

``episodes`` slots each run to the end of their *first* episode only, and every slot counts
once: the estimate is the mean of ``episodes`` independent episodes, so it is unbiased. (To
count instead the first ``episodes`` episodes to *end* over a few parallel envs favours the
outcomes that end early: quick failures of a safety task, quick successes of a reachability
task. That is the length-biased sampling of renewal theory; it vanishes only when each env has
run many episodes.) The success rate comes with its 95% Wilson score interval (Wilson, JASA
1927) and the mean return of the same episodes.

The slots come in batches of at most ``width`` from ``batches(count, first)``, a fresh batch
whose slot ``i`` is episode ``first + i``: any :class:`mitlc.learn.learners.base.Episodes`, the
common
interface of mitlc's simulator of a finite product (:class:`mitlc.learn.envs.vec.VecProduct`,
:func:`mitlc.learn.setting.batches`) and of a vector of task-wrapped gymnasium envs
(:class:`mitlc.learn.envs.envvec.VectorTask`, the same function); each
steps all its slots at once and reports a :class:`mitlc.learn.envs.vec.Step` (``done``,
``success``, ``episode_return``) describing the episodes *before* ended ones restart.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from mitlc.learn.learners.base import Episodes, Policy
from mitlc.worlds.model import BoolArray, FloatArray

Z95 = 1.959963984540054
"""The standard normal quantile of 0.975."""
WIDTH = 1024
"""The most slots stepped together (a bound on memory, not on the estimate)."""


def wilson(successes: int, trials: int, z: float = Z95) -> tuple[float, float]:
    """The Wilson score interval of a binomial proportion (Wilson, JASA 1927): the ``p`` whose
    normal test ``|successes / trials - p| <= z sqrt(p (1 - p) / trials)`` accepts; ``(0, 1)``
    without trials. Its ends are exactly 0 at no success and 1 at no failure (as the formula
    is, without rounding)."""
    if trials <= 0:
        return 0.0, 1.0
    p = successes / trials
    denominator = 1.0 + z * z / trials
    centre = (p + z * z / (2 * trials)) / denominator
    half = z * math.sqrt(p * (1 - p) / trials + z * z / (4 * trials * trials)) / denominator
    low = 0.0 if successes <= 0 else max(0.0, centre - half)
    high = 1.0 if successes >= trials else min(1.0, centre + half)
    return low, high


@dataclass(frozen=True, slots=True)
class Estimate:
    """Successes among ``trials`` independent episodes and their mean return."""

    successes: int
    trials: int
    mean_return: float
    mean_cost: float | None = None
    """The episodes' mean cost, in a world with costs (``None`` otherwise)."""
    mean_rounds: float = 0.0
    """The episodes' mean number of completed rounds of the acceptance sets (recurring tasks:
    docs/episodes.md; 0 for a task without acceptance sets)."""

    @property
    def rate(self) -> float:
        """Successes over trials (0 without trials)."""
        return self.successes / self.trials if self.trials else 0.0

    @property
    def interval(self) -> tuple[float, float]:
        """The 95% Wilson score interval of the success probability."""
        return wilson(self.successes, self.trials)


class Batches(Protocol):
    """A maker of fresh batches of episodes, reproducible from the seed it was made with."""

    def __call__(self, count: int, first: int) -> Episodes:
        """``count`` fresh slots, slot ``i`` being episode ``first + i`` of the estimate."""
        ...


Progress = Callable[[int], None]
"""Told the episodes of the estimate that have ended so far, as they end."""


def first_episodes(
    batch: Episodes, policy: Policy, progress: Progress | None = None
) -> tuple[BoolArray, FloatArray, FloatArray | None, FloatArray]:
    """Step every slot of ``batch`` with ``policy`` until each has ended an episode; the
    success, the return, (where the steps have costs) the cost and the completed rounds of
    each slot's first episode (later ones are not counted). ``progress`` is told how many
    slots have ended, after each step that ends one."""
    n = batch.num_envs
    policy.reset(n)
    ended = np.zeros(n, dtype=np.bool_)
    success = np.zeros(n, dtype=np.bool_)
    returns = np.zeros(n, dtype=np.float64)
    costs: FloatArray | None = None
    rounds = np.zeros(n, dtype=np.float64)
    while not ended.all():
        step = batch.step(policy.act(batch))
        policy.observe(step)
        first = step.done & ~ended
        success[first] = step.success[first]
        returns[first] = step.episode_return[first]
        paid = getattr(step, "episode_cost", None)
        if paid is not None:
            costs = np.zeros(n) if costs is None else costs
            costs[first] = paid[first]
        counted = getattr(step, "episode_rounds", None)
        if counted is not None:
            rounds[first] = np.asarray(counted)[first]
        ended |= step.done
        if progress is not None and first.any():
            progress(int(ended.sum()))
    return success, returns, costs, rounds


def monte_carlo(
    batches: Batches,
    policy: Policy,
    episodes: int,
    *,
    width: int = WIDTH,
    progress: Progress | None = None,
) -> Estimate:
    """The success of ``policy`` over ``episodes`` independent episodes, each slot's first
    (see the module docstring), ``width`` slots at a time; ``progress`` is told how many of
    the ``episodes`` have ended, as they end."""
    if width < 1:
        raise ValueError(f"width: expected a positive integer, got {width}")
    successes, total, cost, completed = 0, 0.0, None, 0.0
    for first in range(0, episodes, width):
        told = None if progress is None else _offset(progress, first)
        success, returns, costs, rounds = first_episodes(
            batches(min(width, episodes - first), first), policy, told
        )
        successes += int(success.sum())
        total += float(returns.sum())
        completed += float(rounds.sum())
        if costs is not None:
            cost = (cost or 0.0) + float(costs.sum())
    count = max(episodes, 1)
    mean_cost = None if cost is None else cost / count
    mean_return = total / count if episodes > 0 else 0.0
    return Estimate(successes, max(episodes, 0), mean_return, mean_cost, completed / count)


def _offset(progress: Progress, first: int) -> Progress:
    """``progress`` told a batch's ended slots as episodes of the whole estimate."""
    return lambda ended: progress(first + ended)
