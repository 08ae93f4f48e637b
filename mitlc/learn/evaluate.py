"""How good a learned policy is: ``evaluate(run_directory) -> Evaluation``.

The greedy policy runs ``episodes`` seeded episodes, one per slot of a :class:`VecProduct`
(each slot's first episode only, so short failures are not over-counted); its success rate
comes with a 95% Wilson score interval (Wilson, JASA 1927). Beside it stand the optimum of the
same event, :func:`mitlc.check.solve.pmax_horizon` on the product (for a POMDP the fully
observable value, an upper bound, and below it the exact success of an observation-based
policy, :func:`mitlc.check.observed.observed_bound`; Storm's belief bounds on request), and,
when the policy is
memoryless on an MDP's product (tabular Q, DQN), its exact success probability
(:func:`mitlc.learn.exact.policy_success`).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np

from mitlc.check.solve import pmax_horizon
from mitlc.learn.base import Policy
from mitlc.learn.exact import policy_success
from mitlc.learn.run import Setting, load_learner
from mitlc.learn.vec import VecProduct
from mitlc.limits import DEFAULT_TIME_LIMIT, Deadline, LimitError
from mitlc.worlds.model import IntArray

Z95 = 1.959963984540054
"""The standard normal quantile of 0.975."""


@runtime_checkable
class Memoryless(Protocol):
    """A policy that is a function of ``(frontier mask, product state)``."""

    def choices(self) -> IntArray:
        """``choices[mask, x]``: the product choice taken (-1 at the absorbing states)."""
        ...


def wilson(successes: int, trials: int, z: float = Z95) -> tuple[float, float]:
    """The Wilson score interval of a binomial proportion."""
    if trials <= 0:
        return 0.0, 1.0
    p = successes / trials
    denominator = 1.0 + z * z / trials
    centre = (p + z * z / (2 * trials)) / denominator
    half = z * math.sqrt(p * (1 - p) / trials + z * z / (4 * trials * trials)) / denominator
    return max(0.0, centre - half), min(1.0, centre + half)


@dataclass(frozen=True, slots=True)
class Evaluation:
    """A policy's measured and exact success beside the optimum."""

    world: str
    algo: str
    episodes: int
    successes: int
    mean_return: float
    exact: float | None
    """The policy's exact success probability (memoryless policies on MDPs)."""
    optimum: float | None
    """``pmax_horizon`` of the product (fully observable: an upper bound for a POMDP);
    ``None`` for a world that is not finite, which has none."""
    pomdp: bool
    bounds: dict[str, Any] | None
    seconds: float
    lower: float | None = None
    """For a POMDP: the exact success of the best observation-based policy found, a lower
    bound of the optimum (``None`` for an MDP, or where the search does not apply)."""

    @property
    def success_rate(self) -> float:
        """Successes over episodes."""
        return self.successes / self.episodes if self.episodes else 0.0

    @property
    def interval(self) -> tuple[float, float]:
        """The 95% Wilson interval of the success rate."""
        return wilson(self.successes, self.episodes)

    def _optimum_kind(self) -> str:
        if self.optimum is None:
            return "none: this world is not finite (no exact optimum)"
        return "fully observable upper bound" if self.pomdp else "exact"

    def summary(self) -> dict[str, Any]:
        """JSON-ready data."""
        low, high = self.interval
        data: dict[str, Any] = {
            "world": self.world,
            "algo": self.algo,
            "episodes": self.episodes,
            "successes": self.successes,
            "success_rate": self.success_rate,
            "interval95": [low, high],
            "mean_return": self.mean_return,
            "exact": self.exact,
            "optimum": self.optimum,
            "optimum_kind": self._optimum_kind(),
            "ratio": self.success_rate / self.optimum if self.optimum else None,
            "seconds": round(self.seconds, 3),
        }
        if self.exact is not None and self.optimum:
            data["exact_ratio"] = self.exact / self.optimum
        if self.bounds is not None:
            data["bounds"] = self.bounds
        if self.lower is not None:
            data["lower_bound"] = self.lower
            data["lower_ratio"] = self.success_rate / self.lower if self.lower > 0 else None
        return data


def _plane_evaluation(directory: Path, episodes: int | None, seed: int) -> Evaluation:
    """The run of a world that is not finite: greedy episodes in its wrapped envs, no
    optimum."""
    from mitlc.learn.plane_run import monte_carlo_open
    from mitlc.learn.run import load_open_learner

    start = time.perf_counter()
    setting, learner = load_open_learner(directory)
    count = episodes if episodes is not None else setting.config.eval_episodes
    successes, mean_return = monte_carlo_open(setting, learner.policy(), count, seed)
    return Evaluation(
        world=setting.world.name,
        algo=setting.config.algo,
        episodes=count,
        successes=successes,
        mean_return=mean_return,
        exact=None,
        optimum=None,
        pomdp=setting.world.is_pomdp,
        bounds=None,
        seconds=time.perf_counter() - start,
    )


def monte_carlo(setting: Setting, policy: Policy, episodes: int, seed: int) -> tuple[int, float]:
    """Successes and mean return of ``episodes`` greedy episodes, one per slot."""
    env = VecProduct(setting.tables, episodes, np.random.default_rng(seed))
    policy.reset(episodes)
    finished = np.zeros(episodes, dtype=bool)
    success = np.zeros(episodes, dtype=bool)
    returns = np.zeros(episodes)
    while not finished.all():
        step = env.step(policy.act(env))
        policy.observe(step)
        first = step.done & ~finished
        success[first] = step.success[first]
        returns[first] = step.episode_return[first]
        finished |= step.done
    return int(success.sum()), float(returns.mean())


def evaluate(
    directory: str | Path,
    *,
    episodes: int | None = None,
    seed: int = 12345,
    pomdp_bounds: bool = False,
    deadline: Deadline | None = None,
) -> Evaluation:
    """Evaluate the run in ``directory`` (its last checkpoint); ``episodes`` defaults to the
    run's ``eval_episodes``. ``pomdp_bounds`` asks Storm for belief bounds (slow on big
    worlds; needs stormpy). The set-up and the exact figures stop at ``deadline`` (by default
    :data:`~mitlc.limits.DEFAULT_TIME_LIMIT` seconds); the POMDP bounds are left out when the
    time runs out during them."""
    from mitlc.learn.run import is_open_run

    if is_open_run(Path(directory)):
        return _plane_evaluation(Path(directory), episodes, seed)
    start = time.perf_counter()
    clock = Deadline.of(deadline, DEFAULT_TIME_LIMIT, "evaluation")
    setting, learner = load_learner(Path(directory), deadline=clock)
    count = episodes if episodes is not None else setting.config.eval_episodes
    policy = learner.policy()
    successes, mean_return = monte_carlo(setting, policy, count, seed)
    horizon = setting.world.horizon
    optimum, _ = pmax_horizon(
        setting.product, horizon, keep_history=False, deadline=clock.at("pmax_horizon")
    )
    exact = None
    if not setting.world.is_pomdp and isinstance(policy, Memoryless):
        exact = policy_success(setting.product, policy.choices(), horizon)
    bounds, lower = None, None
    if setting.world.is_pomdp:
        from mitlc.check.observed import ObservedBoundError, observed_bound

        try:
            stage = clock.at("the observation-based bound")
            found = observed_bound(setting.world, setting.product, horizon=horizon, deadline=stage)
            lower = found.value
        except (ObservedBoundError, LimitError):
            lower = None
    if setting.world.is_pomdp and pomdp_bounds:
        from mitlc.check.pomdp import pomdp_bounds as storm_bounds

        try:
            bounds = storm_bounds(
                setting.world, setting.automaton, horizon_success=True, deadline=clock
            )
        except LimitError:
            bounds = None
    return Evaluation(
        world=setting.world.name,
        algo=setting.config.algo,
        episodes=count,
        successes=successes,
        mean_return=mean_return,
        exact=exact,
        optimum=optimum,
        pomdp=setting.world.is_pomdp,
        bounds=bounds,
        seconds=time.perf_counter() - start,
        lower=lower,
    )
