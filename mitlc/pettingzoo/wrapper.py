"""``TeamTaskWrapper``: timed tasks for a team on any PettingZoo ``ParallelEnv``.

It follows PettingZoo's ``ParallelEnv`` API (v1.27): ``possible_agents``, ``agents`` (who is
still in), ``observation_space(agent)`` / ``action_space(agent)`` (the same object every call),
``reset(seed=, options=) -> (observations, infos)`` and ``step(actions)`` returning five dicts
keyed by the agents that were in; legal actions go in a ``Dict`` observation's
``action_mask``. Every rule of a task (a step, its reward, verdict, success and rounds) is
:class:`mitlc.task.TaskMonitor`'s; the letters are read as :class:`mitlc.gym.TaskWrapper`
reads them (:mod:`mitlc.gym.reading`):

* **Tasks.** Per agent (``tasks={agent: spec}``, over that agent's own propositions) and/or one
  team task (``team=spec``, over ``<prop>_<agent>`` and shared propositions:
  :mod:`mitlc.pettingzoo.labels`). A task with epsilon jumps (``F G a``) is refused.
* **Letters.** Position 0 is the reset's observation; on a step every task reads the letter of
  the position being *left*, then the env steps and the new letters are remembered. An agent
  that the inner env ends (terminated or truncated) stays on its last position: its task reads
  that letter until it is decided or the horizon is reached, within the step that ended it
  (the gymnasium wrapper's ``env_end="finish"``), and its propositions stay at their last
  values for the team task, which runs out the same way once every agent has ended.
* **Observation.** ``Dict({"env": inner, "task": own task, "team": team task, "action_mask":
  ...})``, only the keys that apply; a task's state is its automaton state and frontier, or
  its clocks (``task_obs="clocks"``; :class:`mitlc.gym.parts.TaskPart`).
* **Episode.** The team task decided (satisfied or violated): every agent is terminated; with
  no team task, an agent whose own task is decided is terminated (an own task decided beside a
  team task is kept as it is). The inner env's terminations and truncations pass through, and
  the ``horizon`` truncates everyone. An agent that is done leaves ``agents``; an agent the
  wrapper has ended while the inner env still has it takes ``idle_actions[agent]`` (default:
  the first action of a ``Discrete``, zeros clipped into a ``Box``).
* **Reward.** The agent's own task's reward plus the team task's (``rewards`` as the gymnasium
  wrapper takes them), replacing the env's (``reward_mode="replace"``) or added (``"add"``).
* **info.** The env's, plus ``success``, ``is_success`` (SB3's key), ``rounds``, ``verdict`` of
  the agent's own task; ``team_success``, ``team_rounds``, ``team_verdict`` of the team task
  (an agent with no own task has ``is_success`` the team's); ``step``; ``env_ended``; with a
  shield, ``shield_blocked`` and ``shield_violations``.
* **Shield.** ``shield(agent, wrapper)`` gives the allowed actions of a ``Discrete`` action space
  as booleans; it is asked after every reset and step for each agent still in, shown as
  ``action_mask`` (an int8 ``Box``, as PettingZoo's envs give it; ones on an agent's last
  observation), and each action taken is checked against it: one not allowed is counted
  (``shield_violations``, per agent and episode) and, with ``shield_mode="block"``, replaced by
  the first allowed action.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any, Literal

import numpy as np
import numpy.typing as npt
from gymnasium import spaces
from pettingzoo import ParallelEnv

from mitlc.gym.arguments import TaskWrapperError, check_rewards, task_rewards
from mitlc.pettingzoo.actions import checked, idle_action, mask_of
from mitlc.pettingzoo.labels import (
    AgentLabels,
    TeamLabels,
    agent_labels,
    check_own,
    shared_labellers,
    team_sources,
)
from mitlc.pettingzoo.reading import TeamLetters
from mitlc.pettingzoo.tasks import (
    Run,
    Task,
    TaskObs,
    TeamTaskError,
    TeamTaskTypeError,
    compile_task,
)
from mitlc.task import VERDICT_NAMES
from mitlc.task.rules import TaskRewards

Ends = dict[str, bool]
"""Terminations or truncations, per agent."""

Shield = Callable[[str, "TeamTaskWrapper"], Any]
"""``shield(agent, wrapper)``: the agent's allowed actions now, as booleans."""


class TeamTaskWrapper(ParallelEnv):  # type: ignore[misc]
    """Tasks for a team on a PettingZoo ``ParallelEnv`` (see the module docstring)."""

    def __init__(
        self,
        env: Any,
        tasks: Mapping[str, Any] | None = None,
        *,
        team: Any = None,
        labels: AgentLabels | Mapping[str, AgentLabels] | None = None,
        shared_labels: Mapping[str, Any] | None = None,
        team_labels: TeamLabels | None = None,
        horizon: int,
        rewards: TaskRewards | Mapping[str, float] | None = None,
        reward_mode: Literal["replace", "add"] = "replace",
        task_obs: TaskObs = "state",
        shield: Shield | None = None,
        shield_mode: Literal["block", "count"] = "block",
        idle_actions: Mapping[str, Any] | None = None,
    ) -> None:
        """Wrap ``env`` with the per-agent ``tasks`` and/or the ``team`` task (each a formula's
        text or an eager automaton), read through ``labels``, ``shared_labels`` and
        ``team_labels`` (:mod:`mitlc.pettingzoo.labels`), for at most ``horizon`` steps."""
        self.env = env
        self.possible_agents: list[str] = list(env.possible_agents)
        self.agents: list[str] = []
        self.metadata = getattr(env, "metadata", {})
        self.render_mode = getattr(env, "render_mode", None)
        agents = self.possible_agents
        self._check_plain(agents, tasks, team, horizon, reward_mode, task_obs, shield_mode)
        for name, function in (("team_labels", team_labels), ("shield", shield)):
            if function is not None and not callable(function):
                raise TeamTaskTypeError(
                    f"{name}: expected a callable, got {type(function).__name__}"
                )
        self.horizon, self.reward_mode, self.shield_mode = int(horizon), reward_mode, shield_mode
        inner = {a: env.observation_space(a) for a in agents}
        self._actions: dict[str, spaces.Space[Any]] = {a: env.action_space(a) for a in agents}
        try:
            check_rewards(rewards)
        except TaskWrapperError as err:
            kind = TeamTaskTypeError if isinstance(err, TypeError) else TeamTaskError
            raise kind(str(err)) from None
        terms = task_rewards(rewards)
        given = dict(tasks or {})
        self.tasks: dict[str, Task] = {
            a: compile_task(spec, f"tasks.{a}", terms, task_obs) for a, spec in given.items()
        }
        self.team: Task | None = (
            None if team is None else compile_task(team, "team", terms, task_obs)
        )
        self.labels = agent_labels(labels, agents, inner)
        for agent, task in self.tasks.items():
            check_own(agent, task.propositions, self.labels.get(agent))
        shared = shared_labellers(shared_labels, agents, inner)
        shared_names = shared[agents[0]].propositions if shared and agents else ()
        sources = None
        if self.team is not None:
            sources = team_sources(
                self.team.propositions, agents, self.labels, shared_names, team_labels is not None
            )
        own = {a: task.propositions for a, task in self.tasks.items()}
        team_props = self.team.propositions if self.team is not None else ()
        self._letters = TeamLetters(
            agents, self.labels, own, team_props, sources, shared, team_labels, env.unwrapped
        )
        self.shield = shield
        self._discrete: dict[str, tuple[int, int]] = {}
        """Each agent's number of actions and first action, where a shield masks them."""
        self._spaces = {a: self._space(a, inner[a]) for a in agents}
        self._idle = dict(idle_actions or {})
        self._runs = {a: Run(task) for a, task in self.tasks.items()}
        self._team = Run(self.team) if self.team is not None else None
        self._steps = 0
        self.observations: dict[str, Any] = {}
        """Each agent's last observation of the inner env (kept when it leaves)."""
        self.env_infos: dict[str, dict[str, Any]] = {}
        """Each agent's last info of the inner env (kept when it leaves)."""
        self._masks: dict[str, npt.NDArray[np.int8]] = {}
        self._violations: dict[str, int] = {}

    @staticmethod
    def _check_plain(
        agents: list[str], tasks: Any, team: Any, horizon: Any, reward_mode: Any,
        task_obs: Any, shield_mode: Any,
    ) -> None:  # fmt: skip
        """The arguments that need nothing compiled."""
        odd = [a for a in agents if not isinstance(a, str)]
        if odd:
            raise TeamTaskTypeError(f"possible_agents: agent ids must be strings, got {odd[0]!r}")
        if tasks is not None and not isinstance(tasks, Mapping):
            raise TeamTaskTypeError(
                f"tasks: expected a mapping from agents to tasks, got {type(tasks).__name__}"
            )
        unknown = [a for a in tasks or {} if a not in agents]
        if unknown:
            raise TeamTaskError(f"tasks: {unknown[0]!r} is not an agent (agents: {agents})")
        if not tasks and team is None:
            raise TeamTaskError("tasks, team: give per-agent tasks, a team task or both")
        if not isinstance(horizon, int | np.integer) or isinstance(horizon, bool) or horizon < 1:
            raise TeamTaskError(f"horizon: expected a positive integer, got {horizon!r}")
        for name, value, options in (
            ("reward_mode", reward_mode, ("replace", "add")),
            ("task_obs", task_obs, ("state", "clocks")),
            ("shield_mode", shield_mode, ("block", "count")),
        ):
            if value not in options:
                raise TeamTaskError(f"{name}: expected one of {options}, got {value!r}")

    def _space(self, agent: str, inner: spaces.Space[Any]) -> spaces.Dict:
        parts: dict[str, spaces.Space[Any]] = {"env": inner}
        if agent in self.tasks:
            parts["task"] = spaces.Dict(self.tasks[agent].part.spaces)
        if self.team is not None:
            parts["team"] = spaces.Dict(self.team.part.spaces)
        if self.shield is not None:
            actions = self._actions[agent]
            if not isinstance(actions, spaces.Discrete):
                raise TeamTaskError(
                    f"shield: action masks need Discrete action spaces; {agent}'s is {actions}"
                )
            self._discrete[agent] = (int(actions.n), int(actions.start))
            parts["action_mask"] = spaces.Box(0, 1, (int(actions.n),), dtype=np.int8)
        return spaces.Dict(parts)

    # -- the ParallelEnv API -------------------------------------------------------------------

    def observation_space(self, agent: str) -> spaces.Space[Any]:
        """The agent's observation space (the same object every call)."""
        return self._spaces[self._known(agent)]

    def action_space(self, agent: str) -> spaces.Space[Any]:
        """The agent's action space: the inner env's (the same object every call)."""
        return self._actions[self._known(agent)]

    @property
    def unwrapped(self) -> Any:
        """The inner env's ``unwrapped``."""
        return self.env.unwrapped

    def state(self) -> Any:
        """The inner env's global state."""
        return self.env.state()

    def render(self) -> Any:
        """The inner env's rendering."""
        return self.env.render()

    def close(self) -> None:
        """Close the inner env."""
        self.env.close()

    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, Any], dict[str, dict[str, Any]]]:
        """Reset the inner env (seeded with ``seed``) and start every task at position 0."""
        obs, infos = self.env.reset(seed=seed, options=options)
        self.agents = [a for a in self.env.agents if a in obs]
        self._steps = 0
        self.observations, self.env_infos = {}, {}
        self._letters.clear()
        for agent in self.agents:
            self._remember(agent, obs[agent], dict(infos.get(agent, {})), None, False)
        for run in self._runs.values():
            run.restart()
        if self._team is not None:
            self._team.restart()
        self._violations = dict.fromkeys(self.agents, 0)
        self._masks = {}
        self._ask_shield(self.agents)
        observed = {a: self._observe(a) for a in self.agents}
        return observed, {a: self._info(a, False, False) for a in self.agents}

    def step(
        self, actions: Mapping[str, Any]
    ) -> tuple[dict[str, Any], dict[str, float], Ends, Ends, dict[str, dict[str, Any]]]:
        """Every task reads the letters of the positions being left, the inner env steps, and
        the episode's ends are decided (module docstring)."""
        if not self.agents:
            raise TeamTaskError("step: no agent is in (the episode is over): call reset()")
        live = list(self.agents)
        odd = [a for a in actions if a not in live]
        missing = [a for a in live if a not in actions]
        if odd or missing:
            raise TeamTaskError(
                f"step: actions are given for {sorted(actions)}, the agents in are {live}"
            )
        chosen, blocked = self._shielded(actions, live)
        own = {a: run.step(self._letters.own(a)) for a, run in self._runs.items()
               if a in live and not run.decided}  # fmt: skip
        team = self._team
        team_out = team.step(self._team_letter()) if team is not None else None
        idle = {a: self._idle.get(a) for a in self.env.agents if a not in chosen}
        idle = {a: idle_action(a, self._actions[a]) if v is None else v for a, v in idle.items()}
        inner = {**idle, **chosen}
        obs, gains, terms, truncs, infos = self.env.step(inner)
        self._steps += 1
        ended: dict[str, tuple[bool, bool]] = {}
        for agent in live:
            t, c = bool(terms.get(agent, False)), bool(truncs.get(agent, False))
            ended[agent] = (t, c)
            if agent in obs:
                info = dict(infos.get(agent, {}))
                self._remember(agent, obs[agent], info, float(gains.get(agent, 0.0)), t)
            if (t or c) and agent in own:
                own[agent] = self._runs[agent].finish(own[agent], self._letters.own(agent),
                                                      self.horizon)  # fmt: skip
        if team is not None and team_out is not None and all(map(any, ended.values())):
            team_out = team.finish(team_out, self._team_letter(), self.horizon)
        team_reward = team_out.reward if team_out is not None else 0.0
        team_decided = team is not None and team.decided
        rewards, terminated, truncated = {}, {}, {}
        for agent in live:
            reward = own[agent].reward if agent in own else 0.0
            reward += team_reward
            if self.reward_mode == "add":
                reward += float(gains.get(agent, 0.0))
            rewards[agent] = reward
            run = self._runs.get(agent)
            decided = team_decided or (team is None and run is not None and run.decided)
            t, c = ended[agent]
            terminated[agent] = t or decided
            truncated[agent] = not terminated[agent] and (c or self._steps >= self.horizon)
        self.agents = [a for a in live if not (terminated[a] or truncated[a])]
        self._ask_shield(live)
        observed = {a: self._observe(a) for a in live}
        out_infos = {a: self._info(a, blocked[a], any(ended[a])) for a in live}
        return observed, rewards, terminated, truncated, out_infos

    # -- state a shield may read ---------------------------------------------------------------

    @property
    def steps(self) -> int:
        """Steps taken in the episode."""
        return self._steps

    def run_of(self, agent: str) -> Run | None:
        """The run of ``agent``'s own task (``None``: it has none)."""
        return self._runs.get(self._known(agent))

    @property
    def team_run(self) -> Run | None:
        """The run of the team task (``None``: there is none)."""
        return self._team

    # -- internals -----------------------------------------------------------------------------

    def _known(self, agent: str) -> str:
        if agent not in self._spaces:
            raise TeamTaskError(f"{agent!r} is not an agent (agents: {self.possible_agents})")
        return agent

    def _remember(
        self, agent: str, obs: Any, info: dict[str, Any], reward: float | None, ended: bool
    ) -> None:
        self.observations[agent], self.env_infos[agent] = obs, info
        self._letters.read(agent, obs, info, reward, ended)

    def _team_letter(self) -> int:
        return self._letters.team(self.observations, self.env_infos)

    def _ask_shield(self, agents: list[str]) -> None:
        """The masks of ``agents``: the shield's for those still in, ones for those leaving."""
        if self.shield is None:
            return
        for agent in agents:
            n = self._discrete[agent][0]
            in_ = agent in self.agents
            mask = mask_of(agent, self.shield(agent, self), n) if in_ else np.ones(n, np.int8)
            self._masks[agent] = mask

    def _shielded(
        self, actions: Mapping[str, Any], live: list[str]
    ) -> tuple[dict[str, Any], dict[str, bool]]:
        """The actions the env takes, and which were not allowed (counted)."""
        chosen, blocked = {a: actions[a] for a in live}, dict.fromkeys(live, False)
        if self.shield is None:
            return chosen, blocked
        block = self.shield_mode == "block"
        for agent in live:
            start = self._discrete[agent][1]
            chosen[agent], blocked[agent] = checked(chosen[agent], self._masks[agent], start, block)
            self._violations[agent] = self._violations.get(agent, 0) + blocked[agent]
        return chosen, blocked

    def _observe(self, agent: str) -> dict[str, Any]:
        observed: dict[str, Any] = {"env": self.observations[agent]}
        run = self._runs.get(agent)
        if run is not None:
            observed["task"] = run.observe()
        if self._team is not None:
            observed["team"] = self._team.observe()
        if self.shield is not None:
            observed["action_mask"] = self._masks[agent].copy()
        return observed

    def _info(self, agent: str, blocked: bool, ended: bool) -> dict[str, Any]:
        info = {**self.env_infos.get(agent, {}), "step": self._steps, "env_ended": ended}
        run = self._runs.get(agent)
        if run is not None:
            info["success"] = info["is_success"] = run.success
            info["rounds"] = run.state.rounds
            info["verdict"] = VERDICT_NAMES[run.verdict]
        team = self._team
        if team is not None:
            info["team_success"] = team.success
            info["team_rounds"] = team.state.rounds
            info["team_verdict"] = VERDICT_NAMES[team.verdict]
            if run is None:
                info["is_success"] = team.success
        if self.shield is not None:
            info["shield_blocked"] = blocked
            info["shield_violations"] = self._violations.get(agent, 0)
        return info
