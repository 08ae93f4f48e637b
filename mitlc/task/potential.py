"""The task's shaping potential: how far a run is from doing its task.

Potential-based shaping (Ng, Harada and Russell, "Policy invariance under reward
transformations", ICML 1999) adds ``F = gamma_t * Phi(s') - Phi(s)`` to the reward of each
transition ``s -> s'``. Along any run the added rewards telescope, so every policy's return
from ``s`` changes by the same ``-Phi(s)`` and the optimal policies do not change (their
Theorem 1). The discount ``gamma_t`` is the transition's own: the constant ``gamma``, or under
the accepting discount ``gamma_accept`` on steps that add an acceptance set; the sum still
telescopes, ``sum_t G_t (gamma_t Phi_{t+1} - Phi_t) = -Phi_0`` with ``G_t`` the product of the
discounts before step ``t``, because each ``Phi_{t+1}`` enters once with ``G_{t+1} = G_t
gamma_t`` and once with ``-G_{t+1}``. ``Phi`` is 0 where an episode ends decided (nothing is
bootstrapped there); at a cut (the horizon) a learner bootstraps, so ``Phi`` of the state
reached counts as it should. :func:`shaped` is that one rule.

The potential of a position ``s`` (the env's) in automaton state ``q`` is

    Phi(s, q) = C - ( d(q) + ENV_WEIGHT * min(1, e(s, q) / reach) + TIME_WEIGHT * u(q) )

* ``d(q)``: the fewest letters from ``q`` to a transition that marks an acceptance set or
  enters a satisfied state (:func:`automaton_distance`);
* ``e(s, q)``: the least distance from ``s`` to where a proposition that *advances* ``q``
  holds (its letter alone leads elsewhere than the empty letter does, and no farther from
  acceptance, or marks a set the empty letter does not): in a finite
  world the fewest steps (:func:`world_distances`), in an env the distance of the labels'
  regions and positions (:mod:`mitlc.labels.distance`): through free space where the env's
  occupancy is known (a maze's walls, a MiniGrid grid, a plane's obstacles, a declared grid:
  the wavefront distance of :mod:`mitlc.labels.occupancy`), a straight line elsewhere; 0
  where no such proposition has a distance; ``reach`` scales it (:func:`pull`; beyond it, the
  pull is flat);
* ``u(q)``: the urgency, the largest of ``q``'s clocks over its bound (the clock view,
  :mod:`mitlc.automata.clocks`): the share of the current deadline already spent.

The weights keep one step of the automaton worth more than the whole pull of the env's
distance and of the time. ``C`` (:attr:`TaskPotential.offset`) is the largest the bracket can
be, the largest ``d`` plus both weights, so ``Phi >= 0`` wherever the task is pending, and 0 where
it ends decided.

**Why ``C``: an optimistic start.** Shaping with ``Phi`` is the same as learning without it from
initial values ``Phi`` (Wiewiora, "Potential-based shaping and Q-value initialization are
equivalent", JAIR 19, 2003). A learner's values start near 0, so without ``C`` (``Phi <= 0``)
every pending state starts *below* what it will learn: the states an agent visits rise and look
better than those it has not visited, and an agent that has not met a success yet stays where
it has been (PointMaze parked in its start's corner). With ``C`` every pending state starts at
or above its value, so the states not yet visited look the better. ``C`` is a constant on the
pending states and ``Phi`` stays 0 at the end, so the policies are unchanged as before.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from mitlc.automata.clocks import ClockViewError, clock_view_of
from mitlc.automata.digital import DigitalAutomaton
from mitlc.worlds.model import World

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray2 = npt.NDArray[np.bool_]

ENV_WEIGHT = 0.5
TIME_WEIGHT = 0.25


def pull(distance: FloatArray, reach: float) -> FloatArray:
    """The env's pull of a distance: ``min(1, distance / reach)`` (1 at ``inf``), flat past
    ``reach``. A pull that keeps rising past it (``1 - exp(-distance / reach)``) was tried on
    PointMaze and the finite worlds and did not do better (``docs/deadlines.md``)."""
    result: FloatArray = np.minimum(np.asarray(distance, dtype=np.float64) / reach, 1.0)
    return result


def fewest_steps(sources: IntArray, targets: IntArray, initial: FloatArray) -> FloatArray:
    """The least of ``initial[x]`` and ``1 +`` the least over the edges ``x -> y`` of ``y``'s
    own, at the fixed point: with ``initial`` 0 at some states and ``inf`` elsewhere, the fewest
    edges to one of them (relaxed over every edge at once, as many rounds as the longest path)."""
    distance = initial.copy()
    for _ in range(len(distance)):
        nearest = np.full(len(distance), np.inf)
        np.minimum.at(nearest, sources, distance[targets] + 1.0)
        updated = np.minimum(distance, nearest)
        if np.array_equal(updated, distance):
            break
        distance = updated
    return distance


def automaton_distance(automaton: DigitalAutomaton) -> FloatArray:
    """Per automaton state, the fewest letters to a transition that marks an acceptance set or
    enters a satisfied state (0 when satisfied; violated and hopeless states get one more than
    the largest finite distance)."""
    rows = automaton.rows
    num_q = len(rows)
    satisfied = np.array([state.verdict == "satisfied" for state in automaton.states])
    marked = np.array([any(row.marks) for row in rows])
    initial = np.where(satisfied, 0.0, np.where(marked, 1.0, np.inf))
    sources = np.repeat(np.arange(num_q), [len(row.targets) for row in rows])
    targets = np.asarray([t for row in rows for t in row.targets], dtype=np.int64)
    distance = fewest_steps(sources, targets, initial)
    finite = distance[np.isfinite(distance)]
    result: FloatArray = np.where(
        np.isfinite(distance), distance, (finite.max() if len(finite) else 0) + 1
    )
    return result


@dataclass(frozen=True, slots=True)
class TaskPotential:
    """The parts of ``Phi`` that depend on the task alone (see the module docstring)."""

    distance: FloatArray
    """``d(q)`` per automaton state."""
    advancing: BoolArray2
    """``advancing[q, i]``: proposition ``i`` advances state ``q``."""
    urgency: FloatArray
    """``u(q)`` per automaton state."""

    @property
    def offset(self) -> float:
        """``C``: the largest ``d`` (a hopeless state's) plus both weights."""
        return float(self.distance.max(initial=0.0)) + ENV_WEIGHT + TIME_WEIGHT

    def at(self, q: IntArray, env_distances: FloatArray, reach: float) -> FloatArray:
        """``Phi`` of each row: automaton state ``q[r]`` where proposition ``i`` is
        ``env_distances[r, i]`` away (``inf`` where it never holds, ``nan``: no distance; a row
        of no columns: no distances at all)."""
        q = np.asarray(q, dtype=np.int64)
        known = np.asarray(env_distances, dtype=np.float64)
        advancing = self.advancing[q] if known.shape[1] else np.zeros(known.shape, np.bool_)
        near = self._near(advancing, known, reach)
        far = self.distance[q] + ENV_WEIGHT * near + TIME_WEIGHT * self.urgency[q]
        phi: FloatArray = self.offset - far
        return phi

    def table(self, env_distances: FloatArray, reach: float) -> FloatArray:
        """``Phi`` of every (automaton state, position): ``env_distances[i, s]`` is how far
        position ``s`` is from proposition ``i`` (``inf`` where it never holds, ``nan``: no
        distance); rows are automaton states."""
        by_position = np.asarray(env_distances, dtype=np.float64).T  # (S, P)
        near = self._near(self.advancing[:, None, :], by_position[None, :, :], reach)  # (Q, S)
        far = self.distance[:, None] + ENV_WEIGHT * near + TIME_WEIGHT * self.urgency[:, None]
        phi: FloatArray = self.offset - far
        return phi

    def leading(self, q: int, env_distances: FloatArray) -> int | None:
        """The proposition whose pull :meth:`at` counts in automaton state ``q`` at a position
        ``env_distances[i]`` from each proposition: the nearest that advances ``q`` (the
        first of equals; past the reach, where every pull is flat, still the nearest);
        ``None`` where none does or none has a finite distance."""
        distances = np.asarray(env_distances, np.float64)
        known = ~np.isnan(distances)
        chosen = np.where(self.advancing[q] & known, np.where(known, distances, 0.0), np.inf)
        if chosen.size == 0 or not np.isfinite(chosen.min()):
            return None
        return int(chosen.argmin())

    @staticmethod
    def _near(advancing: BoolArray2, env_distances: FloatArray, reach: float) -> FloatArray:
        """The pull (:func:`pull`) of the nearest proposition that advances, over the last axis
        (0 where none does or none has a distance)."""
        known = ~np.isnan(env_distances)
        scaled = np.where(known, pull(np.where(known, env_distances, 0.0), reach), np.inf)
        chosen = np.where(advancing & known, scaled, np.inf)
        if chosen.shape[-1] == 0:
            return np.zeros(chosen.shape[:-1])
        least = chosen.min(axis=-1)
        near: FloatArray = np.where(np.isfinite(least), least, 0.0)
        return near


def task_potential(automaton: DigitalAutomaton) -> TaskPotential:
    """The task's part of the potential of ``automaton`` (module docstring)."""
    distance = automaton_distance(automaton)
    num_props = len(automaton.propositions)
    advancing = np.zeros((len(distance), num_props), dtype=np.bool_)
    for q in range(len(distance)):
        if distance[q] == 0.0:
            continue
        idle, idle_marks = automaton.successor(q, 0)
        for i in range(num_props):
            target, marks = automaton.successor(q, 1 << i)
            advancing[q, i] = (bool(marks) and not idle_marks) or (
                target != idle and distance[target] <= distance[idle]
            )
    try:
        view = clock_view_of(automaton)
    except ClockViewError:
        urgency = np.zeros(len(distance))
    else:
        clocks = view.features()[:, view.num_locations :].astype(np.float64)
        urgency = clocks.max(axis=1) if view.num_clocks else np.zeros(len(distance))
    return TaskPotential(distance, advancing, urgency)


def shaped(
    reward: FloatArray, gamma: FloatArray, before: FloatArray, after: FloatArray
) -> FloatArray:
    """The shaped reward of transitions: ``reward + gamma * after - before`` (the potentials,
    scaled, of the states left and reached; 0 where an episode ended decided)."""
    result: FloatArray = reward + gamma * after - before
    return result


def world_distances(
    transitions_indptr: IntArray,
    transitions_targets: IntArray,
    num_actions: int,
    holds: npt.NDArray[np.bool_],
) -> FloatArray:
    """The fewest steps from each world state to a state where each proposition holds
    (``holds[i, s]``), over the transitions' support (row ``s * num_actions + a``); ``inf``
    where none can be reached."""
    num_props, num_states = holds.shape
    rows = np.arange(num_states * num_actions)
    sources = np.repeat(rows // num_actions, np.diff(transitions_indptr))
    result = np.full((num_props, num_states), np.inf)
    for i in range(num_props):
        result[i] = fewest_steps(sources, transitions_targets, np.where(holds[i], 0.0, np.inf))
    return result


def world_potential(world: World, automaton: DigitalAutomaton, reach: float = 0.0) -> FloatArray:
    """``Phi`` of every (automaton state, world state) of a finite world, the env's distance
    being the fewest steps to where each proposition holds (:func:`world_distances`);
    ``reach`` (0: the longest such distance) scales it."""
    props = automaton.propositions
    letters = np.asarray(world.letters, dtype=np.int64)
    holds = np.zeros((len(props), world.num_states), dtype=np.bool_)
    for i, p in enumerate(props):
        if p in world.propositions:
            holds[i] = (letters >> world.propositions.index(p)) & 1
    env = world_distances(
        world.transitions.indptr, world.transitions.targets, world.num_actions, holds
    )
    finite = env[np.isfinite(env)]
    reach = reach or max(float(finite.max()) if finite.size else 1.0, 1.0)
    return task_potential(automaton).table(env, reach)
