"""mitlc's simulator of a finite product as a ``gymnasium.vector.VectorEnv``.

:class:`ProductVectorEnv` presents :class:`mitlc.learn.vec.VecProduct` (a batch of product
episodes stepped in numpy) with gymnasium's vector API, so that a learner written for any
vector env of wrapped environments reads it as it reads ``SyncVectorEnv([ProductEnv, ...])``:

* observations are those of :class:`mitlc.product.env.ProductEnv`, batched: a ``Dict`` of
  ``world`` (the cell, or a POMDP's observation id), ``automaton`` and ``frontier`` arrays;
* actions a ``MultiDiscrete`` of the world actions and the epsilon jumps; :meth:`action_masks`
  gives the valid ones (an invalid action is refused: the simulator has no wasted steps);
* ended episodes restart in the same step (gymnasium's ``AutoresetMode.SAME_STEP``): the
  returned observation is the new episode's, and ``infos["final_obs"]`` (an object array, as
  gymnasium's) holds the observation each ended episode reached, with ``infos["_final_obs"]``
  marking them; ``infos["success"]`` / ``infos["is_success"]`` is each ended episode's success
  (the task monitor's, :mod:`mitlc.task.rules`) and ``infos["episode"]`` its return and length
  (``r``, ``l``, as gymnasium's ``RecordEpisodeStatistics``), masked by ``_success`` etc.;
  ``infos["accepting"]`` flags steps that added a set to the frontier (for the accepting
  discount).

The product merges the states where the task is decided, so an episode that ended decided (or
a task decided at the very start) shows cell 0 and automaton state 0 there; no learner reads
them (a terminated step does not bootstrap). The step itself is the simulator's;
:attr:`ProductVectorEnv.last_step` keeps its :class:`~mitlc.learn.vec.Step` (product states
included) for learners of the finite product.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import batch_space

from mitlc.learn.vec import Step, Tables, VecProduct
from mitlc.worlds.model import BoolArray, IntArray

Observation = dict[str, IntArray]


class ProductVectorEnv(gym.vector.VectorEnv[Observation, IntArray, Any]):
    """``num_envs`` episodes of a finite product (see the module docstring)."""

    metadata: dict[str, Any] = {"autoreset_mode": AutoresetMode.SAME_STEP}  # noqa: RUF012

    def __init__(self, tables: Tables, num_envs: int, seed: int | None = None) -> None:
        self.tables, self.num_envs = tables, num_envs
        self.single_observation_space = spaces.Dict(
            {
                "world": spaces.Discrete(tables.num_observations),
                "automaton": spaces.Discrete(max(tables.num_automaton_states, 1)),
                "frontier": spaces.Discrete(tables.all_sets + 1),
            }
        )
        self.single_action_space = spaces.Discrete(tables.num_actions)
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self._automaton = np.maximum(tables.automaton_state, 0)
        self.sim = VecProduct(tables, num_envs, np.random.default_rng(seed))
        self.last_step: Step | None = None

    def reset(
        self, *, seed: int | list[int] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Observation, dict[str, Any]]:
        """Start ``num_envs`` new episodes; ``seed`` (an int) seeds the simulator."""
        if isinstance(seed, list):
            seed = seed[0] if seed else None
        self.sim = VecProduct(self.tables, self.num_envs, np.random.default_rng(seed))
        self.last_step = None
        return self._observation(self.sim.state, self.sim.mask, self.sim.observation), {}

    def step(
        self, actions: IntArray
    ) -> tuple[Observation, Any, BoolArray, BoolArray, dict[str, Any]]:
        """Every episode takes its action; ended ones restart (see the module docstring)."""
        step = self.sim.step(np.asarray(actions, dtype=np.int64))
        self.last_step = step
        done = step.done
        infos: dict[str, Any] = {
            "accepting": step.accepting,
            "_accepting": np.ones(self.num_envs, dtype=np.bool_),
        }
        if done.any():
            ended = np.flatnonzero(done)
            rows = zip(
                step.next_observation[ended].tolist(),
                self._automaton[step.next_state[ended]].tolist(),
                step.next_mask[ended].tolist(),
                strict=True,
            )
            final_obs = np.full(self.num_envs, None, dtype=object)
            final_obs[ended] = [{"world": w, "automaton": q, "frontier": f} for w, q, f in rows]
            infos.update(
                final_obs=final_obs,
                _final_obs=done,
                success=step.success & done,
                _success=done,
                is_success=step.success & done,
                _is_success=done,
                episode={
                    "r": np.where(done, step.episode_return, 0.0),
                    "l": np.where(done, step.episode_steps, 0),
                },
                _episode=done,
            )
        observation = self._observation(self.sim.state, self.sim.mask, self.sim.observation)
        return observation, step.reward, step.terminated, step.truncated, infos

    def action_masks(self) -> BoolArray:
        """``masks[i, a]``: action ``a`` is valid in episode ``i`` (sb3-contrib's convention)."""
        return self.sim.valid_actions()

    def _observation(self, state: IntArray, mask: IntArray, seen: IntArray) -> Observation:
        # the simulator replaces its arrays every step, so they are not copied
        return {"world": seen, "automaton": self._automaton.take(state), "frontier": mask}
