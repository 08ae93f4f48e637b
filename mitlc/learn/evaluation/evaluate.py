"""How good a learned policy is: ``evaluate(run_directory) -> Evaluation``.

The greedy policy runs ``episodes`` seeded episodes through the one Monte-Carlo estimate of
every kind of world, :func:`mitlc.learn.evaluation.montecarlo.monte_carlo` (each slot's first
episode
only, so short episodes are not over-counted): in mitlc's simulator of a finite product or in
the wrapped envs of a world that is not finite (:func:`mitlc.learn.setting.batches`). Its
success rate comes with a 95% Wilson score interval (Wilson, JASA 1927). Beside it stand, for a
finite world, the optimum of the same
event, :func:`mitlc.check.solve.pmax_horizon` on the product (for a POMDP the fully observable
value, an upper bound, and below it the exact success of an observation-based policy,
:func:`mitlc.check.observed.observed_bound`; Storm's belief bounds on request), and, when the
policy is memoryless on an MDP's product (tabular Q, DQN), its exact success probability
(:func:`mitlc.learn.evaluation.exact.policy_success`).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np

from mitlc.check.costs import least_cost
from mitlc.check.shield import Shield
from mitlc.check.solve import pmax_horizon
from mitlc.learn.envs.vec import Tables
from mitlc.learn.evaluation.exact import policy_success
from mitlc.learn.evaluation.montecarlo import monte_carlo, wilson
from mitlc.learn.held import HeldLog, never_held
from mitlc.learn.run import load_learner
from mitlc.learn.setting import Setting, batches
from mitlc.limits import DEFAULT_TIME_LIMIT, Deadline, LimitError
from mitlc.product.costs import choice_costs
from mitlc.worlds.model import BoolArray, IntArray


@runtime_checkable
class Memoryless(Protocol):
    """A policy that is a function of ``(frontier mask, product state)``."""

    def choices(self, valid: BoolArray | None = None) -> IntArray:
        """``choices[mask, x]``: the product choice taken (-1 at the absorbing states) among
        the actions ``valid[mask, x, a]`` (default: every valid one)."""
        ...


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
    never_held: tuple[str, ...] = ()
    """The task's propositions that no letter read in the evaluation made true (worlds
    evaluated through the task wrapper; :mod:`mitlc.learn.held`)."""
    mean_cost: float | None = None
    """In a world with costs: the episodes' mean cost (Monte-Carlo)."""
    min_cost: float | None = None
    """In a finite world with costs: the least expected cost among the policies of best
    success within the horizon (``mitlc check``'s ``min_cost_horizon``)."""
    mean_rounds: float = 0.0
    """The episodes' mean number of completed rounds (docs/episodes.md)."""

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
        """JSON-ready data. The ratios to the optimum are ``None`` where it is ``None`` (no
        exact optimum) or 0 (an exact optimum that no policy exceeds: the ratio is 0 / 0)."""
        low, high = self.interval
        positive = self.optimum if self.optimum is not None and self.optimum > 0 else None
        data: dict[str, Any] = {
            "world": self.world,
            "algo": self.algo,
            "episodes": self.episodes,
            "successes": self.successes,
            "success_rate": self.success_rate,
            "interval95": [low, high],
            "mean_return": self.mean_return,
            "mean_rounds": self.mean_rounds,
            **({"mean_cost": self.mean_cost} if self.mean_cost is not None else {}),
            **({"min_cost_horizon": self.min_cost} if self.min_cost is not None else {}),
            "exact": self.exact,
            "optimum": self.optimum,
            "optimum_kind": self._optimum_kind(),
            "ratio": self.success_rate / positive if positive is not None else None,
            "seconds": round(self.seconds, 3),
        }
        if self.exact is not None and positive is not None:
            data["exact_ratio"] = self.exact / positive
        if self.bounds is not None:
            data["bounds"] = self.bounds
        if self.never_held:
            data["never_held"] = list(self.never_held)
        if self.lower is not None:
            data["lower_bound"] = self.lower
            data["lower_ratio"] = self.success_rate / self.lower if self.lower > 0 else None
        return data


def evaluate(
    directory: str | Path,
    *,
    episodes: int | None = None,
    seed: int = 12345,
    pomdp_bounds: bool = False,
    deadline: Deadline | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> Evaluation:
    """Evaluate the run in ``directory`` (its last checkpoint), of any world; ``episodes``
    defaults to the run's ``eval_episodes``. The Monte-Carlo estimate is the one of every world
    (:func:`mitlc.learn.evaluation.montecarlo.monte_carlo` over
    :func:`mitlc.learn.setting.batches`); a
    finite world adds its optimum and, for a memoryless policy on an MDP, the policy's exact
    success. ``pomdp_bounds`` asks Storm for belief bounds (slow on big worlds; needs
    stormpy). The set-up and the exact figures stop at ``deadline`` (by default
    :data:`~mitlc.limits.DEFAULT_TIME_LIMIT` seconds); the POMDP bounds are left out when the
    time runs out during them. ``progress`` is told the episodes ended and the episodes in all,
    as they end."""
    start = time.perf_counter()
    clock = Deadline.of(deadline, DEFAULT_TIME_LIMIT, "evaluation")
    setting, learner = load_learner(Path(directory), deadline=clock)
    count = episodes if episodes is not None else setting.config.eval_episodes
    policy = learner.policy()
    log = HeldLog()
    told = None if progress is None else (lambda ended: progress(ended, count))
    if progress is not None:
        progress(0, count)
    estimate = monte_carlo(log.track(batches(setting, seed)), policy, count, progress=told)
    unseen = () if setting.finite else never_held(setting.automaton.propositions, log.held())
    optimum, exact, bounds, lower, min_cost = None, None, None, None, None
    if setting.finite:
        optimum, exact, bounds, lower, min_cost = _exact(setting, policy, pomdp_bounds, clock)
    return Evaluation(
        world=setting.world.name,
        algo=setting.config.algo,
        episodes=estimate.trials,
        successes=estimate.successes,
        mean_return=estimate.mean_return,
        mean_cost=estimate.mean_cost,
        mean_rounds=estimate.mean_rounds,
        min_cost=min_cost,
        exact=exact,
        optimum=optimum,
        pomdp=setting.world.is_pomdp,
        bounds=bounds,
        seconds=time.perf_counter() - start,
        lower=lower,
        never_held=unseen,
    )


def _exact(
    setting: Setting, policy: Any, pomdp_bounds: bool, clock: Deadline
) -> tuple[float, float | None, dict[str, Any] | None, float | None, float | None]:
    """A finite world's figures: the optimum, the policy's exact success (memoryless policies
    on an MDP), Storm's POMDP bounds when asked, the observation-based lower bound, and with
    costs the least expected cost among the policies of best success (``mitlc check``'s, from
    the same values of ``pmax_horizon`` as the optimum)."""
    world, product, tables = setting.model()
    horizon = world.horizon
    optimum, history = pmax_horizon(
        product,
        horizon,
        keep_history=tables.cost is not None,
        deadline=clock.at("pmax_horizon"),
    )
    min_cost = None
    if tables.cost is not None:
        costs = choice_costs(product, tables.cost)
        stage = clock.at("the least cost")
        min_cost = least_cost(product, costs, horizon, values=history, deadline=stage).value
    exact = None
    if not world.is_pomdp and isinstance(policy, Memoryless):
        exact = policy_success(product, _choices(policy, tables), horizon)
    bounds, lower = None, None
    if world.is_pomdp:
        from mitlc.check.observed import ObservedBoundError, observed_bound

        try:
            stage = clock.at("the observation-based bound")
            lower = observed_bound(world, product, horizon=horizon, deadline=stage).value
        except (ObservedBoundError, LimitError):
            lower = None
    if world.is_pomdp and pomdp_bounds:
        from mitlc.check.pomdp import pomdp_bounds as storm_bounds

        try:
            bounds = storm_bounds(world, setting.automaton, horizon_success=True, deadline=clock)
        except LimitError:
            bounds = None
    return optimum, exact, bounds, lower, min_cost


def _choices(policy: Memoryless, tables: Tables) -> IntArray:
    """The policy's choices: ``choices[mask, x]``, or under an enforced shield, which it reads
    at every step, ``choices[r - 1, done, mask, x]`` (:func:`policy_success`'s forms) among
    the actions the shield allows with ``r`` steps left (the mask of all sets once a round
    was completed, ``done``)."""
    s = tables.shield
    if not isinstance(s, Shield) or not tables.shield_enforced:  # none, or a POMDP's
        return policy.choices()
    masks = tables.all_sets + 1
    chosen = np.empty((s.horizon, 2, masks, tables.num_states), dtype=np.int64)
    for r in range(1, s.horizon + 1):
        for done in (0, 1):
            lookup = np.full(masks, tables.all_sets) if done else np.arange(masks)
            allowed = s.allowed(np.array(r), lookup[:, None, None], tables.choice[None])
            chosen[r - 1, done] = policy.choices(tables.valid[None] & allowed)
    return chosen
