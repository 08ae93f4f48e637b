"""The team task wrapper (mitlc.pettingzoo) on PettingZoo's ParallelEnv: PettingZoo's own API and
seed tests, success and rounds beside the reference reading of episodes, hand-worked episodes,
and the errors of bad arguments."""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any, ClassVar

import numpy as np
import pytest

pytest.importorskip("pettingzoo")

from gymnasium import spaces
from pettingzoo import ParallelEnv
from pettingzoo.test import parallel_api_test, parallel_seed_test

from mitlc.labels import LabelDeclarationError
from mitlc.pettingzoo import TeamTaskError, TeamTaskTypeError, TeamTaskWrapper
from mitlc.semantics.episode import episode_success
from mitlc.syntax import parse
from mitlc.task import TaskMonitor
from mitlc.worlds.model import Rewards

AGENTS = ("robot_0", "robot_1")
STAY, LEFT, RIGHT = 0, 1, 2


class LineEnv(ParallelEnv):  # type: ignore[misc]
    """Two robots on a line of ``size`` cells; actions stay, left, right; each observes its own
    cell and the other's; ``info["collide"]`` when they share a cell. Every robot is truncated
    after ``max_steps`` steps; a robot that reaches ``exit_cell`` is terminated (it leaves)."""

    metadata: ClassVar[dict[str, Any]] = {"name": "line_v0"}

    def __init__(
        self, size: int = 8, max_steps: int = 40, starts: tuple[int, int] | None = None,
        exit_cell: int | None = None,
    ) -> None:  # fmt: skip
        self.possible_agents = list(AGENTS)
        self.agents: list[str] = []
        self.size, self.max_steps, self.starts, self.exit_cell = size, max_steps, starts, exit_cell
        self._rng = np.random.default_rng()
        self.pos: dict[str, int] = {}
        self.t = 0

    @functools.cache  # noqa: B019
    def observation_space(self, agent: str) -> spaces.Box:
        return spaces.Box(0.0, self.size - 1.0, (2,), dtype=np.float32)

    @functools.cache  # noqa: B019
    def action_space(self, agent: str) -> spaces.Discrete:
        return spaces.Discrete(3)

    def _obs(self, agent: str) -> np.ndarray:
        other = AGENTS[1 - AGENTS.index(agent)]
        return np.array([self.pos[agent], self.pos[other]], dtype=np.float32)

    def _infos(self) -> dict[str, dict[str, Any]]:
        collide = self.pos["robot_0"] == self.pos["robot_1"]
        return {a: {"collide": collide} for a in self.agents}

    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, Any], dict[str, Any]]:
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        half = self.size // 2
        first, second = self.starts or (
            int(self._rng.integers(0, half)),
            int(self._rng.integers(half, self.size)),
        )
        self.pos = {"robot_0": first, "robot_1": second}
        self.agents, self.t = list(AGENTS), 0
        return {a: self._obs(a) for a in self.agents}, self._infos()

    def step(self, actions: dict[str, Any]) -> tuple[dict[str, Any], ...]:
        assert set(actions) == set(self.agents), (actions, self.agents)
        for agent, action in actions.items():
            move = (0, -1, 1)[int(action)]
            self.pos[agent] = int(np.clip(self.pos[agent] + move, 0, self.size - 1))
        self.t += 1
        live = list(self.agents)
        obs = {a: self._obs(a) for a in live}
        infos = self._infos()
        rewards = dict.fromkeys(live, -1.0)
        terms = {a: self.pos[a] == self.exit_cell for a in live}
        truncs = {a: self.t >= self.max_steps for a in live}
        self.agents = [a for a in live if not (terms[a] or truncs[a])]
        return obs, rewards, terms, truncs, infos


LABELS = {
    "a": {"box": {"index": [0], "low": [6.0], "high": [7.0]}},
    "b": {"box": {"index": [0], "low": [0.0], "high": [1.0]}},
}
SHARED = {"collide": {"info": "collide"}}
TEAM = "F[0,10] (a_robot_0 & b_robot_1) & G !collide"


def line(**env: Any) -> Callable[..., TeamTaskWrapper]:
    """A maker of wrappers over a LineEnv made with ``env``."""

    def make(**kwargs: Any) -> TeamTaskWrapper:
        options: dict[str, Any] = {"labels": LABELS, "shared_labels": SHARED, "horizon": 12}
        return TeamTaskWrapper(LineEnv(**env), **{**options, **kwargs})

    return make


def no_right(agent: str, wrapper: TeamTaskWrapper) -> np.ndarray:
    """robot_0 may not move right; robot_1 may do anything."""
    return np.array([True, True, agent != "robot_0"])


CONFIGS: dict[str, dict[str, Any]] = {
    "own": {"tasks": {"robot_0": "F[0,8] a", "robot_1": "G (b -> F a)"}},
    "team": {"team": TEAM},
    "both": {"tasks": {"robot_0": "G F a"}, "team": TEAM, "task_obs": "clocks"},
    "shielded": {"team": "G F (a_robot_0 & b_robot_1) & G !collide", "shield": no_right},
}


@pytest.mark.parametrize("name", sorted(CONFIGS))
def test_pettingzoo_api_and_seed_tests_on_the_line(name: str) -> None:
    make = line(exit_cell=0)
    parallel_api_test(make(**CONFIGS[name]), num_cycles=60)
    parallel_seed_test(lambda: make(**CONFIGS[name]), num_cycles=60)


def test_pettingzoo_api_and_seed_tests_on_mpe2_simple_spread() -> None:
    simple_spread = pytest.importorskip("mpe2.simple_spread_v3")
    near = {"disc": {"index": [2, 3], "center": [0.0, 0.0], "radius": 0.5}}
    right = {"box": {"index": [2], "low": [0.0], "high": [1.0]}}

    def make() -> TeamTaskWrapper:
        env = simple_spread.parallel_env(N=2, max_cycles=25)
        return TeamTaskWrapper(
            env,
            {"agent_0": "G (right -> F near)"},
            team="F[0,20] (near_agent_0 | near_agent_1)",
            labels={"near": near, "right": right},
            horizon=30,
        )

    wrapper = make()
    parallel_api_test(wrapper, num_cycles=40)
    parallel_seed_test(make, num_cycles=40)
    obs, _ = wrapper.reset(seed=3)
    for agent in wrapper.agents:
        assert wrapper.observation_space(agent).contains(obs[agent])
        keys = {"env", "task", "team"} if agent == "agent_0" else {"env", "team"}
        assert set(obs[agent]) == keys


# -- success and rounds beside the reference reading ------------------------------------------


def letter_of(position: int, prefix: str = "") -> set[str]:
    """The propositions of LABELS at a cell (each named ``prefix + name``)."""
    found = set()
    if 6 <= position <= 7:
        found.add("a")
    if 0 <= position <= 1:
        found.add("b")
    return {f"{p}{prefix}" for p in found}


def trace_of(letters: list[frozenset[str]], steps: int) -> list[frozenset[str]]:
    """What a run of ``steps`` steps read: the letters of the positions it left, then (an env
    that ended) its last position's, again and again."""
    return [letters[min(i, len(letters) - 1)] for i in range(steps)]


AGREEMENT = [
    ({"robot_0": "F[0,8] a", "robot_1": "G (b -> F a)"}, TEAM),
    (
        {"robot_0": "G F a", "robot_1": "!a U[2,6] a"},
        "F[0,8] (a_robot_0 | a_robot_1) & G[0,8] !collide",
    ),
    ({"robot_1": "G F a & G F b"}, "G F (a_robot_0 & b_robot_1) & G !collide"),
]


class Letters:
    """The letters of an episode on the line, read from what the wrapper returns: each agent's
    own (``a``, ``b``) and the team's (``<prop>_<agent>`` at each agent's last position, and
    ``collide``)."""

    def __init__(self) -> None:
        self.own: dict[str, list[frozenset[str]]] = {a: [] for a in AGENTS}
        self.last: dict[str, set[str]] = {}
        self.team: list[frozenset[str]] = []

    def see(self, obs: dict[str, Any], infos: dict[str, Any]) -> None:
        for agent in obs:
            cell = int(obs[agent]["env"][0])
            self.own[agent].append(frozenset(letter_of(cell)))
            self.last[agent] = letter_of(cell, f"_{agent}")
            if infos[agent]["collide"]:
                self.last[agent].add("collide")
        self.team.append(frozenset(set().union(*self.last.values())))


@pytest.mark.parametrize("case", range(len(AGREEMENT)))
def test_success_and_rounds_agree_with_the_reference_reading(case: int) -> None:
    tasks, team = AGREEMENT[case]
    rng = np.random.default_rng(case)
    for episode in range(40):
        exit_cell = 0 if episode % 3 == 0 else None
        max_steps = 9 if episode % 4 == 1 else 40
        wrapper = line(size=8, exit_cell=exit_cell, max_steps=max_steps)(tasks=tasks, team=team)
        obs, infos = wrapper.reset(seed=episode)
        letters = Letters()
        letters.see(obs, infos)
        final = dict(infos)
        while wrapper.agents:
            actions = {a: int(rng.integers(3)) for a in wrapper.agents}
            obs, _, _, _, infos = wrapper.step(actions)
            letters.see(obs, infos)
            final.update(infos)
        for agent, text in tasks.items():
            run = wrapper.run_of(agent)
            assert run is not None
            trace = trace_of(letters.own[agent], run.state.steps)
            assert final[agent]["success"] == episode_success(parse(text), trace), (agent, trace)
            monitor = TaskMonitor(run.task.automaton, Rewards())
            state = monitor.reset()
            for letter in trace:
                state = monitor.step(state, monitor.letter(letter)).state
            assert final[agent]["rounds"] == state.rounds
            if text == "G F a":
                assert state.rounds == sum("a" in letter for letter in trace)
        team_run = wrapper.team_run
        assert team_run is not None
        trace = trace_of(letters.team, team_run.state.steps)
        expected = episode_success(parse(team), trace)
        assert team_run.success == expected, trace
        for agent in infos:  # those in at the team task's end (who left earlier saw it pending)
            assert infos[agent]["team_success"] == expected


# -- hand-worked episodes ---------------------------------------------------------------------


def test_one_agent_meets_its_deadline_and_the_other_misses_it() -> None:
    tasks = {"robot_0": "F[0,3] a", "robot_1": "F[0,3] b"}
    wrapper = line(starts=(5, 5))(tasks=tasks, rewards={"satisfied": 10.0, "violated": -5.0})
    wrapper.reset()
    _, rewards, terms, truncs, infos = wrapper.step({"robot_0": RIGHT, "robot_1": STAY})
    assert terms == {"robot_0": False, "robot_1": False} and rewards["robot_0"] == 0.0
    _, rewards, terms, _, infos = wrapper.step({"robot_0": STAY, "robot_1": STAY})
    # robot_0 reached cell 6 (a) at step 1; the monitor reads that position on step 2
    assert terms == {"robot_0": True, "robot_1": False}
    assert infos["robot_0"]["verdict"] == "satisfied" and infos["robot_0"]["success"]
    assert infos["robot_0"]["is_success"] and rewards["robot_0"] == 10.0
    assert wrapper.agents == ["robot_1"]
    for _ in (3, 4):
        _, rewards, terms, truncs, infos = wrapper.step({"robot_1": LEFT})
        assert list(terms) == ["robot_1"]
    assert terms["robot_1"] and not truncs["robot_1"]
    assert infos["robot_1"]["verdict"] == "violated" and not infos["robot_1"]["success"]
    assert rewards["robot_1"] == -5.0 and wrapper.agents == []
    with pytest.raises(TeamTaskError, match="reset"):
        wrapper.step({})


def test_a_collision_violates_the_team_task() -> None:
    wrapper = line(starts=(2, 4))(team=TEAM, rewards={"violated": -10.0})
    _, infos = wrapper.reset()
    assert infos["robot_0"]["team_verdict"] == "pending"
    _, rewards, terms, _, infos = wrapper.step({"robot_0": RIGHT, "robot_1": LEFT})
    assert not any(terms.values()) and infos["robot_0"]["collide"]
    _, rewards, terms, truncs, infos = wrapper.step({"robot_0": STAY, "robot_1": STAY})
    assert terms == {"robot_0": True, "robot_1": True} and not any(truncs.values())
    assert rewards == {"robot_0": -10.0, "robot_1": -10.0}
    for agent in AGENTS:
        assert infos[agent]["team_verdict"] == "violated" and not infos[agent]["team_success"]
        assert not infos[agent]["is_success"]
    assert wrapper.agents == []


def test_an_agent_that_leaves_keeps_its_propositions_for_the_team() -> None:
    team = "F[0,10] (a_robot_0 & b_robot_1)"
    wrapper = line(starts=(3, 1), exit_cell=0)(team=team, rewards={"satisfied": 1.0})
    wrapper.reset()
    _, _, terms, _, infos = wrapper.step({"robot_0": RIGHT, "robot_1": LEFT})
    assert terms == {"robot_0": False, "robot_1": True} and infos["robot_1"]["env_ended"]
    assert wrapper.agents == ["robot_0"]
    for _ in range(2):  # robot_0 to cell 6; robot_1's b (cell 0) stays true
        _, rewards, terms, _, infos = wrapper.step({"robot_0": RIGHT})
        assert list(infos) == ["robot_0"] and not terms["robot_0"]
    _, rewards, terms, _, infos = wrapper.step({"robot_0": STAY})
    assert terms == {"robot_0": True} and infos["robot_0"]["team_success"]
    assert rewards == {"robot_0": 1.0} and wrapper.agents == []


def test_an_env_that_ends_runs_the_task_out_on_its_last_letter() -> None:
    wrapper = line(starts=(5, 5), max_steps=2)(tasks={"robot_0": "F[0,6] a", "robot_1": "G F b"})
    wrapper.reset()
    wrapper.step({"robot_0": STAY, "robot_1": LEFT})
    _, _, terms, truncs, infos = wrapper.step({"robot_0": STAY, "robot_1": LEFT})
    # robot_0 never reaches a: the deadline is read out on cell 5 and missed at step 7 (the
    # last position it reads is 6);
    # robot_1 stops on cell 3, no b: G F b pending at the horizon, no round, truncated
    assert terms == {"robot_0": True, "robot_1": False}
    assert truncs == {"robot_0": False, "robot_1": True}
    assert infos["robot_0"]["verdict"] == "violated" and not infos["robot_0"]["success"]
    assert wrapper.run_of("robot_0").state.steps == 7  # type: ignore[union-attr]
    assert wrapper.run_of("robot_1").state.steps == 12  # type: ignore[union-attr]
    assert infos["robot_1"]["rounds"] == 0 and not infos["robot_1"]["success"]


def test_the_horizon_truncates_everyone() -> None:
    wrapper = line(starts=(3, 4))(tasks={"robot_0": "G F a"}, horizon=3)
    wrapper.reset()
    for _ in range(2):
        _, _, terms, truncs, _ = wrapper.step({a: STAY for a in AGENTS})
        assert not any(truncs.values())
    _, _, terms, truncs, infos = wrapper.step({a: STAY for a in AGENTS})
    assert truncs == {"robot_0": True, "robot_1": True} and not any(terms.values())
    assert infos["robot_0"]["step"] == 3 and "success" not in infos["robot_1"]


def test_observations_spaces_and_rewards() -> None:
    make = line(starts=(5, 2))
    wrapper = make(tasks={"robot_0": "G F a"}, team=TEAM, reward_mode="add")
    space = wrapper.observation_space("robot_0")
    assert space is wrapper.observation_space("robot_0")
    assert wrapper.action_space("robot_1") is wrapper.action_space("robot_1")
    assert set(space.spaces) == {"env", "task", "team"}
    assert set(wrapper.observation_space("robot_1").spaces) == {"env", "team"}
    obs, _ = wrapper.reset()
    assert space.contains(obs["robot_0"]) and obs["robot_0"]["task"]["frontier"] == 0
    wrapper.step({"robot_0": RIGHT, "robot_1": STAY})
    obs, rewards, _, _, infos = wrapper.step({"robot_0": STAY, "robot_1": STAY})
    # robot_0 read a (cell 6): a round of G F a, reward accept (100) plus the env's -1
    assert infos["robot_0"]["rounds"] == 1 and rewards["robot_0"] == 99.0
    assert rewards["robot_1"] == -1.0 and infos["robot_1"]["is_success"] is False
    assert all(wrapper.observation_space(a).contains(obs[a]) for a in AGENTS)
    clocks = make(tasks={"robot_0": "F[0,8] a"}, task_obs="clocks")
    assert set(clocks.observation_space("robot_0")["task"].spaces) == {
        "location", "clocks", "frontier"
    }  # fmt: skip
    obs, _ = clocks.reset()
    assert clocks.observation_space("robot_0").contains(obs["robot_0"])


def test_the_shield_masks_and_blocks_actions() -> None:
    wrapper = line(starts=(3, 5))(team="G !collide", shield=no_right)
    obs, infos = wrapper.reset()
    mask = obs["robot_0"]["action_mask"]
    assert mask.dtype == np.int8 and mask.tolist() == [1, 1, 0]
    assert obs["robot_1"]["action_mask"].tolist() == [1, 1, 1]
    assert infos["robot_0"]["shield_violations"] == 0
    obs, _, _, _, infos = wrapper.step({"robot_0": RIGHT, "robot_1": RIGHT})
    assert infos["robot_0"]["shield_blocked"] and infos["robot_0"]["shield_violations"] == 1
    assert not infos["robot_1"]["shield_blocked"] and infos["robot_1"]["shield_violations"] == 0
    assert obs["robot_0"]["env"][0] == 3 and obs["robot_1"]["env"][0] == 6  # blocked: stayed
    obs, _, _, _, infos = wrapper.step({"robot_0": LEFT, "robot_1": STAY})
    assert infos["robot_0"]["shield_violations"] == 1 and obs["robot_0"]["env"][0] == 2
    counting = line(starts=(3, 5))(team="G !collide", shield=no_right, shield_mode="count")
    counting.reset()
    obs, _, _, _, infos = counting.step({"robot_0": RIGHT, "robot_1": STAY})
    assert infos["robot_0"]["shield_violations"] == 1 and obs["robot_0"]["env"][0] == 4
    bad = line()(team="G !collide", shield=lambda agent, wrapper: np.ones(2, dtype=bool))
    with pytest.raises(TeamTaskError, match=r"shield: .*shape \(2,\).*expected \(3,\)"):
        bad.reset()


def test_team_labels_give_shared_propositions() -> None:
    def apart(observations: dict[str, Any], infos: dict[str, Any]) -> set[str]:
        cells = [int(o[0]) for o in observations.values()]
        return {"far"} if max(cells) - min(cells) >= 6 else set()

    wrapper = line(starts=(1, 5))(team="F[0,4] far", team_labels=apart, shared_labels=None)
    wrapper.reset()
    wrapper.step({"robot_0": LEFT, "robot_1": RIGHT})  # cells 0 and 6: far
    _, _, terms, _, infos = wrapper.step({"robot_0": STAY, "robot_1": STAY})
    assert all(terms.values()) and infos["robot_0"]["team_success"]


# -- errors -----------------------------------------------------------------------------------


def test_tasks_with_epsilon_jumps_are_refused() -> None:
    with pytest.raises(TeamTaskError, match=r"tasks\.robot_0: .*epsilon jumps"):
        line()(tasks={"robot_0": "F G a"})
    with pytest.raises(TeamTaskError, match=r"team: .*epsilon jumps"):
        line()(team="F G a_robot_0")


def test_bad_labels_name_their_field_path() -> None:
    bad = {"robot_0": {"a": {"box": {"index": [5], "low": [0.0], "high": [1.0]}}}, "robot_1": {}}
    with pytest.raises(LabelDeclarationError, match=r"labels\.robot_0\.a\.box\.index"):
        line()(tasks={"robot_0": "F[0,3] a"}, labels=bad)
    with pytest.raises(LabelDeclarationError, match=r"shared_labels\.collide"):
        line()(team=TEAM, shared_labels={"collide": {"inf": "collide"}})
    with pytest.raises(TeamTaskError, match=r"labels: 'robot_9' is not an agent"):
        line()(team=TEAM, labels={"robot_0": LABELS, "robot_9": LABELS})
    with pytest.raises(TeamTaskTypeError, match=r"labels\.robot_0: expected"):
        line()(team=TEAM, labels={"robot_0": 3, "robot_1": LABELS})


def test_unknown_agents_and_undeclared_propositions_are_errors() -> None:
    with pytest.raises(TeamTaskError, match=r"tasks: 'robot_7' is not an agent"):
        line()(tasks={"robot_7": "F[0,3] a"})
    with pytest.raises(TeamTaskError, match=r"tasks\.robot_1: .*\['goal'\] are not declared"):
        line()(tasks={"robot_1": "F[0,3] goal"})
    with pytest.raises(TeamTaskError, match=r"team: proposition 'goal_robot_1': robot_1's"):
        line()(team="F[0,3] goal_robot_1")
    with pytest.raises(TeamTaskError, match=r"team: proposition 'dance' is neither"):
        line()(team="F[0,3] dance")
    with pytest.raises(TeamTaskError, match="give per-agent tasks, a team task or both"):
        line()()
    with pytest.raises(TeamTaskError, match="horizon"):
        line()(team=TEAM, horizon=0)
    with pytest.raises(TeamTaskError, match=r"rewards: unknown term 'bonus'"):
        line()(team=TEAM, rewards={"bonus": 1.0})
    wrapper = line()(team=TEAM)
    with pytest.raises(TeamTaskError, match="not an agent"):
        wrapper.observation_space("robot_5")
    wrapper.reset(seed=0)
    with pytest.raises(TeamTaskError, match="actions are given for"):
        wrapper.step({"robot_0": STAY})


def test_callables_of_the_wrong_kind_are_type_errors() -> None:
    with pytest.raises(TeamTaskTypeError, match="team_labels: expected a callable"):
        line()(team=TEAM, team_labels={"far": True})
    with pytest.raises(TeamTaskTypeError, match="shield: expected a callable"):
        line()(team=TEAM, shield=[1, 1, 0])
    with pytest.raises(TeamTaskTypeError, match=r"tasks\.robot_0: expected a formula"):
        line()(tasks={"robot_0": 3})
