"""A batch of any wrapped gymnasium environments, stepped as the learners step the product's
simulator: ``TaskVector(envs, seed)``.

Each env is a :class:`mitlc.gym.TaskWrapper` (Dict observations: the env's own part, a
``Discrete`` or a bounded ``Box``, the automaton state and the frontier; masked epsilon jumps),
so the task's rules are the monitor's. The vector has the interface the learners read of
:class:`mitlc.learn.vec.VecProduct`: ``observation`` (the env's part), ``automaton``, ``mask``
(the frontier), :meth:`valid_actions` and :meth:`step`, whose :class:`~mitlc.learn.vec.Step`
gives rewards, whether a step added a set to the frontier (from the wrapper's ``marks``),
terminations, truncations, the next observation, automaton state, frontier and valid actions
*before* an ended episode restarts (same-step autoreset, as gymnasium's
``AutoresetMode.SAME_STEP``), success and the episode's return and length. There are no
product states (``next_state`` is -1): exact evaluation needs a finite product.

The envs are stepped one after another in this process (gymnasium's ``SyncVectorEnv`` does the
same); env ``i`` is reset first with ``seed + i``, then continues its own random stream.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from mitlc.learn.vec import Step
from mitlc.worlds.model import BoolArray, IntArray


class TaskVector:
    """``len(envs)`` wrapped episodes stepped together (see the module docstring)."""

    def __init__(self, envs: Sequence[Any], seed: int = 0) -> None:
        self.envs, self.num_envs = list(envs), len(envs)
        space = self.envs[0].observation_space
        self.env_key = next(k for k in space.spaces if k not in ("automaton", "frontier"))
        self.observation_space = space
        self.num_actions = int(self.envs[0].action_space.n)
        observations = [env.reset(seed=seed + i)[0] for i, env in enumerate(self.envs)]
        self.observation, self.automaton, self.mask = self._stack(observations)
        self.returns = np.zeros(self.num_envs)
        self.steps = np.zeros(self.num_envs, dtype=np.int64)

    @property
    def state(self) -> IntArray:
        """No product states: -1 for every episode."""
        return np.full(self.num_envs, -1, dtype=np.int64)

    def state_dict(self) -> dict[str, Any]:
        """Everything needed to go on exactly: each wrapper's run (and its env's state, where
        the env has one: a continuous world's does), the episodes' observations and tallies."""
        return {
            "envs": [env.state_dict() for env in self.envs],
            "observation": np.asarray(self.observation).copy(),
            "automaton": self.automaton.copy(),
            "mask": self.mask.copy(),
            "returns": self.returns.copy(),
            "steps": self.steps.copy(),
        }

    def load_state_dict(self, saved: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`."""
        if len(saved["envs"]) != self.num_envs:
            raise ValueError(f"envs: {len(saved['envs'])} saved, {self.num_envs} here")
        for env, state in zip(self.envs, saved["envs"], strict=True):
            env.load_state_dict(state)
        for name in ("observation", "automaton", "mask", "returns", "steps"):
            setattr(self, name, np.array(saved[name]))

    def valid_actions(self) -> BoolArray:
        """``valid[i, a]``: action ``a`` is available to episode ``i``."""
        return np.stack([env.action_masks() for env in self.envs])

    def step(self, actions: IntArray) -> Step:
        """Take ``actions[i]`` in episode ``i``; restart ended episodes."""
        n = self.num_envs
        reward, accepting = np.zeros(n), np.zeros(n, dtype=np.bool_)
        terminated, truncated = np.zeros(n, dtype=np.bool_), np.zeros(n, dtype=np.bool_)
        success = np.zeros(n, dtype=np.bool_)
        reached: list[Any] = []
        restarted: list[Any] = []
        self.infos: list[dict[str, Any]] = []
        """The infos of the last step (before ended episodes restarted)."""
        before = self.mask
        for i, (env, action) in enumerate(zip(self.envs, actions.tolist(), strict=True)):
            obs, r, term, trunc, info = env.step(action)
            reward[i], terminated[i], truncated[i] = r, term, trunc
            marks = sum(1 << k for k in info["marks"])
            accepting[i] = bool(marks & ~int(before[i]))
            success[i] = info["success"]
            self.infos.append(info)
            self.steps[i] = info["step"]
            reached.append(obs)
            restarted.append(env.reset()[0] if term or trunc else obs)
        self.returns += reward
        next_observation, next_automaton, next_mask = self._stack(reached)
        result = Step(
            reward=reward,
            accepting=accepting,
            terminated=terminated,
            truncated=truncated,
            next_state=np.full(n, -1, dtype=np.int64),
            next_mask=next_mask,
            next_observation=next_observation,
            success=success,
            episode_return=self.returns.copy(),
            episode_steps=self.steps.copy(),
            next_automaton=next_automaton,
            next_valid=self._valid_after(next_automaton),
        )
        done = result.done
        self.returns[done], self.steps[done] = 0.0, 0
        self.observation, self.automaton, self.mask = self._stack(restarted)
        return result

    def _stack(self, observations: list[Any]) -> tuple[Any, IntArray, IntArray]:
        own = np.asarray([obs[self.env_key] for obs in observations])
        automaton = np.asarray([obs["automaton"] for obs in observations], dtype=np.int64)
        mask = np.asarray([obs["frontier"] for obs in observations], dtype=np.int64)
        return own, automaton, mask

    def _valid_after(self, automaton: IntArray) -> BoolArray:
        """The actions valid in automaton states ``automaton`` (the wrapper's masks)."""
        masks_of = self.envs[0].masks_of
        return np.stack([masks_of(q) for q in automaton.tolist()])

