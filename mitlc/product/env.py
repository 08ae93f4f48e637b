"""The on-the-fly product of a world and a digital automaton, as a gymnasium environment.

:class:`ProductEnv` is the world as a plain environment (:class:`mitlc.worlds.grid_env.GridEnv`)
with the task put on it by :class:`mitlc.gym.TaskWrapper`; every rule of the task (automaton
step, frontier, reward terms, verdict, termination, success) is
:class:`mitlc.task.TaskMonitor`'s, as in the explicit product (:mod:`mitlc.product.explicit`),
so that learning and checking see the same model. The state is ``(s, q)``: the world in state
``s``, the automaton in state ``q`` about to read the letter of ``s`` (position 0 is the start
cell, before the first action).

* **Observation**: ``{"world": ..., "automaton": q, "frontier": mask}``. ``"world"`` is the
  cell ``s`` for an MDP; for a POMDP it is an observation id drawn from
  ``world.observations.model.row(s)``. The agent always knows its automaton state (labels are
  observable: the letters are the world's letters of the true cell) and the frontier, the
  acceptance sets seen in the current round, as one integer in ``Discrete(2 ** num_sets)``.
* **Actions**: ``Discrete(num_actions + max_jumps)``. Action ``a < num_actions`` is a world
  action: ``s'`` is drawn from the world's row ``s * num_actions + a``, the automaton reads the
  letter of ``s``. Action ``num_actions + j`` takes the ``j``-th epsilon jump of ``q`` (in the
  order of the automaton's ``jumps(q)``): the automaton moves, the world does not, no time
  passes (the step counter and the horizon are untouched, as in
  :func:`mitlc.check.solve.pmax_horizon`) and the observation is unchanged. A jump that ``q``
  does not have is *invalid*: world and automaton stay as they are, the reward is 0,
  ``info["invalid_action"]`` is True, and it costs a step of the episode's budget, so an agent
  that ignores the mask still ends every episode by the horizon; :meth:`ProductEnv.action_masks`
  gives the valid actions (sb3-contrib's ``MaskablePPO`` convention).
* **Reward**: the task's (``rewards.accept`` for each acceptance set first seen in the current
  round, ``rewards.satisfied`` / ``rewards.violated`` on entering a satisfied / violated
  automaton state) plus the world's ``rewards.move`` for every world action other than ``stay``.
* **Episode end**: ``terminated`` when the automaton state is satisfied or violated,
  ``truncated`` when ``world.horizon`` world actions have been taken. The automaton reads the
  letter of a cell on the action taken *from* it, so a verdict shows one step after arrival.
* **info**: ``state`` (the true cell), ``verdict`` of the automaton state, ``marks`` (the
  acceptance sets of the last transition), ``rounds`` (completed rounds), ``success`` and
  ``is_success`` (so far: never violated, and satisfied, or a round completed, or there are no
  acceptance sets), ``step`` (world actions taken), ``invalid_action`` and
  ``automaton_state``.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import gymnasium as gym
import numpy as np

from mitlc.automata import DigitalAutomaton, translate
from mitlc.gym.wrapper import PENDING, TaskObs, TaskWrapper
from mitlc.product.explicit import Product, automaton_letters
from mitlc.syntax import parse
from mitlc.task import VERDICT_NAMES, rules
from mitlc.task.costs import StepTable, TransitionCosts, world_cost
from mitlc.task.potential import world_potential
from mitlc.worlds import World, load_world
from mitlc.worlds.grid_env import GridEnv, WorldLabels
from mitlc.worlds.model import BoolArray

if TYPE_CHECKING:  # the check stage's data, read here as a plain value (no import at run time)
    from mitlc.check.shield import Shield

ENV_ID = "mitlc/Product-v0"
"""The gymnasium id: ``gymnasium.make(ENV_ID, world=..., automaton=...)``."""


class ProductEnv(TaskWrapper):
    """A world joined with a digital automaton, stepped on the fly (see the module docstring):
    ``TaskWrapper(GridEnv(world), automaton, labels=the world's, rewards=world.rewards,
    horizon=world.horizon, reward_mode="add")``, its env's part of the observation named
    ``"world"``."""

    _spec_is_inner = True
    env: GridEnv

    def __init__(
        self,
        world: World,
        automaton: DigitalAutomaton,
        *,
        render_mode: str | None = None,
        flatten: bool = False,
        task_obs: TaskObs = "state",
        potential: float | None = None,
        shield: Shield | None = None,
        product: Product | None = None,
        shield_audit: bool = False,
    ) -> None:
        automaton_letters(world, automaton.propositions)  # the world must label the task
        super().__init__(
            GridEnv(world, render_mode=render_mode),
            automaton,
            WorldLabels.of(world),
            rewards=world.rewards,
            horizon=world.horizon,
            reward_mode="add",
            env_key="world",
            flatten=flatten,
            task_obs=task_obs,
            potential=potential,
        )
        self.world: World = world
        self.automaton: DigitalAutomaton = automaton
        self._table = None if potential is None else world_potential(world, automaton, potential)
        self._shield = None
        if shield is not None:
            if product is None:
                raise ValueError("a shield needs the product it was computed on")
            self._shield = _ProductShield(shield, product, world.num_states)
        self._shield_audit = shield_audit
        self._costs = None
        if world.costs is not None:  # the one definition of a step's cost (mitlc.task.costs)
            self._costs = (StepTable.of(world), TransitionCosts(world, automaton))

    def action_masks(self) -> BoolArray:
        """The valid actions (:meth:`TaskWrapper.action_masks`), and with a shield that is
        kept to only those it allows now (:mod:`mitlc.check.shield`)."""
        masks = super().action_masks()
        if self._shield is None or self._shield_audit:
            return masks
        return masks & self._shield_masks(len(masks))

    def _shield_masks(self, width: int) -> BoolArray:
        assert self._shield is not None
        return self._shield.masks(
            self.world_state, self.automaton_state, self.frontier, self.rounds,
            self.horizon - self.steps, width,
        )  # fmt: skip

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        """:meth:`TaskWrapper.step`, less the step's cost in a world with costs (``info["cost"]``:
        :func:`mitlc.task.costs.world_cost` of the world step and the transition rules' cost
        of the automaton state and the letter read; jumps and refused actions cost nothing).
        With a shield ``info["shield_blocked"]`` says whether the action was a valid one the
        shield blocks (an agent that reads the masks never takes one), and
        ``info["action_mask"]`` is the shielded mask."""
        if self._costs is None:
            return self._shielded_step(action)
        index = int(action)
        s, q = self.world_state, self.automaton_state
        world_step = 0 <= index < self.world.num_actions and not self._done
        obs, reward, terminated, truncated, info = self._shielded_step(action)
        cost = 0.0
        if world_step and not info.get("invalid_action", False):
            table, rules = self._costs
            letters = self.world.letters
            cost = float(world_cost(table, index, int(letters[s]), int(letters[self.world_state])))
            cost += rules.cost(q, int(letters[s]))
        info["cost"] = cost
        return obs, reward - cost, terminated, truncated, info

    def _shielded_step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        if self._shield is None:
            return super().step(action)
        valid = super().action_masks()
        index = int(action)
        inside = 0 <= index < len(valid)
        blocked = inside and bool(valid[index]) and not self._shield_masks(len(valid))[index]
        obs, reward, terminated, truncated, info = super().step(action)
        info["shield_blocked"] = blocked
        if "action_mask" in info and not (terminated or truncated):
            info["action_mask"] = self.action_masks()
        return obs, reward, terminated, truncated, info

    def potential(self) -> float:
        """The task's shaping potential now, the world's distances being the fewest steps
        to where each proposition holds (:func:`mitlc.task.potential.world_potential`)."""
        if self._table is None or self.monitor.verdict(self.automaton_state) != PENDING:
            return super().potential()
        return float(self._table[self.automaton_state, self.world_state])

    @property
    def num_flat_states(self) -> int:
        """The size of the flat index space of :meth:`state_index`."""
        return self.world.num_states * self.num_q

    @property
    def world_state(self) -> int:
        """The true world state ``s``."""
        return self.env.state

    def state_index(self) -> int:
        """The flat index ``s * Q + q`` of the true product state, for tabular learners."""
        return self.env.state * self.num_q + self.automaton_state

    def render(self) -> str | None:
        """With ``render_mode="ansi"``: the grid (``@`` the robot, ``#`` blocked, labels by
        their first letter) and a status line."""
        grid = self.env.render()
        if grid is None:
            return None
        q = self.automaton_state
        verdict = VERDICT_NAMES[self.monitor.verdict(q)]
        status = f"step {self.steps}/{self.horizon}  q={q} ({verdict})  rounds={self.rounds}"
        return f"{grid}\n{status}"


class _ProductShield:
    """A shield read from the on-the-fly product: the product state of ``(s, q)`` found among
    the explicit product's (codes ``q * S + s``, sorted), its choices in the wrapper's action
    order (world actions, then the jumps of ``q`` in order)."""

    def __init__(self, shield: Shield, product: Product, num_s: int) -> None:
        self.shield, self.product, self.num_s = shield, product, num_s
        live = np.flatnonzero(product.world_state >= 0)
        codes = product.automaton_state[live].astype(np.int64) * num_s + product.world_state[live]
        order = np.argsort(codes)
        self.codes, self.states = codes[order], live[order]
        self.all_sets = (1 << product.num_sets) - 1

    def masks(
        self, s: int, q: int, frontier: int, rounds: int, remaining: int, width: int
    ) -> BoolArray:
        """Per action of the wrapper (``width`` of them), whether the shield allows it."""
        allowed = np.ones(width, dtype=np.bool_)
        code = q * self.num_s + s
        at = int(np.searchsorted(self.codes, code))
        if at == len(self.codes) or self.codes[at] != code:  # decided: nothing to shield
            return allowed
        x = int(self.states[at])
        lo, hi = int(self.product.choice_ptr[x]), int(self.product.choice_ptr[x + 1])
        count = min(hi - lo, width)
        mask = rules.seen_sets(frontier, rounds, self.all_sets)
        choices = np.arange(lo, lo + count)
        allowed[:count] = self.shield.allowed(np.array(remaining), np.array(mask), choices)
        return allowed


def make_env(
    world_path: str | Path, spec: str | None = None, *, render_mode: str | None = None
) -> ProductEnv:
    """The product environment of the world file at ``world_path`` and its spec, or ``spec``
    (a formula's text) in its place (a :class:`mitlc.worlds.WorldError` if it names a
    proposition that no label declares)."""
    world = load_world(world_path, spec)
    automaton = translate(parse(world.spec, world.spec_source))
    return ProductEnv(world, automaton, render_mode=render_mode)


if ENV_ID not in gym.registry:
    gym.register(id=ENV_ID, entry_point="mitlc.product.env:ProductEnv")
