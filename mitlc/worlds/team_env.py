"""``TeamGridEnv``: a team world (:mod:`mitlc.worlds.team`) as a PettingZoo ``ParallelEnv``,
without its task (needs the ``teams`` extra: ``pip install 'mitlc[teams]'``).

The agents are the robots' ids. Each agent's action space is ``Discrete`` over its own actions;
its observation is its own cell's index into ``world.team.cells``, or, for a robot with an
observation model, an id of that model drawn in its cell (``Discrete`` over the model's
names). A step samples the next joint state from the joint world's own transitions
(``World.transitions``: the one definition of motion, blocking and collisions), then each
modelled robot's observation, in robot order, from one generator seeded by ``reset(seed=...)``.
Rewards are 0 (the task is the wrapper's: :mod:`mitlc.pettingzoo`); every agent is truncated
at the world's horizon. ``infos[agent]`` holds ``cell`` (``[row, col]``), ``collide`` (the
agent shares its cell with another, or swapped cells with another on this step) and ``state``,
the joint state.

:func:`team_task` puts the world's task on it (:class:`mitlc.pettingzoo.TeamTaskWrapper`),
the team's propositions read from the joint state's letter (``World.letters``, the one
definition of the team's labels).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from mitlc.worlds.model import World
from mitlc.worlds.team_model import Team, radix_weights


class TeamGridEnv(ParallelEnv):  # type: ignore[misc]
    """A team world's robots as PettingZoo agents (see the module docstring)."""

    metadata: dict[str, Any] = {"name": "mitlc_team_grid_v0", "render_modes": []}  # noqa: RUF012

    def __init__(self, world: World) -> None:
        if world.team is None:
            raise ValueError(f"world {world.name!r} is not a team world (it has no robots)")
        self.world = world
        self.team: Team = world.team
        self.render_mode = None
        self.possible_agents: list[str] = list(self.team.robots)
        self.agents: list[str] = []
        counts = self.team.observation_counts()
        self.observation_spaces = {
            agent: spaces.Discrete(count)
            for agent, count in zip(self.possible_agents, counts, strict=True)
        }
        self.action_spaces = {
            agent: spaces.Discrete(len(actions))
            for agent, actions in zip(self.possible_agents, self.team.actions, strict=True)
        }
        self._weights = radix_weights(tuple(len(a) for a in self.team.actions))
        self._rng = np.random.default_rng()
        self._state = world.start
        self._steps = 0

    def observation_space(self, agent: str) -> spaces.Discrete:
        """The agent's observation space (the same object every call)."""
        return self.observation_spaces[agent]

    def action_space(self, agent: str) -> spaces.Discrete:
        """The agent's action space (the same object every call)."""
        return self.action_spaces[agent]

    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, int], dict[str, dict[str, Any]]]:
        """Every robot at its start; ``seed`` reseeds the generator of moves and
        observations."""
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        self.agents = list(self.possible_agents)
        self._steps = 0
        self._state = self._start()
        return self._observe(), self._infos(None)

    def step(
        self, actions: dict[str, int]
    ) -> tuple[
        dict[str, int],
        dict[str, float],
        dict[str, bool],
        dict[str, bool],
        dict[str, dict[str, Any]],
    ]:
        """Every robot's action at once (a robot left out stays, if it can, else takes its
        first action); the next joint state is drawn from ``World.transitions``."""
        if not self.agents:
            return {}, {}, {}, {}, {}
        parts = [self._action(agent, actions) for agent in self.possible_agents]
        joint = int(np.dot(parts, self._weights))
        targets, probs = self.world.transitions.row(self._state * self.world.num_actions + joint)
        before = self._state
        pick = int(np.searchsorted(np.cumsum(probs), self._rng.random(), side="right"))
        self._state = int(targets[min(pick, len(targets) - 1)])
        self._steps += 1
        done = self._steps >= self.world.horizon
        agents = list(self.agents)
        observations, infos = self._observe(), self._infos(before)
        if done:
            self.agents = []
        return (
            observations,
            dict.fromkeys(agents, 0.0),
            dict.fromkeys(agents, False),
            dict.fromkeys(agents, done),
            infos,
        )

    def close(self) -> None:
        """Nothing to release."""

    # -- the state -------------------------------------------------------------------------------

    def _start(self) -> int:
        if not self.world.start_distribution:
            return self.world.start
        states, probs = zip(*self.world.start_distribution, strict=True)
        return int(self._rng.choice(states, p=probs))

    def _action(self, agent: str, actions: dict[str, int]) -> int:
        robot = self.possible_agents.index(agent)
        if agent in actions:
            action = int(actions[agent])
            if not 0 <= action < len(self.team.actions[robot]):
                raise ValueError(f"{agent}: action {action} is not in {self.action_spaces[agent]}")
            return action
        names = self.team.actions[robot]
        return names.index("stay") if "stay" in names else 0

    def _observe(self) -> dict[str, int]:
        """Each robot's observation in the current state: its cell, or a draw of its model."""
        out = {}
        for r, agent in enumerate(self.possible_agents):
            cell = int(self.team.positions[self._state, r])
            model = self.team.observations[r]
            if model is None:
                out[agent] = cell
            else:
                ids, probs = model.model.row(cell)
                pick = int(np.searchsorted(np.cumsum(probs), self._rng.random(), side="right"))
                out[agent] = int(ids[min(pick, len(ids) - 1)])
        return out

    def _infos(self, before: int | None) -> dict[str, dict[str, Any]]:
        """Each robot's cell, and whether it collides (see the module docstring)."""
        now = self.team.positions[self._state]
        was = None if before is None else self.team.positions[before]
        out = {}
        for r, agent in enumerate(self.possible_agents):
            others = [j for j in range(len(now)) if j != r]
            collide = any(now[j] == now[r] for j in others)
            if was is not None:
                collide |= any(
                    now[r] == was[j] and now[j] == was[r] and was[r] != was[j] for j in others
                )
            out[agent] = {
                "cell": list(self.team.cells[int(now[r])]),
                "collide": bool(collide),
                "state": int(self._state),
            }
        return out


def team_task(world: World, automaton: Any = None, **options: Any) -> Any:
    """The team world under its task (``automaton``: the task compiled once; default: the
    world's spec) as a :class:`mitlc.pettingzoo.TeamTaskWrapper`; the team's propositions are
    the joint state's letter (``world.letters[infos[agent]["state"]]``). ``options``: the
    wrapper's others (``task_obs``, ``shield``, ...)."""
    from mitlc.pettingzoo import TeamTaskWrapper

    letters, names = world.letters, world.propositions

    def labels(observations: Any, infos: dict[str, dict[str, Any]]) -> set[str]:
        if not infos:
            return set()
        state = next(iter(infos.values()))["state"]
        letter = int(letters[state])
        return {p for i, p in enumerate(names) if letter >> i & 1}

    return TeamTaskWrapper(
        TeamGridEnv(world),
        team=world.spec if automaton is None else automaton,
        team_labels=labels,
        horizon=world.horizon,
        rewards={"accept": world.rewards.accept, "satisfied": world.rewards.satisfied,
                 "violated": world.rewards.violated},
        **options,
    )  # fmt: skip
