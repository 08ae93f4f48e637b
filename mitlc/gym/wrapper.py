"""``TaskWrapper``: a timed task (an MITL spec) on any gymnasium environment.

The wrapper defines no rule of the task: every automaton step, frontier update, reward term,
verdict, termination and success is :class:`mitlc.task.TaskMonitor`'s. What it adds is the
plumbing between the monitor and the environment:

* **Letters.** Position 0 is the observation ``reset`` returns. Labels read ``(obs, info)`` and
  the :class:`~mitlc.labels.Moment`: ``env.unwrapped`` and the reward and termination of the
  step that reached the position (paths checked at the first reset and step:
  :mod:`mitlc.labels.probe`); ``held`` or-s every letter read. On a world action the monitor
  reads the letter of the position being *left* (the labels of the current ``obs``/``info``),
  then the environment steps and the new letter is remembered for the next step; so a verdict
  shows one step after arrival (the convention of the explicit product). A declared label with
  ``probability: p`` (``{obs: [15], probability: 0.9}``: :mod:`mitlc.labels.chance`) is
  perceived with probability ``p`` where its form holds, drawn at every position read (the
  reset's and each step's, not after the env has ended: the last letter stays), from the env's
  own generator, the wrapper's ``np_random``, which ``reset(seed=...)`` seeds: an episode is
  reproducible from its seed, and a label of probability 1 draws nothing.
* **Observation.** ``Dict({"env": env's space, "automaton": Discrete(Q), "frontier":
  Discrete(2 ** num_sets)})``: the frontier (the acceptance sets seen in the current round) is
  the monitor's bit mask as one integer, so the observation is the task's full state and
  Stable-Baselines3 one-hot encodes it. With ``task_obs="clocks"`` the task's state is
  shown by its clock view (:mod:`mitlc.automata.clocks`): ``location`` (a ``Discrete`` of the
  T-LDGBA's locations) and ``clocks`` (a ``Box`` of its clocks over their bounds) in place of
  ``automaton``; the digital state is still the monitor's and ``info["automaton_state"]``.
  ``Q`` is the number of states of an eager
  :class:`~mitlc.automata.DigitalAutomaton` (or ``max_automaton_states``, if larger); any other
  (lazy) automaton needs ``max_automaton_states``, and a run that reaches a state past it, or a
  state with more jumps than ``max_jumps`` (default 0), raises :class:`TaskWrapperError`.
  With ``flatten=True``: one float32 ``Box``, the readable part of the env's observation
  flattened as ``gymnasium.spaces.flatten`` does (text parts left out:
  :mod:`mitlc.gym.observations`), a one-hot of the automaton state (or its clock view's
  features) and the ``num_sets`` frontier bits. The env's
  part is named ``env_key`` (``"env"``; the grid product names it ``"world"``).
* **Actions.** The env's. If the automaton has epsilon jumps (``J`` at most from a state), the
  env's action space must be ``Discrete(n)`` and becomes ``Discrete(n + J)``: action ``n + j``
  takes the ``j``-th jump of the current state; no time passes, the env is not stepped and its
  part of the observation is unchanged. A jump the state does not have is *invalid*: nothing
  moves, the reward is 0, ``info["invalid_action"]`` is True, and it costs a step of the
  horizon, so an agent that ignores :meth:`TaskWrapper.action_masks` still ends every episode.
* **The end of the inner env.** An env that terminates, or truncates before the task's horizon
  (its own ``TimeLimit``, or its own notion of duration), ends the *world*, not the task: as
  in a finite world, whose terminal states are absorbing, the world stays on its last position
  and the task goes on reading its last letter, one step of the horizon per world action,
  until the task is decided or the horizon is reached (the env is not stepped again and adds
  no reward). ``info["env_ended"]`` is True from that step on. With ``env_end="step"`` every
  such step is an action of the agent's, so it can still take an epsilon jump there, exactly
  as in the finite product; with ``"finish"`` the rest of the episode is run within the one
  ``step`` call that ended the env (no choice is left when the task has no jumps; rewards
  summed, ``info["marks"]`` their union). The default, ``"auto"``, is ``"step"`` when the task
  has jumps and ``"finish"`` otherwise. An env that truncates before the horizon is warned
  about once (:class:`EpisodeCutWarning`), and so is an env with a ``TimeLimit`` shorter than
  the horizon, when the wrapper is made.
* **Episode end** (one rule for every path, :mod:`mitlc.task.rules`): ``terminated`` when the
  task is decided (*satisfied* or *violated*); ``truncated`` when it is still pending after
  ``horizon`` steps (world steps, stutters and invalid actions). Exactly one of them is true
  at the end, and ``info["success"]`` is then the task's success: a decided task's verdict, a
  pending one's value on the finite trace it read (:func:`mitlc.task.rules.success`). At every
  step ``info["success"]`` says what the episode's success would be if it stopped there, so an
  outer ``TimeLimit`` (``gymnasium.make(ENV_ID, ..., max_episode_steps=k)``) that cuts the
  episode short judges it by the same rule.
* **Reward.** The monitor's, replacing the env's (``reward_mode="replace"``) or added to it
  (``"add"``; a jump or an invalid action never steps the env, so adds nothing).
* **info.** The env's last info, plus ``env_ended``, ``verdict``, ``marks`` (acceptance-set
  indices), ``rounds``, ``success``, ``is_success`` (SB3's name; equal to ``success``), ``step``,
  ``invalid_action``, ``automaton_state``, ``accepting`` (the step added a set to the
  frontier: the monitor's ``new``), ``letter`` (the letter the task read on this step, that of
  the position left, as perceived: a label with a probability is there only where its draw
  held; nothing else about the draws is added; -1 where it read none: a reset or a jump),
  ``env_reward`` (the env's
  reward of the step, 0 where the env did not step) and, with a ``Discrete`` action space,
  ``action_mask`` (the
  valid actions now, :meth:`TaskWrapper.masks_of`; gymnasium's toy-text convention, so that a
  vector env's ``final_info`` carries the mask of the state an episode ended in). Made with
  ``potential=REACH``: ``potential`` (the task's shaping potential now), ``distances`` and
  ``distances_left`` (how far the positions reached and left are from each proposition;
  :class:`mitlc.gym.guide.TaskGuide` keeps them): through free space where the env's occupancy
  is known (``occupancy``: ``"auto"`` reads a maze's ``maze_map``, a MiniGrid grid, a plane's
  obstacles, :mod:`mitlc.labels.geodesic`; or a declared grid), straight lines elsewhere, warned
  about once (:class:`~mitlc.gym.guide.StraightDistanceWarning`). Made with ``guide=True``
  too: ``ways`` and ``ways_left`` (each proposition's direction at those positions, a row each,
  ``nan`` where it has none; :meth:`TaskWrapper.way_at` reads them).

``gymnasium.make("mitlc/Task-v0", env_id=..., env_kwargs=..., spec=..., labels=...,
horizon=...)`` builds the inner env by id and wraps it.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from typing import Any, Literal

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.utils import RecordConstructorArgs

from mitlc.automata import DigitalAutomaton
from mitlc.gym.arguments import (
    TaskWrapperError,
    check_arguments,
    shaping_of,
    task_of,
    task_rewards,
)
from mitlc.gym.guide import OccupancyChoice, TaskGuide, geodesic_of
from mitlc.gym.parts import TaskObservation, data_only, time_limit
from mitlc.gym.reading import LetterTaker, run_out
from mitlc.labels import LabelFunction, Labels, as_labels
from mitlc.task import VERDICT_NAMES, MonitorState, Outcome, TaskAutomaton, TaskMonitor
from mitlc.task.rules import VERDICT_CODES, TaskRewards
from mitlc.worlds.model import BoolArray, FloatArray, IntArray

ENV_ID = "mitlc/Task-v0"
"""``gymnasium.make(ENV_ID, env_id=..., spec=..., labels=..., horizon=...)``."""

PENDING = VERDICT_CODES["pending"]
RewardMode = Literal["replace", "add"]
EnvEnd = Literal["auto", "step", "finish"]
TaskObs = Literal["state", "clocks"]


class EpisodeCutWarning(UserWarning):
    """The inner env ends its episodes before the task's horizon (the world then stays on its
    last position until the task is decided or the horizon is reached)."""


class TaskWrapper(gym.Wrapper[Any, Any, Any, Any], RecordConstructorArgs):
    """A task on a gymnasium environment (see the module docstring)."""

    _spec_is_inner = False
    """Set where the inner env's spec already names the whole (a registered entry point)."""

    def __init__(
        self,
        env: gym.Env[Any, Any],
        spec: str | TaskAutomaton,
        labels: Labels | LabelFunction | Mapping[str, Any],
        *,
        rewards: TaskRewards | Mapping[str, float] | None = None,
        horizon: int,
        reward_mode: RewardMode = "replace",
        flatten: bool = False,
        max_automaton_states: int | None = None,
        max_jumps: int | None = None,
        env_key: str = "env",
        env_end: EnvEnd = "auto",
        task_obs: TaskObs = "state",
        potential: float | None = None,
        occupancy: OccupancyChoice = "auto",
        guide: bool = False,
    ) -> None:
        """Wrap ``env`` with the task ``spec`` (a formula's text, or an automaton), read through
        ``labels``. ``max_automaton_states`` (and ``max_jumps``, default 0) size a lazy
        automaton's part of the spaces; ``env_key`` names the env's part of the observation;
        ``env_end`` says how the steps after the env has ended are taken; ``task_obs`` shows
        the task's state as the automaton state or by its clocks; with ``potential`` (the
        env distance at which a label's pull is flat; 0: the largest at the first reset)
        ``info["potential"]`` is the task's shaping potential (module docstring), and
        ``info["distances"]`` / ``info["distances_left"]`` how far the positions reached and
        left are from each proposition (:meth:`potential_at` reads them for any task state),
        measured through the free cells of ``occupancy`` (module docstring); with ``guide``
        (and ``potential``) the observation shows the way the potential pulls, a unit vector
        (:meth:`mitlc.gym.guide.TaskGuide.way`), and ``info["ways"]`` / ``info["ways_left"]``
        each proposition's direction at the two positions (:meth:`way_at` reads them for any
        task state)."""
        RecordConstructorArgs.__init__(
            self, _disable_deepcopy=True, spec=spec, labels=labels, rewards=rewards,
            horizon=horizon, reward_mode=reward_mode, flatten=flatten,
            max_automaton_states=max_automaton_states, max_jumps=max_jumps, env_key=env_key,
            env_end=env_end, task_obs=task_obs, potential=potential, occupancy=occupancy,
            guide=guide,
        )  # fmt: skip
        options = dict(
            rewards=rewards, horizon=horizon, reward_mode=reward_mode, flatten=flatten,
            max_automaton_states=max_automaton_states, max_jumps=max_jumps, env_key=env_key,
            env_end=env_end, task_obs=task_obs, potential=potential, guide=guide,
        )  # fmt: skip
        check_arguments(env, spec, labels, options)
        gym.Wrapper.__init__(self, env)
        automaton, self.clocks = task_of(spec, task_obs)
        self.automaton: TaskAutomaton = automaton
        self.monitor = TaskMonitor(automaton, task_rewards(rewards))
        self.labels = as_labels(labels, env.observation_space)
        self._letters = LetterTaker(self.labels, automaton.propositions, env.unwrapped)
        self.held = 0
        """The letters read so far, or-ed: bit ``i`` is set once ``automaton.propositions[i]``
        has held (a proposition that never holds is almost always a mistaken label)."""
        self.horizon, self.reward_mode, self.flatten = int(horizon), reward_mode, bool(flatten)
        self._cut_warned = False
        limit = time_limit(env)
        if limit is not None and limit < self.horizon:
            self._warn_cut(
                f"the env's own time limit ({limit} steps) ends episodes before the task's "
                f"horizon ({horizon})"
            )
        self._add = reward_mode == "add"
        self.num_q, self.max_jumps = self._sizes(max_automaton_states, max_jumps)
        self.env_end: EnvEnd = env_end
        self._finish = env_end == "finish" or (env_end == "auto" and not self.max_jumps)
        self._checked_below = self.num_q if isinstance(automaton, DigitalAutomaton) else 0
        self._num_sets = automaton.num_sets
        self._mark_lists = [
            tuple(k for k in range(self._num_sets) if m >> k & 1)
            for m in range(1 << min(self._num_sets, 12))
        ]
        self._env_key = env_key
        shaping = shaping_of(automaton, potential)
        self._guide = None
        if shaping is not None:
            geodesic = geodesic_of(env.unwrapped, self.labels, occupancy)
            self._guide = TaskGuide(shaping, automaton.propositions, float(potential or 0.0),
                                    geodesic, env.unwrapped)  # fmt: skip
            if guide:
                self._guide.point(self.labels)
        self._action_spaces(env.action_space)
        self._observation_spaces(env.observation_space)
        self._state: MonitorState = self.monitor.reset()
        self._letter, self._done, self._ended = 0, True, False
        self._env_obs: Any = None
        self._env_info: dict[str, Any] = {}

    def _warn_cut(self, what: str) -> None:
        if not self._cut_warned:
            self._cut_warned = True
            warnings.warn(
                f"{what}: the world stays on its last position until the task is decided or "
                f"its horizon is reached (make the env with gymnasium.make(..., "
                f"max_episode_steps={self.horizon}) or a longer duration to let it move)",
                EpisodeCutWarning,
                stacklevel=3,
            )

    def _sizes(self, max_states: int | None, max_jumps: int | None) -> tuple[int, int]:
        if not isinstance(self.automaton, DigitalAutomaton):
            if max_states is None or max_states < 1:
                raise TaskWrapperError(
                    "max_automaton_states: a lazy automaton needs a positive bound on its states"
                )
            return max_states, max_jumps or 0
        count = len(self.automaton.states)
        if count:
            self.monitor.jumps(count - 1)  # learns every state at once (one by one: quadratic)
        jumps = max((len(self.monitor.jumps(q)) for q in range(count)), default=0)
        if max_states is not None and max_states < count:
            raise TaskWrapperError(
                f"max_automaton_states: {max_states} is below the automaton's {count} states"
            )
        return max_states or count, max(jumps, max_jumps or 0)

    def _action_spaces(self, space: spaces.Space[Any]) -> None:
        self._discrete = isinstance(space, spaces.Discrete)
        if not self._discrete:
            if self.max_jumps:
                raise TaskWrapperError(
                    "the task has epsilon jumps, so the env's actions must be Discrete, "
                    f"not {space}"
                )
            self._env_actions = self._action_start = 0
            return
        assert isinstance(space, spaces.Discrete)
        self._env_actions, self._action_start = int(space.n), int(space.start)
        self._num_actions = self._env_actions + self.max_jumps
        if self.max_jumps:
            self.action_space = spaces.Discrete(self._num_actions, start=self._action_start)
        self._masks: dict[int, BoolArray] = {}

    def _observation_spaces(self, space: spaces.Space[Any]) -> None:
        try:
            pointing = self._guide.pointing if self._guide is not None else 0
            self._view = TaskObservation.of(
                space, self._env_key, self.num_q, self._num_sets, self.flatten, self.clocks,
                pointing,
            )  # fmt: skip
        except ValueError as err:
            raise TaskWrapperError(f"flatten: {err}") from None
        self.observation_space = self._view.space

    # -- state ---------------------------------------------------------------------------------

    @property
    def automaton_state(self) -> int:
        """The automaton state ``q``."""
        return self._state.q

    @property
    def frontier(self) -> int:
        """The mask of acceptance sets seen in the current round."""
        return self._state.frontier

    @property
    def rounds(self) -> int:
        """Completed rounds of all acceptance sets."""
        return self._state.rounds

    @property
    def steps(self) -> int:
        """Steps taken towards the horizon (world steps, stutters and invalid actions)."""
        return self._state.steps

    @property
    def spec(self) -> Any:  # type: ignore[override]
        """The env's spec, with this wrapper's (gymnasium's convention), or the inner env's
        alone where it already names the whole (a registered entry point)."""
        return self.env.spec if self._spec_is_inner else super().spec

    def action_masks(self) -> BoolArray:
        """Which actions are valid now (sb3-contrib's ``MaskablePPO`` convention): every env
        action and the jumps of the current automaton state."""
        return self.masks_of(self._state.q).copy()

    def masks_of(self, q: int) -> BoolArray:
        """The valid actions in automaton state ``q`` (read-only; cached per state)."""
        if not self._discrete:
            raise TaskWrapperError(
                f"action masks need a Discrete action space, not {self.action_space}"
            )
        mask = self._masks.get(q)
        if mask is None:
            mask = np.zeros(self._num_actions, dtype=np.bool_)
            mask[: self._env_actions + len(self.monitor.jumps(q))] = True
            mask.setflags(write=False)
            self._masks[q] = mask
        return mask

    def potential(self) -> float:
        """The task's shaping potential now (:mod:`mitlc.task.potential`; unscaled, 0 once the
        task is decided); needs ``potential`` set when the wrapper was made."""
        return self._potential_here(self.distances())

    def _potential_here(self, here: FloatArray) -> float:
        """:meth:`potential` at the distances ``here`` of the position now."""
        return float(self.potential_at(np.array([self._state.q]), here[None, :])[0])

    @property
    def reach(self) -> float:
        """The distance that scales the potential's pull (``potential=REACH``; where it was 0,
        the largest distance at the first reset, and 0 before it)."""
        return self._guide.reach if self._guide is not None else 0.0

    @property
    def way_size(self) -> int:
        """The number of values of the way the observation shows (``guide=True``; 0: none)."""
        return self._guide.pointing if self._guide is not None else 0

    def way_at(self, q: int, distances: FloatArray, ways: FloatArray) -> FloatArray:
        """The way the observation shows in automaton state ``q`` at a position whose
        ``info["distances"]`` and ``info["ways"]`` are ``distances`` and ``ways``
        (:meth:`mitlc.gym.guide.TaskGuide.way_at`; ``guide=True``)."""
        if self._guide is None or not self._guide.pointing:
            raise TaskWrapperError("way_at: make the wrapper with guide=True")
        return self._guide.way_at(q, distances, ways)

    @property
    def has_potential(self) -> bool:
        """Whether the wrapper was made with ``potential`` (and reports it)."""
        return self._guide is not None

    def potential_at(self, q: IntArray, distances: FloatArray) -> FloatArray:
        """The shaping potential (unscaled) of automaton state ``q[r]`` at a position whose
        distances to the propositions are ``distances[r]`` (as :meth:`distances` gives them):
        what :meth:`potential` reports, for any task state (0 where ``q[r]`` is decided)."""
        if self._guide is None:
            raise TaskWrapperError("potential: make the wrapper with potential=REACH")
        q = np.asarray(q, dtype=np.int64)
        return self._guide.at(q, distances, self.monitor.verdicts(q) == PENDING)

    def distances(self) -> FloatArray:
        """How far the position now is from each of the automaton's propositions (``nan``: no
        distance), as the potential reads it; ``info["distances"]`` holds it after every step
        and ``info["distances_left"]`` that of the position the step left."""
        if self._guide is None:
            return np.full(len(self.automaton.propositions), np.nan)
        return self._guide.array(self._guide.now)

    def state_dict(self) -> dict[str, Any]:
        """The run's state for a checkpoint: the task monitor's, the letter to read next,
        whether the env has ended, the env's last observation and info (its entries that are
        data: numbers, strings, arrays and containers of them) and, where the env has a
        ``state_dict``, the env's own."""
        inner = self.env.unwrapped
        own = inner.state_dict() if hasattr(inner, "state_dict") else {}
        return {
            "monitor": list(self._state),
            "letter": self._letter,
            "done": self._done,
            "env_ended": self._ended,
            "env_obs": self._env_obs,
            "env_info": data_only(self._env_info),
            "held": self.held,
            **(self._guide.state_dict() if self._guide is not None else {}),
            "env": own,
        }

    def load_state_dict(self, saved: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`."""
        self._state = MonitorState(*(int(v) for v in saved["monitor"]))
        self._letter, self._done = int(saved["letter"]), bool(saved["done"])
        self._ended = bool(saved.get("env_ended", False))
        self._env_obs, self._env_info = saved["env_obs"], dict(saved.get("env_info", {}))
        self.held = int(saved.get("held", 0))
        if self._guide is not None:
            self._guide.load_state_dict(saved)
        inner = self.env.unwrapped
        if hasattr(inner, "load_state_dict"):
            inner.load_state_dict(saved["env"])

    # -- gymnasium API -------------------------------------------------------------------------

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        """Reset the env and start the task's run at its position 0."""
        obs, info = self.env.reset(seed=seed, options=options)
        self._env_obs, self._env_info = obs, info
        self._take_letter(obs, info, None, False)
        self._state = state = self.monitor.reset()
        self._done = self._ended = False
        verdict = self.monitor.verdict(state.q)
        success = self.monitor.success(state)
        info = self._info(info, state, verdict, 0, success, False, False)
        return self._observation(obs, state), info

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        """A world action (the env steps) or an epsilon jump; see the module docstring."""
        if self._done:
            raise RuntimeError("the episode is over: call reset()")
        if self._discrete:
            a = int(action) - self._action_start
            if not 0 <= a < self._env_actions:
                if self._env_actions <= a < self._num_actions:
                    return self._jump(a - self._env_actions)
                raise ValueError(f"action {action!r} is not in {self.action_space}")
        monitor, read, env_reward = self.monitor, self._letter, 0.0
        guide = self._guide
        left = guide.now if guide is not None else []
        left_ways = guide.ways() if guide is not None and guide.pointing else None
        state, marks, new, reward, verdict, decided, success = monitor.step(self._state, read)
        if self._ended:  # the world stays on its last position: the env is not stepped
            obs, env_info = self._env_obs, self._env_info
        else:
            obs, gained, inner_terminated, inner_truncated, env_info = self.env.step(action)
            env_reward = float(gained)
            self._env_obs, self._env_info = obs, env_info
            self._take_letter(obs, env_info, env_reward, bool(inner_terminated))
            if self._add:
                reward += env_reward
            if inner_terminated or inner_truncated:
                self._ended = True
                if not inner_terminated and not decided and state.steps < self.horizon:
                    self._warn_cut(f"the env truncated its episode at step {state.steps}")
        if self._ended and self._finish:  # no choice is left: the rest of the episode at once
            last = Outcome(state, marks, new, reward, verdict, decided, success)
            out = run_out(monitor, last, self._letter, self.horizon)
            state, marks, new, reward, verdict, decided, success = out
        self._state = state
        q, _, _, steps = state
        if q >= self._checked_below:
            self._check_capacity(q)
        terminated = bool(decided)
        truncated = not terminated and steps >= self.horizon
        self._done = terminated or truncated
        info = self._info(env_info, state, verdict, marks, success, False, new > 0, read)
        info["env_reward"] = env_reward
        if guide is not None:
            info["distances_left"] = guide.array(left)
        if left_ways is not None:
            info["ways_left"] = left_ways
        return self._observation(obs, state), reward, terminated, truncated, info

    def _jump(self, j: int) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        out = self.monitor.jump(self._state, j)
        if out is None:  # invalid: nothing moves, but a step of the horizon is spent
            state = self._state = self._state._replace(steps=self._state.steps + 1)
            truncated = state.steps >= self.horizon
            self._done = truncated
            verdict, success = self.monitor.verdict(state.q), self.monitor.success(state)
            info = self._info(self._env_info, state, verdict, 0, success, True, False)
            return self._observation(self._env_obs, state), 0.0, False, truncated, info
        self._state = state = out.state
        if state.q >= self._checked_below:
            self._check_capacity(state.q)
        truncated = not out.terminated and state.steps >= self.horizon
        self._done = out.terminated or truncated
        accepting = out.new > 0
        info = self._info(self._env_info, state, out.verdict, 0, out.success, False, accepting)
        return self._observation(self._env_obs, state), out.reward, out.terminated, truncated, info

    # -- internals -----------------------------------------------------------------------------

    def _take_letter(
        self, obs: Any, info: dict[str, Any], reward: float | None, terminated: bool
    ) -> None:
        """Read the letter of the position ``reset`` (``reward`` None) or a step reached, with
        the moment where the labels read one (:class:`mitlc.gym.reading.LetterTaker`), and or
        it into :attr:`held`."""
        moment = self._letters.moment(reward, terminated)
        self._letter = self._letters.take(obs, info, moment)
        self.held |= self._letter
        if self._guide is not None:
            self._guide.measure(self.labels, obs, info, moment, reset=reward is None)

    def _check_capacity(self, q: int) -> None:
        """A lazy automaton's new states must fit the spaces declared for it."""
        if q >= self.num_q:
            raise TaskWrapperError(
                f"max_automaton_states: the automaton reached state {q}, past {self.num_q}"
            )
        for state in range(self._checked_below, q + 1):
            if len(self.monitor.jumps(state)) > self.max_jumps:
                raise TaskWrapperError(
                    f"max_jumps: automaton state {state} has more than {self.max_jumps} jumps"
                )
        self._checked_below = q + 1

    def _marks_of(self, marks: int) -> tuple[int, ...]:
        lists = self._mark_lists
        if marks < len(lists):
            return lists[marks]
        return tuple(k for k in range(self._num_sets) if marks >> k & 1)

    def _observation(self, obs: Any, state: MonitorState) -> Any:
        guide = self._guide
        way = guide.way(state.q) if guide is not None and guide.pointing else None
        return self._view.observe(obs, state.q, state.frontier, way)

    def _info(
        self,
        env_info: dict[str, Any],
        state: MonitorState,
        verdict: int,
        marks: int,
        success: bool,
        invalid: bool,
        accepting: bool,
        letter: int = -1,
    ) -> dict[str, Any]:
        """The env's ``info`` with the task's entries (module docstring), for a step that read
        ``letter`` (-1: none) and did not step the env (:meth:`step` sets ``env_reward`` and
        ``distances_left`` where it did)."""
        q, _, rounds, steps = state
        info = {
            **env_info,
            "env_ended": self._ended,
            "verdict": VERDICT_NAMES[verdict],
            "marks": [*self._marks_of(marks)],
            "rounds": rounds,
            "success": success,
            "is_success": success,
            "step": steps,
            "invalid_action": invalid,
            "automaton_state": q,
            "accepting": accepting,
            "letter": letter,
            "env_reward": 0.0,
        }
        if self._discrete:
            info["action_mask"] = self.masks_of(q).copy()
        if self._guide is not None:
            info["distances"] = info["distances_left"] = here = self.distances()
            info["potential"] = self._potential_here(here)
            if self._guide.pointing:
                info["ways"] = info["ways_left"] = self._guide.ways()
        return info
