"""What the learners read: any ``gymnasium.vector.VectorEnv`` of task-wrapped environments,
seen through :class:`VectorTask`.

The vector env must be what :class:`mitlc.gym.TaskWrapper` makes of each env, batched:

* a ``Dict`` single observation space with the env's own part (any space: a ``Discrete`` one
  is read as it is, any other as its readable part flattened, one vector per episode,
  :func:`mitlc.gym.observations.readable`: a ``Box`` of any rank, ``Dict``, ``Tuple``,
  ``MultiBinary``, ``MultiDiscrete``, nested, text and other parts without numbers left out,
  images listed in :attr:`VectorTask.images`), ``automaton`` and ``frontier``; a ``Discrete``
  single action space;
* ended episodes restart in the same step (``AutoresetMode.SAME_STEP``): the observation an
  ended episode reached is in ``infos["final_obs"]`` and its last info in
  ``infos["final_info"]``, as gymnasium's ``SyncVectorEnv`` and ``AsyncVectorEnv`` give them;
* each step's infos carry the wrapper's task entries: ``accepting`` (the step added a set to
  the frontier), ``action_mask`` (the valid actions, also at reset), ``success`` and ``step``.

:func:`task_vector` builds one from wrapped envs (a ``SyncVectorEnv``); mitlc's numpy simulator
of a finite product is one too (:class:`mitlc.learn.envs.vector.ProductVectorEnv`), and its infos
add ``product_state``, the finite-product adapter read only by the learners that index the
product (tabular Q-learning over product states, counterfactual experience) and by exact
evaluation; elsewhere ``state`` is -1.

:class:`VectorTask` gives the learners the current ``observation`` (the env's part),
``automaton``, ``mask`` (the frontier), ``state``, :meth:`~VectorTask.valid_actions`, and
:meth:`~VectorTask.step`, whose :class:`~mitlc.learn.envs.vec.Step` describes what each episode
reached *before* an ended one restarted, with its return and length so far.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, cast

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode

from mitlc.gym.observations import ImagePart, Readable, readable
from mitlc.learn.envs.vec import Step
from mitlc.worlds.model import BoolArray, IntArray

TASK_KEYS = ("automaton", "frontier")
VIEW = ("observation", "automaton", "mask", "state", "valid", "returns", "steps")
"""The episodes' current view, checkpointed beside in-process wrappers."""


def task_vector(envs: Sequence[gym.Env[Any, Any]], seed: int | None = 0) -> VectorTask:
    """``envs`` (each a :class:`mitlc.gym.TaskWrapper`) stepped in this process by gymnasium's
    ``SyncVectorEnv`` with same-step restarts; env ``i`` is reset first with ``seed + i``."""
    makers = [_returning(env) for env in envs]
    venv = gym.vector.SyncVectorEnv(makers, autoreset_mode=AutoresetMode.SAME_STEP)
    return VectorTask(venv, seed)


def _returning(env: gym.Env[Any, Any]) -> Callable[[], gym.Env[Any, Any]]:
    return lambda: env


class VectorTask:
    """The learners' view of a vector env of wrapped envs (see the module docstring)."""

    def __init__(self, venv: gym.vector.VectorEnv[Any, Any, Any], seed: int | None = None):
        space = venv.single_observation_space
        if not isinstance(space, spaces.Dict) or not set(TASK_KEYS) <= set(space.spaces):
            raise ValueError(f"not a task-wrapped env's observation space: {space}")
        actions = venv.single_action_space
        if not isinstance(actions, spaces.Discrete | spaces.Box):
            raise ValueError(f"the learners need a Discrete or Box action space, not {actions}")
        mode = venv.metadata.get("autoreset_mode")
        if mode != AutoresetMode.SAME_STEP:
            raise ValueError(f"the learners need same-step restarts (AutoresetMode.SAME_STEP), "
                             f"not {mode}")  # fmt: skip
        self.venv, self.num_envs = venv, int(venv.num_envs)
        self.env_key = next(k for k in space.spaces if k not in TASK_KEYS)
        own = space.spaces[self.env_key]
        self.layout: Readable | None = None
        """The readable part of the env's own observation, unless it is ``Discrete``."""
        if not isinstance(own, spaces.Discrete):
            self.layout = readable(own)
            own = self.layout.space
        self.observation_space = spaces.Dict({self.env_key: own, **{
            k: space.spaces[k] for k in TASK_KEYS}})  # fmt: skip
        """The single observation space as the learners read it (the env's part a
        ``Discrete`` or the flat ``Box`` of its readable part)."""
        self.continuous = isinstance(actions, spaces.Box)
        """Box actions (for SB3's policies): no discrete actions, so :meth:`valid_actions` has
        no columns."""
        self.num_actions = 0 if self.continuous else int(cast("spaces.Discrete", actions).n)
        self.returns = np.zeros(self.num_envs)
        self.steps = np.zeros(self.num_envs, dtype=np.int64)
        obs, infos = venv.reset(seed=seed)
        self._last: tuple[dict[str, Any], dict[str, Any], BoolArray] = (
            infos, {}, np.zeros(self.num_envs, dtype=np.bool_))  # fmt: skip
        self._take(obs, infos)

    @property
    def images(self) -> tuple[ImagePart, ...]:
        """The image parts of the env's own observation as the learners read it."""
        return self.layout.images if self.layout is not None else ()

    @property
    def envs(self) -> list[Any]:
        """The wrapped envs, where the vector env steps them in this process."""
        return list(getattr(self.venv, "envs", []))

    # -- checkpoints ---------------------------------------------------------------------------

    def state_dict(self) -> dict[str, Any]:
        """Everything needed to go on exactly. A simulator that checkpoints itself (it has
        ``state_dict``, ``load_state_dict`` and ``current``, as
        :class:`~mitlc.learn.envs.vector.ProductVectorEnv`) gives its own state, which holds its
        episodes' returns; otherwise each in-process wrapper's run (with its env's state) and
        the episodes' current view."""
        venv: Any = self.venv
        if _simulator(venv):
            state: dict[str, Any] = venv.state_dict()
            return state
        envs = getattr(self.venv, "envs", None)
        if envs is None:
            raise ValueError("exact checkpoints need in-process envs (a SyncVectorEnv)")
        view = {name: np.array(getattr(self, name)) for name in VIEW}
        return {"envs": [env.state_dict() for env in envs], **view}

    def load_state_dict(self, saved: dict[str, Any]) -> None:
        """Restore :meth:`state_dict` (``ValueError`` if it does not fit)."""
        venv: Any = self.venv
        if _simulator(venv):
            venv.load_state_dict(saved)
            obs, infos = venv.current()
            self._take(obs, infos)
            self.returns = np.array(saved["returns"], dtype=np.float64)
            self.steps = np.array(infos["step"], dtype=np.int64)
            return
        envs = getattr(self.venv, "envs", None)
        if envs is None or len(saved["envs"]) != len(envs):
            raise ValueError(f"envs: {len(saved['envs'])} saved, {self.num_envs} here")
        for name in VIEW:
            if len(saved[name]) != self.num_envs:
                raise ValueError(f"{name}: {len(saved[name])} episodes saved, {self.num_envs} here")
        if not all(hasattr(env.unwrapped, "load_state_dict") for env in envs):
            # an env whose own state cannot be saved: its running episodes start over, from a
            # seed the checkpoint fixes (the resumed run is reproducible, not the same)
            self.returns = np.zeros(self.num_envs)
            self.steps = np.zeros(self.num_envs, dtype=np.int64)
            obs, infos = self.venv.reset(seed=int(np.sum(saved["steps"])) + 1)
            self._take(obs, infos)
            return
        for env, state in zip(envs, saved["envs"], strict=True):
            env.load_state_dict(state)
        for name in VIEW:
            setattr(self, name, np.array(saved[name]))

    # -- stepping ------------------------------------------------------------------------------

    def valid_actions(self) -> BoolArray:
        """``valid[i, a]``: action ``a`` is available to episode ``i``."""
        return self.valid

    def step(self, actions: IntArray) -> Step:
        """Take ``actions[i]`` in episode ``i``; ended episodes restart. A vector env with
        ``step_task`` (:class:`~mitlc.learn.envs.vector.ProductVectorEnv`) gives the step's
        :class:`~mitlc.learn.envs.vec.Step` itself, which is what the infos would say, faster."""
        fast = getattr(self.venv, "step_task", None)
        if fast is not None:
            result: Step = fast(actions)
            done = result.done
            self.returns = np.where(done, 0.0, result.episode_return)
            self.steps = np.where(done, 0, result.episode_steps)
            self._last = ({}, {}, done)
            self._take(*self.venv.current())  # type: ignore[attr-defined]
            return result
        obs, reward, terminated, truncated, infos = self.venv.step(actions)
        reward = np.asarray(reward, dtype=np.float64)
        terminated = np.asarray(terminated, dtype=np.bool_)
        truncated = np.asarray(truncated, dtype=np.bool_)
        done = terminated | truncated
        final = infos.get("final_info", {}) if done.any() else {}
        own, automaton, mask = self._view(obs, copy=True)
        if final:
            ended = np.flatnonzero(done)
            reached = infos["final_obs"][ended].tolist()
            own[ended] = np.array([self._own_one(obs_i[self.env_key]) for obs_i in reached])
            automaton[ended] = [obs_i["automaton"] for obs_i in reached]
            mask[ended] = [obs_i["frontier"] for obs_i in reached]
        self.returns += reward
        counted = self.steps + 1
        steps = _entry(infos, final, done, "step", counted).astype(np.int64)
        shaped = "distances" in infos
        result = Step(
            reward=reward,
            accepting=_entry(infos, final, done, "accepting", np.zeros(self.num_envs, bool)),
            terminated=terminated,
            truncated=truncated,
            next_state=_entry(infos, final, done, "product_state", np.full(self.num_envs, -1)),
            next_mask=mask,
            next_observation=own,
            success=_entry(infos, final, done, "success", np.zeros(self.num_envs, bool)),
            episode_return=self.returns.copy(),
            episode_steps=steps,
            next_automaton=automaton,
            next_valid=_entry(infos, final, done, "action_mask", self._all_valid()),
            next_potential=_entry(infos, final, done, "potential", np.zeros(self.num_envs)),
            letter=_entry(infos, final, done, "letter", np.full(self.num_envs, -1)),
            env_reward=_entry(infos, final, done, "env_reward", np.zeros(self.num_envs)),
            env_ended=_entry(infos, final, done, "env_ended", np.zeros(self.num_envs, bool)),
            distances=_entry(infos, final, done, "distances", None) if shaped else None,
            distances_left=_entry(infos, final, done, "distances_left", None) if shaped else None,
            episode_rounds=_entry(infos, final, done, "rounds", np.zeros(self.num_envs, int)),
        )
        self.returns[done] = 0.0
        self.steps = np.where(done, 0, steps)
        self._last = (infos, final, done)
        self._take(obs, infos)
        return result

    def reached(self, key: str) -> Any:
        """``info[key]`` of each episode as the last step left it (an ended episode's final
        info, before it restarted), e.g. a continuous world's ``position``."""
        infos, final, done = self._last
        if key not in infos and key not in final:
            raise KeyError(key)
        return _entry(infos, final, done, key, None)

    # -- internals -----------------------------------------------------------------------------

    def _take(self, obs: dict[str, Any], infos: dict[str, Any]) -> None:
        """The episodes' current view after a reset or a step."""
        self.observation, self.automaton, self.mask = self._view(obs, copy=False)
        way = obs.get("guide")
        self.guide = None if way is None else np.asarray(way, dtype=np.float32)
        """The way the shaping pulls, where the wrappers show it (``guide=True``)."""
        mask = infos.get("action_mask")
        self.valid = np.asarray(mask, dtype=np.bool_) if mask is not None else self._all_valid()
        product = infos.get("product_state")
        self.state = np.full(self.num_envs, -1, dtype=np.int64) if product is None else product
        potential = infos.get("potential")
        self.potential = np.zeros(self.num_envs) if potential is None else np.asarray(potential)

    def _view(self, obs: dict[str, Any], *, copy: bool) -> tuple[Any, IntArray, IntArray]:
        own = obs[self.env_key]
        if self.layout is not None:
            own = self.layout.extract_batch(own, self.num_envs)
        if copy and (self.layout is None or self.layout.lone_box):  # else already a new array
            own = np.array(own)
        automaton = np.array(obs["automaton"], dtype=np.int64, copy=copy)
        return own, automaton, np.array(obs["frontier"], dtype=np.int64, copy=copy)

    def _own_one(self, value: Any) -> Any:
        """One episode's own observation as the learners read it."""
        if self.layout is None:
            return value
        return self.layout.extract(value)

    def _all_valid(self) -> BoolArray:
        return np.ones((self.num_envs, self.num_actions), dtype=np.bool_)


def _simulator(venv: Any) -> bool:
    """Whether ``venv`` checkpoints itself (see :meth:`VectorTask.state_dict`)."""
    return all(hasattr(venv, name) for name in ("state_dict", "load_state_dict", "current"))


def _entry(
    infos: dict[str, Any], final: dict[str, Any], done: BoolArray, key: str, default: Any
) -> Any:
    """A copy of ``infos[key]`` (``default`` where the env gives none), with each ended
    episode's ``final_info[key]`` in its place."""
    value = np.array(infos.get(key, default))
    if key in final:
        ended = done & np.asarray(final.get(f"_{key}", done))
        value[ended] = np.asarray(final[key])[ended]
    return value
