"""A sweep's scores, as the report and its figures read them: which worlds have an exact
optimum, each setting's normalised scores over them, and rliable's random draws kept quiet and
seeded."""

from __future__ import annotations

import contextlib
import warnings
from collections.abc import Iterator
from typing import Any

import numpy as np

TAUS = np.linspace(0.0, 1.0, 101)
"""The thresholds of the performance profile."""


@contextlib.contextmanager
def quiet(seed: int | None = None) -> Iterator[None]:
    """arch's FutureWarning on rliable's ``random_state`` silenced (library code warns no one)
    and, with ``seed``, numpy's global generator seeded meanwhile and then put back: rliable's
    stratified bootstrap draws its resamples from it (``np.random.choice``), whatever
    ``random_state`` says."""
    state = np.random.get_state()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", FutureWarning)
            if seed is not None:
                np.random.seed(seed)
            yield
    finally:
        np.random.set_state(state)


def has_optimum(settings: dict[str, dict[int, dict[str, Any]]]) -> bool:
    """Whether every trial of a world (its ``settings``) has an exact optimum (0 included:
    a world where no policy succeeds has one)."""
    return all(r.get("optimum") is not None for runs in settings.values() for r in runs.values())


def normalised(
    by_world: dict[str, dict[str, dict[int, dict[str, Any]]]],
) -> dict[str, np.ndarray[Any, Any]]:
    """Each setting's scores (seeds x worlds) over the worlds with an exact optimum that it
    ran on all of, and the seeds it has on each of them."""
    exact = {w: s for w, s in by_world.items() if has_optimum(s)}
    names = sorted({name for s in exact.values() for name in s})
    scores = {}
    for name in names:
        on = [w for w in sorted(exact) if name in exact[w]]
        if len(on) != len(exact) or not on:
            continue
        seeds = sorted(set.intersection(*(set(exact[w][name]) for w in on)))
        if seeds:
            scores[name] = np.array([[exact[w][name][s]["score"] for w in on] for s in seeds])
    return scores
