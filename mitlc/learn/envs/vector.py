"""mitlc's simulator of a finite product as a ``gymnasium.vector.VectorEnv``.

:class:`ProductVectorEnv` presents :class:`mitlc.learn.envs.vec.VecProduct` (a batch of product
episodes stepped in numpy) with gymnasium's vector API, so that a learner written for any
vector env of wrapped environments reads it as it reads ``SyncVectorEnv([ProductEnv, ...])``:

* observations are those of :class:`mitlc.product.env.ProductEnv`, batched: a ``Dict`` of
  ``world`` (the cell, or a POMDP's observation id), ``automaton`` and ``frontier`` arrays;
* actions a ``MultiDiscrete`` of the world actions and the epsilon jumps; :meth:`action_masks`
  gives the valid ones (an invalid action is refused: the simulator has no wasted steps);
* ended episodes restart in the same step (gymnasium's ``AutoresetMode.SAME_STEP``): the
  returned observation is the new episode's; ``infos["final_obs"]`` (an object array, as
  gymnasium's) holds the observation each ended episode reached and ``infos["final_info"]``
  its last entries, with ``_final_obs`` / ``_final_info`` marking them (as ``SyncVectorEnv``
  does); ``success`` / ``is_success`` is each ended episode's success (the task monitor's,
  :mod:`mitlc.task.rules`) and ``episode`` its return and length (``r``, ``l``, as gymnasium's
  ``RecordEpisodeStatistics``), in ``final_info`` and, for convenience, at the top level;
* every step's infos have the task wrapper's entries (:class:`mitlc.gym.TaskWrapper`):
  ``accepting`` (the step added a set to the frontier), ``action_mask`` and ``step``, and
  ``product_state``, the finite-product adapter (:mod:`mitlc.learn.envs.envvec`).

The product merges the states where the task is decided, so an episode that ended decided (or
a task decided at the very start) shows cell 0 and automaton state 0 there; no learner reads
them (a terminated step does not bootstrap). The step itself is the simulator's;
:attr:`ProductVectorEnv.last_step` keeps its :class:`~mitlc.learn.envs.vec.Step` (product states
included) for learners of the finite product.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import batch_space

from mitlc.learn.envs.vec import Step, Tables, VecProduct
from mitlc.worlds.model import BoolArray, IntArray

Observation = dict[str, IntArray]


class ProductVectorEnv(gym.vector.VectorEnv[Observation, IntArray, Any]):
    """``num_envs`` episodes of a finite product (see the module docstring)."""

    metadata: dict[str, Any] = {"autoreset_mode": AutoresetMode.SAME_STEP}  # noqa: RUF012

    def __init__(
        self,
        tables: Tables,
        num_envs: int,
        seed: int | None = None,
        *,
        rng: np.random.Generator | None = None,
    ) -> None:
        """``seed`` (or ``rng`` itself, which the simulator then draws from) seeds it."""
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
        self._rng = rng if rng is not None else np.random.default_rng(seed)
        self.sim = VecProduct(tables, num_envs, self._rng)
        self.last_step: Step | None = None

    def reset(
        self, *, seed: int | list[int] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Observation, dict[str, Any]]:
        """Start ``num_envs`` new episodes; ``seed`` (an int) reseeds the simulator."""
        if isinstance(seed, list):
            seed = seed[0] if seed else None
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        self.sim = VecProduct(self.tables, self.num_envs, self._rng)
        self.last_step = None
        return self.current()

    def current(self) -> tuple[Observation, dict[str, Any]]:
        """The episodes' current observation and task entries (as a reset gives them)."""
        sim = self.sim
        return self._observation(sim.state, sim.mask, sim.observation), self._now()

    def step(
        self, actions: IntArray
    ) -> tuple[Observation, Any, BoolArray, BoolArray, dict[str, Any]]:
        """Every episode takes its action; ended ones restart (see the module docstring)."""
        step = self.sim.step(np.asarray(actions, dtype=np.int64))
        self.last_step = step
        done = step.done
        infos = self._now()
        infos.update(accepting=step.accepting, _accepting=np.ones(self.num_envs, dtype=np.bool_))
        if done.any():
            ended = np.flatnonzero(done)
            reached_q = self._automaton[step.next_state]
            rows = zip(
                step.next_observation[ended].tolist(),
                reached_q[ended].tolist(),
                step.next_mask[ended].tolist(),
                strict=True,
            )
            final_obs = np.full(self.num_envs, None, dtype=object)
            final_obs[ended] = [{"world": w, "automaton": q, "frontier": f} for w, q, f in rows]
            success = step.success & done
            final = {
                "success": success,
                "is_success": success,
                "accepting": step.accepting,
                "step": step.episode_steps,
                "action_mask": step.next_valid,
                "product_state": step.next_state,
                "episode": {
                    "r": np.where(done, step.episode_return, 0.0),
                    "l": np.where(done, step.episode_steps, 0),
                },
            }
            final.update({f"_{key}": done for key in list(final)})
            infos.update(final_obs=final_obs, _final_obs=done, final_info=final, _final_info=done)
            infos.update({key: final[key] for key in ("success", "is_success", "episode")})
            infos.update({f"_{key}": done for key in ("success", "is_success", "episode")})
        observation = self._observation(self.sim.state, self.sim.mask, self.sim.observation)
        return observation, step.reward, step.terminated, step.truncated, infos

    def step_task(self, actions: IntArray) -> Step:
        """:meth:`step` as the learners read it, without building the observation and infos:
        the simulator's own :class:`~mitlc.learn.envs.vec.Step` (what
        :class:`~mitlc.learn.envs.envvec.VectorTask` would decode from them; a test holds the two
        equal). Read :meth:`current` for the episodes now."""
        step = self.sim.step(np.asarray(actions, dtype=np.int64))
        self.last_step = step
        return step

    def state_dict(self) -> dict[str, Any]:
        """The simulator's state (:meth:`mitlc.learn.envs.vec.VecProduct.state_dict`)."""
        return self.sim.state_dict()

    def load_state_dict(self, saved: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`."""
        self.sim.load_state_dict(saved)

    def action_masks(self) -> BoolArray:
        """``masks[i, a]``: action ``a`` is valid in episode ``i`` (sb3-contrib's convention)."""
        return self.sim.valid_actions()

    def _now(self) -> dict[str, Any]:
        """The current episodes' task entries: valid actions, steps taken, product state."""
        sim, every = self.sim, np.ones(self.num_envs, dtype=np.bool_)
        return {
            "action_mask": sim.valid_actions(),
            "_action_mask": every,
            "step": sim.steps.copy(),
            "_step": every,
            "product_state": sim.state,
            "_product_state": every,
        }

    def _observation(self, state: IntArray, mask: IntArray, seen: IntArray) -> Observation:
        # the simulator replaces its arrays every step, so they are not copied
        return {"world": seen, "automaton": self._automaton.take(state), "frontier": mask}
