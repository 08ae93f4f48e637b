"""Counterfactual experience in the replay memory of SB3's off-policy learners (``sb3-dqn``,
``sb3-sac``, ``sb3-td3`` with ``sb3.crm``; Toro Icarte, Klassen, Valenzano and McIlraith,
"Reward Machines: Exploiting Reward Function Structure in Reinforcement Learning", JAIR 73,
2022: CRM, which pycrm also feeds to SB3's replay).

:class:`CounterfactualReplay` is SB3's ``ReplayBuffer`` (given as ``replay_buffer_class``,
:func:`replay_settings`) that stores, beside each transition SB3 adds, its counterfactuals over
the task's states (:mod:`mitlc.learn.learners.crm_env`: which task states, at most
:data:`~mitlc.learn.learners.crm_env.LIMIT` a step, and the monitor's step over them). A
counterfactual has the experienced observation and next observation (SB3's, with an ended
episode's ``terminal_observation`` in its place) with their task part rebuilt by the wrapper's
own layout (:meth:`mitlc.gym.parts.TaskObservation.observe`, :class:`FlatTask`), the same
action, the monitor's reward (plus ``info["env_reward"]`` where the wrapper adds the env's),
and ``done`` when the task is decided or, still pending, at the horizon (the experienced step's
``info["step"]``); under SB3's ``handle_timeout_termination`` the latter is a timeout, from
which SB3 bootstraps, as for the experienced transitions.

**The task state a transition was taken in** is followed per env inside the buffer, by the
monitor itself: every env starts at the monitor's start (SB3 resets its envs when learning
starts, and an episode restarts there), a world step advances it by the letter read
(``info["letter"]``), a jump sets the automaton state the info reports; each is checked against
the info's ``automaton_state`` and ``step``, and an env whose run the buffer did not follow
from its start (a buffer put in mid-episode) gives no counterfactuals until its next episode.

**Shaping** (a run's ``shaping``: SB3 learns on :class:`mitlc.gym.shaping.ShapedReward`): a
counterfactual's reward is shaped as the wrapper would have shaped it in its own task state,
``scale * (gamma * Phi(q', s') - Phi(q, s))``, the potentials the wrapper's
(:meth:`~mitlc.learn.learners.crm_env.EnvCounterfactuals.potentials`, from the distances the
step's info reports: ``distances_left`` of the position left, ``distances`` of the one
reached).

**The way** (a run's ``guide``: the observation ends with the way the shaping pulls, which
depends on the task state): a counterfactual shows the way of its own task state, as the
wrapper would show it there (:meth:`mitlc.gym.TaskWrapper.way_at`, the one rule of the way,
from the directions the step's info reports: ``ways_left``, ``ways``).

**Skipped**: the transitions of :meth:`~mitlc.learn.learners.crm_env.EnvCounterfactuals.tells`
(a jump or an invalid action, an env that has ended). SB3's ``optimize_memory_usage`` is
refused (each stored transition needs its own next observation). SB3 stores transitions
``n_envs`` at a time (one row per env): counterfactuals wait in a queue until they fill a row,
so up to ``n_envs - 1`` of them are stored one step late. The experienced transitions are
stored as SB3 stores them; :attr:`CounterfactualReplay.counterfactual` marks the others.

This module imports Stable-Baselines3: import it only where SB3 is installed.
"""

from __future__ import annotations

import copy
from typing import Any

import numpy as np
import numpy.typing as npt
import torch
from gymnasium import spaces
from stable_baselines3.common.buffers import ReplayBuffer

from mitlc.gym.parts import TaskObservation
from mitlc.learn.config import TrainConfig
from mitlc.learn.learners.crm_env import (
    LIMIT,
    CounterfactualError,
    EnvCounterfactuals,
    Rows,
    task_wrapper,
)
from mitlc.learn.rundir.files import RunError
from mitlc.task import MonitorState
from mitlc.worlds.model import BoolArray, IntArray

Flat = npt.NDArray[np.float32]
FIELDS = ("obs", "next_obs", "action", "reward", "done", "timeout")
Where = tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]
"""Per row, the distances to the propositions and their directions (``info["distances"]``,
``info["ways"]``)."""
DENSE = 1 << 20
"""The most task states ``(q, frontier)`` that :class:`FlatTask` indexes densely."""


class FlatTask:
    """A wrapped env's task as the buffer needs it: its counterfactuals and its flat
    observation, whose task part (after the env's ``view.env_dim`` values) :meth:`observe`
    replaces."""

    def __init__(
        self, counterfactuals: EnvCounterfactuals, view: TaskObservation, wrapper: Any = None
    ) -> None:
        """``wrapper``: the task wrapper whose :meth:`~mitlc.gym.TaskWrapper.way_at` gives a
        task state's way, where the observation shows one (``view.guide``)."""
        if not view.flatten:
            raise CounterfactualError("sb3.crm needs the wrapper's flat observation")
        if view.guide and wrapper is None:
            raise CounterfactualError("sb3.crm: the way is shown, but no wrapper gives it")
        self.counterfactuals, self.view, self._wrapper = counterfactuals, view, wrapper
        space = copy.deepcopy(view.env_space)
        space.seed(0)
        self._reference = space.sample()
        """An observation of the env, whose part :meth:`observe` does not keep."""
        self._parts: dict[tuple[int, int], Flat] = {}
        self._frontiers = 1 << view.num_sets
        dense = view.num_q * self._frontiers <= DENSE
        self._index = np.full((view.num_q, self._frontiers) if dense else (0, 0), -1)
        """Where :attr:`_table` holds the part of ``(q, frontier)`` (-1: not yet made)."""
        width = spaces.flatdim(view.space) - view.env_dim
        self._table = np.zeros((0, width), dtype=np.float32)

    @staticmethod
    def of(env: Any, limit: int = LIMIT) -> FlatTask:
        """The task of the :class:`mitlc.gym.TaskWrapper` ``env`` is or wraps, made with
        ``flatten=True`` (its layout rebuilt from its own parts and checked against its
        space), giving at most ``limit`` counterfactuals a step (``sb3.crm_limit``)."""
        wrapper = task_wrapper(env)
        automaton = wrapper.automaton
        view = TaskObservation.of(wrapper.env.observation_space, "env", wrapper.num_q,
                                  automaton.num_sets, wrapper.flatten, wrapper.clocks,
                                  wrapper.way_size)  # fmt: skip
        if view.space != wrapper.observation_space:
            raise CounterfactualError(
                f"the wrapper's observation {wrapper.observation_space} is not the layout "
                f"{view.space} of its parts"
            )
        return FlatTask(EnvCounterfactuals.of(wrapper, limit), view, wrapper)

    def part(self, q: int, frontier: int) -> Flat:
        """The task part of a flat observation in task state ``(q, frontier)``."""
        found = self._parts.get((q, frontier))
        if found is None:
            whole = self.view.observe(self._reference, q, frontier)
            found = self._parts[(q, frontier)] = np.asarray(whole[self.view.env_dim :])
        return found

    def observe(
        self,
        flat: Flat,
        q: IntArray,
        frontier: IntArray,
        where: Where | None = None,
    ) -> Flat:
        """Each row of ``flat`` with its task part that of ``(q[r], frontier[r])``; where the
        observation shows the way, that of ``q[r]`` at the position whose distances and
        directions are ``where[0][r]``, ``where[1][r]`` (``info["distances"]``,
        ``info["ways"]``)."""
        out = self._task_parts(flat, q, frontier)
        if self.view.guide:
            if where is None:
                raise CounterfactualError("sb3.crm: the way is shown, but the step gave none")
            distances, ways = where
            for r, qr in enumerate(q.tolist()):
                out[r, -self.view.guide :] = self._wrapper.way_at(qr, distances[r], ways[r])
        return out

    def _task_parts(self, flat: Flat, q: IntArray, frontier: IntArray) -> Flat:
        """Each row of ``flat`` with the task part of ``(q[r], frontier[r])`` (no way)."""
        out = np.array(flat, dtype=np.float32, copy=True)
        dim = self.view.env_dim
        if not self._index.size:  # too many task states for a dense index
            for r, (qr, fr) in enumerate(zip(q.tolist(), frontier.tolist(), strict=True)):
                out[r, dim:] = self.part(qr, fr)
            return out
        where = self._index[q, frontier]
        missing = where < 0
        if missing.any():
            self._add_parts(q[missing], frontier[missing])
            where = self._index[q, frontier]
        out[:, dim:] = self._table[where]
        return out

    def _add_parts(self, q: IntArray, frontier: IntArray) -> None:
        """Put the parts of the task states ``(q[r], frontier[r])`` in the dense table."""
        new = sorted({(int(a), int(b)) for a, b in zip(q, frontier, strict=True)})
        first = len(self._table)
        self._table = np.concatenate([self._table, np.stack([self.part(a, b) for a, b in new])])
        for k, (a, b) in enumerate(new):
            self._index[a, b] = first + k


class CounterfactualReplay(ReplayBuffer):
    """SB3's replay memory with the counterfactuals of every transition (see the module
    docstring); ``task`` and ``seed`` (of the sample of counterfactuals above the bound) come
    through ``replay_buffer_kwargs``."""

    def __init__(
        self,
        buffer_size: int,
        observation_space: spaces.Space[Any],
        action_space: spaces.Space[Any],
        device: torch.device | str = "auto",
        n_envs: int = 1,
        optimize_memory_usage: bool = False,
        handle_timeout_termination: bool = True,
        *,
        task: FlatTask,
        seed: int = 0,
        shaping: float = 0.0,
        gamma: float = 1.0,
        share: float = 0.0,
    ) -> None:
        if optimize_memory_usage:
            raise CounterfactualError("sb3.crm: each transition needs its own next observation, "
                                      "not SB3's optimize_memory_usage")  # fmt: skip
        super().__init__(buffer_size, observation_space, action_space, device, n_envs,
                         optimize_memory_usage, handle_timeout_termination)  # fmt: skip
        self.task, self.rng = task, np.random.default_rng(seed)
        self.shaping, self.gamma = shaping, gamma
        """The scale of the shaping potential (0: none) and the discount it is shaped at."""
        self.share = share
        """The share of each sampled batch that is counterfactual (``sb3.crm_share``; 0: SB3's
        uniform sample over the whole memory, see :meth:`sample`)."""
        self.counterfactual = np.zeros((self.buffer_size, self.n_envs), dtype=np.bool_)
        """Which stored transitions are counterfactual."""
        self.made = 0
        """Counterfactual transitions made so far (stored, or waiting in the queue)."""
        monitor = task.counterfactuals.monitor
        self.runs: list[MonitorState | None] = [monitor.reset()] * self.n_envs
        """The task state of each env's episode now (``None``: not followed)."""
        self._queue: dict[str, npt.NDArray[Any]] = {}

    def add(
        self,
        obs: npt.NDArray[Any],
        next_obs: npt.NDArray[Any],
        action: npt.NDArray[Any],
        reward: npt.NDArray[Any],
        done: npt.NDArray[Any],
        infos: list[dict[str, Any]],
    ) -> None:
        """Store SB3's transitions, then their counterfactuals (by whole rows of
        ``n_envs``)."""
        made = self._counterfactuals(obs, next_obs, action, infos)
        self.counterfactual[self.pos] = False  # the experienced row, stored as SB3 stores it
        super().add(obs, next_obs, action, reward, done, infos)
        self._follow(np.asarray(done, dtype=np.bool_), infos)
        self.made += len(made["reward"])
        queue = self._queue
        self._queue = {k: np.concatenate([queue[k], made[k]]) for k in FIELDS} if queue else made
        whole = len(self._queue["reward"]) // self.n_envs * self.n_envs
        if whole:
            self.store_rows({k: v[:whole] for k, v in self._queue.items()})
            self._queue = {k: v[whole:] for k, v in self._queue.items()}

    def sample(self, batch_size: int, env: Any = None) -> Any:
        """A batch for a gradient step. With no :attr:`share`, SB3's: uniform over the
        transitions held, so with ``k`` counterfactuals a step one in ``k + 1`` was lived.
        With a share ``p``, a fixed mix, as SB3's HER fixes its share of relabelled goals:
        ``round(p * batch_size)`` transitions uniform among the counterfactual ones held and the
        rest uniform among the lived ones (all of one kind while the memory holds no other),
        drawn from the memory's own generator, which its checkpoint keeps."""
        if not self.share:
            return super().sample(batch_size, env=env)
        upper = self.buffer_size if self.full else self.pos
        flags = self.counterfactual[:upper].reshape(-1)
        made = int(np.count_nonzero(flags))
        lived = flags.size - made
        wanted = round(self.share * batch_size) if made and lived else batch_size * (made > 0)
        cells = np.concatenate([self._draw(flags, True, made, wanted),
                                self._draw(flags, False, lived, batch_size - wanted)])  # fmt: skip
        rows, envs = np.divmod(cells, self.n_envs)
        return self._samples_at(rows, envs, env)

    def _draw(self, flags: BoolArray, kind: bool, held: int, count: int) -> IntArray:
        """``count`` cells (row * n_envs + env) drawn uniformly, with replacement, among those
        whose flag is ``kind`` (``held`` of them): uniform draws over all cells, the others
        left out, until there are enough."""
        drawn = np.zeros(0, dtype=np.int64)
        while len(drawn) < count:
            tries = int((count - len(drawn)) * flags.size / held * 1.25) + 8
            candidates = self.rng.integers(flags.size, size=tries)
            drawn = np.concatenate([drawn, candidates[flags[candidates] == kind]])
        return drawn[:count]

    def _samples_at(self, rows: IntArray, envs: IntArray, env: Any) -> Any:
        """SB3's ``ReplayBuffer._get_samples`` at the given rows and envs (SB3 draws the envs
        itself), for a memory without ``optimize_memory_usage``."""
        from stable_baselines3.common.type_aliases import ReplayBufferSamples

        live = (self.dones[rows, envs] * (1 - self.timeouts[rows, envs])).reshape(-1, 1)
        data = (
            self._normalize_obs(self.observations[rows, envs, :], env),
            self.actions[rows, envs, :],
            self._normalize_obs(self.next_observations[rows, envs, :], env),
            live,
            self._normalize_reward(self.rewards[rows, envs].reshape(-1, 1), env),
        )
        return ReplayBufferSamples(*tuple(map(self.to_torch, data)))

    def store_rows(self, rows: dict[str, npt.NDArray[Any]]) -> None:
        """Store counterfactual transitions (the fields of :data:`FIELDS`, a whole number of
        rows of ``n_envs``) at once, as as many calls of SB3's ``add`` would, one row each."""
        n = self.n_envs
        count = len(rows["reward"]) // n
        keep = min(count, self.buffer_size)  # a block longer than the memory: its last rows
        at = (self.pos + count - keep + np.arange(keep)) % self.buffer_size

        def block(key: str, *shape: int) -> npt.NDArray[Any]:
            return np.asarray(rows[key]).reshape(count, n, *shape)[count - keep :]

        self.observations[at] = block("obs", *self.obs_shape)
        self.next_observations[at] = block("next_obs", *self.obs_shape)
        self.actions[at] = block("action", self.action_dim)
        self.rewards[at] = block("reward")
        self.dones[at] = block("done")
        if self.handle_timeout_termination:
            self.timeouts[at] = block("timeout")
        self.counterfactual[at] = True
        self.full = self.full or self.pos + count >= self.buffer_size
        self.pos = (self.pos + count) % self.buffer_size

    def _counterfactuals(
        self,
        obs: npt.NDArray[Any],
        next_obs: npt.NDArray[Any],
        action: npt.NDArray[Any],
        infos: list[dict[str, Any]],
    ) -> dict[str, npt.NDArray[Any]]:
        """The counterfactual transitions of one vector step, as the fields of
        :data:`FIELDS`."""
        crm = self.task.counterfactuals
        runs = self.runs
        known = np.array([run is not None for run in runs], dtype=np.bool_)
        q, frontier, rounds = (np.array([getattr(run, name, 0) for run in runs], dtype=np.int64)
                               for name in ("q", "frontier", "rounds"))  # fmt: skip
        letter = np.array([info.get("letter", -1) for info in infos], dtype=np.int64)
        ended = np.array([info.get("env_ended", False) for info in infos], dtype=np.bool_)
        env_reward = np.array([info.get("env_reward", 0.0) for info in infos], dtype=np.float64)
        told: BoolArray = crm.tells(letter, ended) & known
        rows: Rows = crm.rows(q, frontier, letter, env_reward, told, self.rng, rounds)
        i = rows.source
        reward = rows.reward
        guide = bool(self.task.view.guide)
        keys: tuple[str, ...] = ("distances_left", "distances") if self.shaping or guide else ()
        keys += ("ways_left", "ways") if guide else ()
        # each env's entries of the step's info, read once for the shaping and the way
        read = {key: np.array([info[key] for info in infos], dtype=np.float64) for key in keys}
        if self.shaping:
            gammas = np.full(len(reward), self.gamma)
            reward = crm.shaped_reward(
                rows, gammas, read["distances_left"], read["distances"], self.shaping
            )
        steps = np.array([info.get("step", 0) for info in infos], dtype=np.int64)[i]
        truncated = ~rows.terminated & (steps >= crm.horizon)
        flat = np.asarray(obs).reshape(self.n_envs, -1)
        after = np.asarray(next_obs).reshape(self.n_envs, -1)
        from_: Where | None = None  # where the way is shown: what it is read from
        to: Where | None = None
        if guide:
            from_ = (read["distances_left"][i], read["ways_left"][i])
            to = (read["distances"][i], read["ways"][i])
        return {
            "obs": self.task.observe(flat[i], rows.q, rows.frontier, from_),
            "next_obs": self.task.observe(after[i], rows.next_q, rows.next_frontier, to),
            "action": np.asarray(action).reshape(self.n_envs, self.action_dim)[i],
            "reward": reward.astype(np.float32),
            "done": (rows.terminated | truncated).astype(np.float32),
            "timeout": truncated,
        }

    def _follow(self, done: BoolArray, infos: list[dict[str, Any]]) -> None:
        """Advance each env's task state by its step (see the module docstring)."""
        monitor = self.task.counterfactuals.monitor
        for i, info in enumerate(infos):
            run = self.runs[i]
            if done[i]:
                self.runs[i] = monitor.reset()
                continue
            if run is None:
                continue
            letter = int(info.get("letter", -1))
            q, steps = int(info.get("automaton_state", -1)), int(info.get("step", -1))
            if letter >= 0:
                after = monitor.step(run, letter).state
            else:  # a jump (or an invalid action): the frontier stays
                after = MonitorState(q, run.frontier, int(info.get("rounds", 0)), steps)
            self.runs[i] = after if (after.q, after.steps) == (q, steps) else None


def replay_settings(config: TrainConfig, env: Any) -> dict[str, Any]:
    """SB3's ``replay_buffer_class`` and ``replay_buffer_kwargs`` for ``sb3.crm`` on ``env``
    (the run's wrapped env; nothing without ``sb3.crm``); a :class:`RunError` where it cannot
    be."""
    if not config.sb3.crm:
        return {}
    from mitlc.learn.backends.sb3_offpolicy import OFF_POLICY

    if config.algo not in OFF_POLICY:
        raise RunError(f"sb3.crm: counterfactual experience goes into a replay memory: "
                       f"{', '.join(OFF_POLICY)}, not {config.algo}")  # fmt: skip
    try:
        task = FlatTask.of(env, config.sb3.crm_limit)
    except CounterfactualError as err:
        raise RunError(f"sb3.crm: {err}") from None
    kwargs = {"task": task, "seed": config.seed, "shaping": config.shaping,
              "gamma": config.discount.gamma, "share": config.sb3.crm_share}  # fmt: skip
    return {"replay_buffer_class": CounterfactualReplay, "replay_buffer_kwargs": kwargs}
