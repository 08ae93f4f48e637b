"""``TeamVecEnv``: :class:`~mitlc.pettingzoo.TeamTaskWrapper` teams as one Stable-Baselines3
``VecEnv`` in which every agent is a slot, for one policy shared by all agents.

The idea of an agent as a slot of a vector env is SuperSuit's (``pettingzoo_env_to_vec_env``);
the convention followed is SB3's ``VecEnv`` (``stable_baselines3.common.vec_env``): ``reset()``
returns the batch of observations, ``step_wait()`` returns ``(obs, rewards, dones, infos)``,
an ended episode is reset at once and its last observation is in
``infos[i]["terminal_observation"]``, ``seed(seed)`` applies to the next ``reset()``.

* **Slots.** Team ``t``'s agent ``k`` (its index in ``possible_agents``) is slot
  ``t * n + k`` (``n`` agents a team). Every team has the same agents, the same action space
  and flat observations of the same length (else a :class:`TeamVectorError`).
* **Observation.** One float32 vector per slot: the readable part of the agent's env
  observation flattened (:func:`mitlc.gym.observations.readable`, ``gymnasium.spaces.flatten``'s
  layout), then its own task's state and the team task's state as the gymnasium wrapper's
  ``flatten=True`` layout shows a task (a one-hot of the automaton state, or its clock features,
  then the frontier's bits: :class:`mitlc.gym.parts.TaskObservation`), then the one-hot of the
  agent's index. The own task's part is as wide as the widest agent's (zeros where an agent has
  none), so one network reads every slot.
* **Episodes.** A team's slots end together, when its episode ends (no agent left in the
  wrapper); then the team is reset. An agent that left earlier (its own end, the inner env's)
  keeps a no-op slot meanwhile: its last observation, reward 0, ``dones`` false; the action
  given for it is ignored.
* **Rewards** are each agent's, from the wrapper.
* **infos.** Each slot's last info from the wrapper; at the episode's end also
  ``is_success`` (the team task's success, else the agent's own), ``team_success`` (with a
  team task), ``team_rounds`` (the team task's completed rounds, else the agent's own),
  ``terminal_observation`` and SB3's ``TimeLimit.truncated`` (the slot was truncated, not
  terminated).
* **Masks.** With a shield, :meth:`TeamVecEnv.action_masks` gives each slot's ``action_mask``
  as booleans (ones for a no-op slot); sb3-contrib's ``MaskablePPO`` reads it through
  ``env_method("action_masks")``.
* **Seeding.** ``seed(s)``: team ``t`` is reset with ``s + t`` at the next ``reset()``; later
  resets continue the inner envs' own generators.
* **Letters held.** :attr:`TeamVecEnv.held` or-s every team letter read
  (:mod:`mitlc.learn.held`; :attr:`envs` is the adapter itself, which holds them).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt
from gymnasium import spaces
from stable_baselines3.common.vec_env import VecEnv

from mitlc.gym.observations import Readable, readable
from mitlc.pettingzoo.tasks import Run, Task, TeamTaskError
from mitlc.pettingzoo.wrapper import TeamTaskWrapper

Array = npt.NDArray[np.float32]


class TeamVectorError(TeamTaskError):
    """Teams that cannot share one vector env (agents with other action spaces or observation
    lengths, teams with other agents)."""


def _task_width(task: Task | None) -> int:
    if task is None:
        return 0
    features = task.part.features
    states = len(task.automaton.states) if features is None else int(features.shape[1])
    return states + int(task.automaton.num_sets)


def _write_task(run: Run | None, out: Array) -> None:
    """A task's state in the gymnasium wrapper's flat layout: the state's one-hot or clock
    features, then the frontier's bits."""
    if run is None:
        return
    features, q = run.task.part.features, run.state.q
    width = len(run.task.automaton.states) if features is None else int(features.shape[1])
    if features is None:
        out[q] = 1.0
    else:
        out[:width] = features[q]
    for k in range(int(run.task.automaton.num_sets)):
        if run.state.frontier >> k & 1:
            out[width + k] = 1.0


class _Layout:
    """Where each part of a slot's vector lies."""

    def __init__(self, team: TeamTaskWrapper) -> None:
        agents = team.possible_agents
        self.agents = list(agents)
        self.env_parts: dict[str, Readable] = {
            a: readable(team.env.observation_space(a)) for a in agents
        }
        sizes = {a: part.size for a, part in self.env_parts.items()}
        if len(set(sizes.values())) > 1:
            raise TeamVectorError(
                f"one shared policy needs flat observations of one length; the agents' are {sizes}"
            )
        self.env = next(iter(sizes.values()))
        self.own = max((_task_width(team.tasks.get(a)) for a in agents), default=0)
        self.team = _task_width(team.team)
        self.size = self.env + self.own + self.team + len(agents)

    def space(self) -> spaces.Box:
        """The slots' observation space (bounds the widest of every agent's)."""
        lows = np.stack([p.space.low.astype(np.float32) for p in self.env_parts.values()])
        highs = np.stack([p.space.high.astype(np.float32) for p in self.env_parts.values()])
        rest = self.size - self.env
        low = np.concatenate([lows.min(axis=0), np.zeros(rest, np.float32)])
        high = np.concatenate([highs.max(axis=0), np.ones(rest, np.float32)])
        return spaces.Box(low, high, dtype=np.float32)

    def write(self, team: TeamTaskWrapper, agent: str, out: Array) -> None:
        """The vector of ``agent`` of ``team`` now (its last observation if it left)."""
        out[:] = 0.0
        env, own = self.env, self.env + self.own
        self.env_parts[agent].write(team.observations[agent], out[:env])
        _write_task(team.run_of(agent), out[env:own])
        _write_task(team.team_run, out[own : own + self.team])
        out[own + self.team + self.agents.index(agent)] = 1.0


class TeamVecEnv(VecEnv):
    """Teams as one SB3 ``VecEnv``, a slot per agent (see the module docstring)."""

    def __init__(self, teams: Sequence[TeamTaskWrapper]) -> None:
        if not teams:
            raise TeamVectorError("teams: give at least one TeamTaskWrapper")
        self.teams = list(teams)
        first = self.teams[0]
        self.agents: list[str] = list(first.possible_agents)
        odd = [t.possible_agents for t in self.teams if list(t.possible_agents) != self.agents]
        if odd:
            raise TeamVectorError(f"every team needs the agents {self.agents}, one has {odd[0]}")
        actions = {a: first.action_space(a) for a in self.agents}
        if any(space != actions[self.agents[0]] for space in actions.values()):
            raise TeamVectorError(
                f"one shared policy needs one action space; the agents' are {actions}"
            )
        self.layout = _Layout(first)
        self.n = len(self.agents)
        super().__init__(len(self.teams) * self.n, self.layout.space(), actions[self.agents[0]])
        self.held = 0
        """Every team letter read so far, or-ed (bit ``i``: the team task's ``i``-th
        proposition)."""
        self._obs = np.zeros((self.num_envs, self.layout.size), dtype=np.float32)
        self._infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        self._actions: Any = None
        self._team_seeds: list[int | None] = [None] * len(self.teams)

    # -- SB3's VecEnv --------------------------------------------------------------------------

    def seed(self, seed: int | None = None) -> Sequence[int | None]:
        """Team ``t`` is reset with ``seed + t`` at the next :meth:`reset`."""
        self._team_seeds = [None if seed is None else seed + t for t in range(len(self.teams))]
        return [s for s in self._team_seeds for _ in range(self.n)]

    def reset(self) -> Array:
        """Reset every team (with the seeds given to :meth:`seed`, once)."""
        for t, team in enumerate(self.teams):
            self._reset_team(t, team, self._team_seeds[t])
        self._team_seeds = [None] * len(self.teams)
        self.reset_infos = [dict(info) for info in self._infos]
        return self._obs.copy()

    def step_async(self, actions: Any) -> None:
        """Remember the slots' actions for :meth:`step_wait`."""
        self._actions = np.asarray(actions)

    def step_wait(self) -> tuple[Array, Array, npt.NDArray[np.bool_], list[dict[str, Any]]]:
        """Step every team with its live agents' actions (module docstring)."""
        if self._actions is None:
            raise TeamVectorError("step_wait: call step_async first")
        actions, self._actions = self._actions, None
        rewards = np.zeros(self.num_envs, dtype=np.float32)
        dones = np.zeros(self.num_envs, dtype=np.bool_)
        infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        for t, team in enumerate(self.teams):
            base = t * self.n
            live = {a: self._action(actions[base + k]) for k, a in enumerate(self.agents)
                    if a in team.agents}  # fmt: skip
            _, gains, terms, truncs, step_infos = team.step(live)
            self.held |= team._team_letter()
            for k, agent in enumerate(self.agents):
                slot = base + k
                if agent in live:
                    rewards[slot] = gains[agent]
                    info = dict(step_infos[agent])
                    info["TimeLimit.truncated"] = bool(truncs[agent]) and not terms[agent]
                    self._infos[slot] = info
                    self.layout.write(team, agent, self._obs[slot])
                infos[slot] = dict(self._infos[slot])
            if team.agents:
                continue
            for k, agent in enumerate(self.agents):
                slot = base + k
                infos[slot].update(self._ending(team, agent))
                infos[slot]["terminal_observation"] = self._obs[slot].copy()
                dones[slot] = True
            self._reset_team(t, team, None)
        return self._obs.copy(), rewards, dones, infos

    def close(self) -> None:
        """Close every team's env."""
        for team in self.teams:
            team.close()

    def get_attr(self, attr_name: str, indices: Any = None) -> list[Any]:
        """``attr_name`` of each slot's team wrapper."""
        return [getattr(self._team_of(i), attr_name) for i in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: Any = None) -> None:
        """Set ``attr_name`` on each slot's team wrapper."""
        for i in self._get_indices(indices):
            setattr(self._team_of(i), attr_name, value)

    def env_method(
        self, method_name: str, *method_args: Any, indices: Any = None, **method_kwargs: Any
    ) -> list[Any]:
        """``action_masks`` gives each slot's mask; another method is called on each slot's
        team wrapper."""
        chosen = list(self._get_indices(indices))
        if method_name == "action_masks":
            masks = self.action_masks()
            return [masks[i] for i in chosen]
        return [getattr(self._team_of(i), method_name)(*method_args, **method_kwargs)
                for i in chosen]  # fmt: skip

    def has_attr(self, attr_name: str) -> bool:
        """Whether the slots have ``attr_name``: ``action_masks`` where every team is
        shielded, else the team wrapper's attributes."""
        if attr_name == "action_masks":
            return all(team.shield is not None for team in self.teams)
        return hasattr(self.teams[0], attr_name)

    def env_is_wrapped(self, wrapper_class: type[Any], indices: Any = None) -> list[bool]:
        """No slot is a gymnasium env, so none is wrapped."""
        return [False for _ in self._get_indices(indices)]

    # -- mitlc's additions ---------------------------------------------------------------------

    def action_masks(self) -> npt.NDArray[np.bool_]:
        """Each slot's allowed actions (a shield's ``action_mask``; ones for a no-op slot)."""
        n = int(getattr(self.action_space, "n", 0))
        if not self.has_attr("action_masks"):
            raise TeamVectorError("action_masks: the teams have no shield")
        masks = np.ones((self.num_envs, n), dtype=np.bool_)
        for t, team in enumerate(self.teams):
            for k, agent in enumerate(self.agents):
                mask = team._masks.get(agent) if agent in team.agents else None
                if mask is not None:
                    masks[t * self.n + k] = mask.astype(np.bool_)
        return masks

    @property
    def envs(self) -> list[Any]:
        """What :func:`mitlc.learn.held.held_of` reads: the adapter, which holds the letters."""
        return [self]

    # -- internals -----------------------------------------------------------------------------

    def _team_of(self, slot: int) -> TeamTaskWrapper:
        return self.teams[slot // self.n]

    def _action(self, action: Any) -> Any:
        if isinstance(self.action_space, spaces.Discrete):
            return int(action)
        return np.asarray(action)

    def _reset_team(self, t: int, team: TeamTaskWrapper, seed: int | None) -> None:
        _, infos = team.reset(seed=seed)
        self.held |= team._team_letter()
        missing = [a for a in self.agents if a not in team.agents]
        if missing:
            raise TeamVectorError(f"reset: the env left out the agents {missing}")
        for k, agent in enumerate(self.agents):
            self.layout.write(team, agent, self._obs[t * self.n + k])
            self._infos[t * self.n + k] = dict(infos[agent])

    def _ending(self, team: TeamTaskWrapper, agent: str) -> dict[str, Any]:
        """The end-of-episode entries of ``agent``'s slot: the team task's, else its own."""
        runs: Iterable[Run | None] = (team.team_run, team.run_of(agent))
        run = next((r for r in runs if r is not None), None)
        success = bool(run.success) if run is not None else False
        found: dict[str, Any] = {"is_success": success}
        found["team_rounds"] = int(run.state.rounds) if run is not None else 0
        if team.team_run is not None:
            found["team_success"] = success
        return found
