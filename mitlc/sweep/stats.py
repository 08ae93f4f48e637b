"""rliable's aggregate metrics written in numpy alone, for the bootstrap's many resamples.

rliable computes the IQM with ``scipy.stats.trim_mean`` and the probability of improvement
with ``scipy.stats.mannwhitneyu``, whose per-call overhead (about half a millisecond) makes a
report of a few settings take minutes at thousands of resamples. These are the same
definitions (Agarwal et al., NeurIPS 2021; ``rliable.metrics``), checked equal to rliable's on
fixed scores in ``tests/test_sweep.py``; the bootstrap itself is rliable's
(``rliable.library.get_interval_estimates``). ``scores`` is a (runs x tasks) array.
"""

from __future__ import annotations

from typing import Any

import numpy as np

Array = np.ndarray[Any, Any]


def iqm(scores: Array) -> float:
    """The interquartile mean: the mean of all scores with the lowest and highest quarter
    (``int(0.25 n)`` each) left out (``scipy.stats.trim_mean(scores, 0.25, axis=None)``)."""
    flat = np.sort(np.ravel(scores))
    cut = int(0.25 * len(flat))
    return float(np.mean(flat[cut : len(flat) - cut]))


def median(scores: Array) -> float:
    """The median over tasks of each task's mean score."""
    return float(np.median(np.mean(scores, axis=0)))


def mean(scores: Array) -> float:
    """The mean over tasks of each task's mean score."""
    return float(np.mean(np.mean(scores, axis=0)))


def optimality_gap(scores: Array, gamma: float = 1.0) -> float:
    """How far the scores fall below ``gamma`` on average (scores above it count as
    ``gamma``)."""
    return float(gamma - np.mean(np.minimum(scores, gamma)))


def aggregates(scores: Array) -> Array:
    """IQM, median, mean and optimality gap of ``scores``."""
    return np.array([iqm(scores), median(scores), mean(scores), optimality_gap(scores)])


def probability_of_improvement(scores_x: Array, scores_y: Array) -> float:
    """P(X > Y) averaged over tasks: per task, the share of (run of X, run of Y) pairs where
    X scores higher, ties counting half (the Mann-Whitney U statistic over the pairs), and
    0.5 where the two runs' scores are the same arrays."""
    values = []
    for task in range(scores_x.shape[1]):
        x, y = scores_x[:, task], scores_y[:, task]
        if np.array_equal(x, y):
            values.append(0.5)
            continue
        greater = (x[:, None] > y[None, :]).sum()
        ties = (x[:, None] == y[None, :]).sum()
        values.append((greater + 0.5 * ties) / (len(x) * len(y)))
    return float(np.mean(values))
