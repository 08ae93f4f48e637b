"""The on-the-fly product of a world and a digital automaton, as a gymnasium environment.

The conventions are those of :mod:`mitlc.product.explicit`, so that learning and checking see
the same model. The state is ``(s, q)``: the world in state ``s``, the automaton in state ``q``
about to read the letter of ``s`` (position 0 is the start cell, before the first action).

* **Observation**: ``{"world": ..., "automaton": q}``. ``"world"`` is the cell ``s`` for an MDP;
  for a POMDP it is an observation id drawn from ``world.observations.model.row(s)``. The agent
  always knows its automaton state (labels are observable).
* **Actions**: ``Discrete(num_actions + max_jumps)``. Action ``a < num_actions`` is a world
  action: ``s'`` is drawn from the world's row ``s * num_actions + a``, the automaton moves to
  ``delta[q][L(s)]`` and the transition is in the acceptance sets ``marks[q][L(s)]``. Action
  ``num_actions + j`` takes the ``j``-th epsilon jump of ``q`` (jumps sorted by target): the
  automaton moves, the world does not, no time passes (the step counter and the horizon are
  untouched, as in :func:`mitlc.check.solve.pmax_horizon`) and the observation is unchanged.
  A jump that ``q`` does not have is *invalid*: world and automaton stay as they are, the
  reward is 0, ``info["invalid_action"]`` is True, and it costs a step of the episode's
  budget (the step counter counts it towards the horizon), so an agent that ignores the mask
  still ends every episode by the horizon; :meth:`ProductEnv.action_masks` gives the valid
  actions (the convention of sb3-contrib's ``MaskablePPO``).
* **Reward**: ``rewards.accept`` for each acceptance set first seen in the current round of the
  generalized Büchi condition (a frontier: once every set has been seen the round is complete
  and the frontier is emptied), ``rewards.satisfied`` / ``rewards.violated`` on entering a
  satisfied / violated automaton state, and ``rewards.move`` for every world action other than
  ``stay``.
* **Episode end**: ``terminated`` when the automaton state is satisfied or violated,
  ``truncated`` when ``world.horizon`` world actions have been taken. The automaton reads the
  letter of a cell on the action taken *from* it, so a verdict shows one step after arrival.
* **info**: ``verdict`` of the automaton state, ``marks`` (the acceptance sets of the last
  transition), ``rounds`` (completed rounds), ``success`` (so far: never violated, and
  satisfied, or a round completed, or there are no acceptance sets), ``step`` (world actions
  taken) and ``invalid_action``.
"""

from __future__ import annotations

from bisect import bisect_right
from collections.abc import Mapping, Sequence
from dataclasses import replace
from itertools import accumulate
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from mitlc.automata import DigitalAutomaton, translate
from mitlc.product.explicit import automaton_letters
from mitlc.syntax import atoms, parse
from mitlc.worlds import Sparse, World, load_world, read_world_file
from mitlc.worlds.model import BoolArray

ENV_ID = "mitlc/Product-v0"
"""The gymnasium id: ``gymnasium.make(ENV_ID, world=..., automaton=...)``."""

Obs = dict[str, Any]
"""``{"world": int, "automaton": int}``."""


class _Sampler:
    """Draws from the rows of a :class:`Sparse` by inverting their cumulative sums."""

    def __init__(self, sparse: Sparse) -> None:
        self._rows: list[tuple[list[int], list[float]]] = []
        for r in range(sparse.num_rows):
            targets, probs = sparse.row(r)
            self._rows.append((targets.tolist(), list(accumulate(probs.tolist()))))

    def draw(self, r: int, u: float) -> int:
        """The target of row ``r`` that the uniform number ``u`` in [0, 1) selects."""
        targets, cumulative = self._rows[r]
        i = bisect_right(cumulative, u * cumulative[-1])
        return targets[min(i, len(targets) - 1)]


class ProductEnv(gym.Env[Obs, np.int64]):
    """A world joined with a digital automaton, stepped on the fly (see the module docstring)."""

    observation_space: spaces.Dict
    action_space: spaces.Discrete
    metadata: dict[str, Any] = {"render_modes": ["ansi"], "render_fps": 4}  # noqa: RUF012

    def __init__(
        self, world: World, automaton: DigitalAutomaton, *, render_mode: str | None = None
    ) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode {render_mode!r} is not one of 'ansi' or None")
        self.world, self.automaton, self.render_mode = world, automaton, render_mode
        self._letters = automaton_letters(world, automaton.propositions).tolist()
        self._jumps = [automaton.jumps_from(q) for q in range(len(automaton.states))]
        self.max_jumps = max(map(len, self._jumps), default=0)
        """The largest number of epsilon jumps leaving an automaton state."""
        self._verdicts = [state.verdict for state in automaton.states]
        self._moves = [name != "stay" for name in world.actions]
        self._motion = _Sampler(world.transitions)
        obs = world.observations
        self._sensor = None if obs is None else _Sampler(obs.model)
        num_obs = world.num_states if obs is None else len(obs.names)
        self.observation_space = spaces.Dict(
            {"world": spaces.Discrete(num_obs), "automaton": spaces.Discrete(self.num_q)}
        )
        self.action_space = spaces.Discrete(world.num_actions + self.max_jumps)
        self._s, self._q, self._seen_obs = world.start, automaton.initial, world.start
        self._seen, self._rounds, self._step, self._done = 0, 0, 0, False

    # -- state ---------------------------------------------------------------------------------

    @property
    def num_q(self) -> int:
        """The number of automaton states."""
        return len(self.automaton.states)

    @property
    def num_flat_states(self) -> int:
        """The size of the flat index space of :meth:`state_index`."""
        return self.world.num_states * self.num_q

    @property
    def world_state(self) -> int:
        """The true world state ``s``."""
        return self._s

    @property
    def automaton_state(self) -> int:
        """The automaton state ``q``."""
        return self._q

    @property
    def frontier(self) -> int:
        """The mask of acceptance sets seen in the current round."""
        return self._seen

    @property
    def steps(self) -> int:
        """World actions taken in this episode."""
        return self._step

    def state_index(self) -> int:
        """The flat index ``s * Q + q`` of the true product state, for tabular learners."""
        return self._s * self.num_q + self._q

    def action_masks(self) -> BoolArray:
        """Which actions are valid now: every world action, and the jumps ``q`` has."""
        mask = np.zeros(int(self.action_space.n), dtype=np.bool_)
        mask[: self.world.num_actions + len(self._jumps[self._q])] = True
        return mask

    # -- gymnasium API -------------------------------------------------------------------------

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Obs, dict[str, Any]]:
        """Start at ``(world.start, automaton.initial)``; ``seed`` seeds :attr:`np_random`."""
        super().reset(seed=seed)
        self._s, self._q = self.world.start, self.automaton.initial
        self._seen, self._rounds, self._step, self._done = 0, 0, 0, False
        self._seen_obs = self._observe()
        return self._obs(), self._info(0, invalid=False)

    def step(self, action: int | np.integer[Any]) -> tuple[Obs, float, bool, bool, dict[str, Any]]:
        """One world action, or one epsilon jump (which takes no time); see the module doc."""
        if self._done:
            raise RuntimeError("the episode is over: call reset()")
        a, num_actions = int(action), self.world.num_actions
        if not 0 <= a < int(self.action_space.n):
            raise ValueError(f"action {action!r} is not in {self.action_space}")
        rewards, marks = self.world.rewards, 0
        if a >= num_actions:
            jumps = self._jumps[self._q]
            if a - num_actions >= len(jumps):  # invalid: nothing moves, but a step is spent
                self._step += 1
                truncated = self._step >= self.world.horizon
                self._done = truncated
                return self._obs(), 0.0, False, truncated, self._info(0, invalid=True)
            self._q, reward = jumps[a - num_actions], 0.0
        else:
            letter = self._letters[self._s]
            marks = self.automaton.marks[self._q][letter]
            self._q = self.automaton.delta[self._q][letter]
            self._s = self._motion.draw(self._s * num_actions + a, self.np_random.random())
            self._step += 1
            self._seen_obs = self._observe()
            reward = rewards.move if self._moves[a] else 0.0
            reward += rewards.accept * self._account(marks)
        verdict = self._verdicts[self._q]
        if verdict == "satisfied":
            reward += rewards.satisfied
        elif verdict == "violated":
            reward += rewards.violated
        terminated = verdict != "pending"
        truncated = not terminated and self._step >= self.world.horizon
        self._done = terminated or truncated
        return self._obs(), float(reward), terminated, truncated, self._info(marks, invalid=False)

    def render(self) -> str | None:
        """With ``render_mode="ansi"``: the grid (``@`` the robot, ``#`` blocked, labels by
        their first letter) and a status line."""
        if self.render_mode != "ansi":
            return None
        world = self.world
        grid = [["#"] * world.cols for _ in range(world.rows)]
        for s, (row, col) in enumerate(world.cells):
            props = [p for i, p in enumerate(world.propositions) if world.letters[s] >> i & 1]
            grid[row][col] = "@" if s == self._s else props[0][0] if props else "."
        status = (
            f"step {self._step}/{world.horizon}  q={self._q} ({self._verdicts[self._q]})  "
            f"rounds={self._rounds}"
        )
        return "\n".join(["".join(line) for line in grid] + [status])

    # -- internals -----------------------------------------------------------------------------

    def _observe(self) -> int:
        if self._sensor is None:
            return self._s
        return self._sensor.draw(self._s, self.np_random.random())

    def _obs(self) -> Obs:
        return {"world": self._seen_obs, "automaton": self._q}

    def _account(self, marks: int) -> int:
        """Add ``marks`` to the frontier; the number of sets new in this round."""
        new = (marks & ~self._seen).bit_count()
        self._seen |= marks
        if self.automaton.num_sets and self._seen == self.automaton.all_sets:
            self._rounds += 1
            self._seen = 0
        return new

    def _info(self, marks: int, *, invalid: bool) -> dict[str, Any]:
        verdict = self._verdicts[self._q]
        done = verdict == "satisfied" or self._rounds > 0 or self.automaton.num_sets == 0
        return {
            "verdict": verdict,
            "marks": [k for k in range(self.automaton.num_sets) if marks >> k & 1],
            "rounds": self._rounds,
            "success": verdict != "violated" and done,
            "step": self._step,
            "invalid_action": invalid,
        }


def relabel(world: World, labels: Mapping[str, Sequence[Sequence[int]]], spec: str) -> World:
    """``world`` with the task ``spec``: its propositions and letters recomputed from the
    world file's ``labels`` (cell lists); a ``ValueError`` if a proposition labels no cell."""
    propositions = atoms(parse(spec, "<spec>"))
    cells = {p: {(int(c[0]), int(c[1])) for c in labels.get(p, ())} for p in propositions}
    missing = [p for p in propositions if not cells[p]]
    if missing:
        raise ValueError(f"propositions {missing} label no cell (labels: {sorted(labels)})")
    letters = [
        sum(1 << i for i, p in enumerate(propositions) if cell in cells[p]) for cell in world.cells
    ]
    return replace(
        world,
        propositions=propositions,
        letters=np.asarray(letters, dtype=np.int64),
        spec=spec,
        spec_source="<spec>",
    )


def make_env(
    world_path: str | Path, spec: str | None = None, *, render_mode: str | None = None
) -> ProductEnv:
    """The product environment of the world file at ``world_path`` and its spec, or ``spec``
    (a formula's text) in its place."""
    world = load_world(world_path)
    if spec is not None:
        world = relabel(world, read_world_file(world_path).labels, spec)
    automaton = translate(parse(world.spec, world.spec_source))
    return ProductEnv(world, automaton, render_mode=render_mode)


if ENV_ID not in gym.registry:
    gym.register(id=ENV_ID, entry_point="mitlc.product.env:ProductEnv")
