"""Greedy rollouts recorded step by step: ``rollouts(setting, policy, episodes, seed)``.

Each of ``episodes`` slots of a :class:`~mitlc.learn.envs.vec.VecProduct` runs its first episode
only. A trajectory lists the product positions the episode went through: the world cell, the
automaton state and the world step (epsilon jumps take no step, so a step number repeats
across a jump). The step that enters the absorbing *satisfied* or *violated* state ends the
episode; that state has no cell, so the trajectory ends in the last real cell (the one whose
letter decided the verdict). In a team world a cell is the robots' joint tuple
``(r0, c0, r1, c1, ...)``; :func:`robot_cells` splits a trajectory into each robot's cells.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mitlc.automata.digital import Verdict
from mitlc.learn.envs.vec import Step, VecProduct
from mitlc.learn.learners.base import Policy
from mitlc.learn.setting import Setting
from mitlc.product.explicit import SATISFIED, VIOLATED
from mitlc.worlds.model import BoolArray, IntArray
from mitlc.worlds.team_model import Team

Cell = tuple[int, int]


@dataclass(frozen=True, slots=True)
class Trajectory:
    """One greedy episode, position by position (the start included)."""

    world_states: tuple[int, ...]
    """Indices into ``world.cells``."""
    cells: tuple[Cell, ...]
    """``(row, col)`` of each position (a team world's: the joint ``world.cells`` tuple)."""
    automaton_states: tuple[int, ...]
    steps: tuple[int, ...]
    """World actions taken before each position (0 at the start)."""
    success: bool
    """The episode's success, as :class:`~mitlc.learn.envs.vec.VecProduct` counts it."""
    verdict: Verdict
    """``satisfied`` / ``violated`` when it entered that state, ``pending`` when truncated."""
    episode_return: float

    @property
    def length(self) -> int:
        """World actions taken in the whole episode."""
        return self.steps[-1]

    def stops(self) -> list[tuple[Cell, int, int]]:
        """Consecutive positions in one cell merged: (cell, first step, last step)."""
        merged: list[tuple[Cell, int, int]] = []
        for cell, step in zip(self.cells, self.steps, strict=True):
            if merged and merged[-1][0] == cell:
                merged[-1] = (cell, merged[-1][1], step)
            else:
                merged.append((cell, step, step))
        return merged


def robot_cells(trajectory: Trajectory, team: Team) -> tuple[tuple[Cell, ...], ...]:
    """Each robot's ``(row, col)`` at each position of a team world's ``trajectory``, in the
    team's robot order (read from ``team.positions``)."""
    indices = team.positions[np.asarray(trajectory.world_states, dtype=np.int64)]
    return tuple(
        tuple(team.cells[i] for i in indices[:, r].tolist()) for r in range(team.num_robots)
    )


class _Recorder:
    """The positions of every slot's first episode, until each has ended."""

    def __init__(self, setting: Setting, env: VecProduct) -> None:
        self.setting = setting
        n = env.num_envs
        self.live: BoolArray = np.ones(n, dtype=np.bool_)
        self.positions: list[list[tuple[int, int, int]]] = [[] for _ in range(n)]
        self.ends: list[tuple[bool, Verdict, float] | None] = [None] * n
        self.record(np.arange(n), env.state, env.steps)

    def record(self, slots: IntArray, states: IntArray, steps: IntArray) -> None:
        """Append the product states ``states`` (at world steps ``steps``) to ``slots``."""
        _, _, tables = self.setting.model()
        for slot, state, step in zip(slots.tolist(), states.tolist(), steps.tolist(), strict=True):
            world = int(tables.world_state[state])
            if world >= 0:
                self.positions[slot].append((world, int(tables.automaton_state[state]), step))

    def observe(self, step: Step) -> None:
        """Take note of one step of the batch."""
        live = np.flatnonzero(self.live)
        self.record(live, step.next_state[live], step.episode_steps[live])
        for slot in np.flatnonzero(self.live & step.done).tolist():
            reached = int(step.next_state[slot])
            verdict: Verdict = "pending"
            if reached in (SATISFIED, VIOLATED):
                verdict = "satisfied" if reached == SATISFIED else "violated"
            self.ends[slot] = (bool(step.success[slot]), verdict, float(step.episode_return[slot]))
            self.live[slot] = False

    def trajectories(self) -> list[Trajectory]:
        """The recorded episodes, by slot."""
        cells = self.setting.model()[0].cells
        result = []
        for positions, end in zip(self.positions, self.ends, strict=True):
            assert end is not None, "an episode is still running"
            worlds, automata, steps = zip(*positions, strict=True)
            result.append(
                Trajectory(
                    world_states=worlds,
                    cells=tuple(cells[s] for s in worlds),
                    automaton_states=automata,
                    steps=steps,
                    success=end[0],
                    verdict=end[1],
                    episode_return=end[2],
                )
            )
        return result


def rollouts(setting: Setting, policy: Policy, episodes: int, seed: int) -> list[Trajectory]:
    """Run ``policy`` greedily for ``episodes`` episodes of the run's product (a fresh
    ``np.random.default_rng(seed)`` drives the world and the observations; the same seed gives
    the same trajectories) and record each (see the module docstring)."""
    if episodes <= 0:
        return []
    env = VecProduct(setting.model()[2], episodes, np.random.default_rng(seed))
    policy.reset(episodes)
    recorder = _Recorder(setting, env)
    while recorder.live.any():
        step = env.step(policy.act(env))
        policy.observe(step)
        recorder.observe(step)
    return recorder.trajectories()
