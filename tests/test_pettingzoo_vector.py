"""The agent-per-slot SB3 VecEnv over team task wrappers (mitlc.pettingzoo.vector): SB3's VecEnv
contract (shapes, dtypes, seeding), the layout of a slot's vector, no-op slots of agents that
left, masks, and PPO running on it over a tiny ParallelEnv and over mpe2's simple_spread."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

pytest.importorskip("pettingzoo")
pytest.importorskip("stable_baselines3")

from stable_baselines3.common.vec_env import VecEnv, VecMonitor

from mitlc.pettingzoo import TeamTaskWrapper
from mitlc.pettingzoo.vector import TeamVecEnv, TeamVectorError
from tests.test_pettingzoo import CONFIGS, line


def venv(config: str = "team", teams: int = 2, **env: Any) -> TeamVecEnv:
    make = line(**env)
    return TeamVecEnv([make(**CONFIGS[config]) for _ in range(teams)])


def step(vec: TeamVecEnv, actions: Any) -> tuple[Any, Any, Any, list[dict[str, Any]]]:
    """SB3's ``VecEnv.step``, typed as the adapter's ``step_wait``."""
    vec.step_async(actions)
    return vec.step_wait()


def rollout(vec: TeamVecEnv, steps: int, seed: int) -> list[np.ndarray]:
    vec.seed(seed)
    seen = [vec.reset()]
    rng = np.random.default_rng(seed)
    for _ in range(steps):
        obs, rewards, dones, _ = step(vec, rng.integers(0, 3, vec.num_envs))
        seen += [obs, rewards, dones.astype(np.float32)]
    return seen


@pytest.mark.parametrize("config", sorted(CONFIGS))
def test_the_vecenv_contract(config: str) -> None:
    vec = venv(config, teams=3)
    assert isinstance(vec, VecEnv) and vec.num_envs == 6
    obs = vec.reset()
    assert obs.shape == (6, vec.layout.size) and obs.dtype == np.float32
    assert all(vec.observation_space.contains(o) for o in obs)
    ended = 0
    for _ in range(30):
        obs2, rewards, dones, infos = step(vec, np.zeros(6, dtype=np.int64))
        assert obs2.shape == (6, vec.layout.size) and obs2.dtype == np.float32
        assert rewards.shape == (6,) and rewards.dtype == np.float32
        assert dones.shape == (6,) and dones.dtype == np.bool_ and len(infos) == 6
        for t in range(3):  # a team's slots end together
            assert len(set(dones[2 * t : 2 * t + 2])) == 1
        for i in np.flatnonzero(dones):
            ended += 1
            assert "is_success" in infos[i] and "team_rounds" in infos[i]
            assert infos[i]["terminal_observation"].shape == (vec.layout.size,)
    assert ended > 0
    vec.close()


def test_seeding_is_deterministic() -> None:
    first, second = rollout(venv(), 40, 7), rollout(venv(), 40, 7)
    assert all(np.array_equal(a, b) for a, b in zip(first, second, strict=True))
    other = rollout(venv(), 40, 8)
    assert not all(np.array_equal(a, b) for a, b in zip(first, other, strict=True))


def test_a_slot_is_the_env_part_the_tasks_and_the_agent_index() -> None:
    vec = venv("both", teams=1, starts=(2, 5))
    obs = vec.reset()
    layout = vec.layout
    assert layout.env == 2 and layout.size == layout.env + layout.own + layout.team + 2
    assert obs[0, :2].tolist() == [2.0, 5.0] and obs[1, :2].tolist() == [5.0, 2.0]
    assert obs[0, -2:].tolist() == [1.0, 0.0] and obs[1, -2:].tolist() == [0.0, 1.0]
    own = obs[:, layout.env : layout.env + layout.own]
    assert own[1].sum() == 0.0  # robot_1 has no own task
    team = obs[:, layout.env + layout.own : layout.env + layout.own + layout.team]
    assert np.array_equal(team[0], team[1]) and team[0].sum() >= 1.0


def test_an_agent_that_left_keeps_a_no_op_slot() -> None:
    # robot_0 starts at 1 and leaves at the exit cell 0; robot_1 goes on until the horizon
    vec = venv("team", teams=1, starts=(1, 6), exit_cell=0)
    vec.reset()
    obs, _, dones, _ = step(vec, np.array([1, 0]))  # robot_0 moves left: exits
    assert not dones.any()
    left = obs[0].copy()
    obs, rewards, dones, _ = step(vec, np.array([2, 0]))  # its action is ignored
    assert rewards[0] == 0.0 and np.array_equal(obs[0], left) and not dones.any()


def test_success_is_the_teams() -> None:
    # robot_0 to 6 (a), robot_1 to 0 or 1 (b), never on the same cell: the team succeeds
    vec = venv("team", teams=1, starts=(3, 4))
    vec.reset()
    moves = [np.array([2, 1])] * 3 + [np.array([0, 0])] * 9  # G !collide: to the horizon
    for action in moves:
        _, _, dones, infos = step(vec, action)
    assert dones.all() and all(i["is_success"] and i["team_success"] for i in infos)


def test_masks_from_the_shield() -> None:
    vec = venv("shielded", teams=2)
    vec.reset()
    assert vec.has_attr("action_masks")
    masks = np.stack(vec.env_method("action_masks"))
    assert masks.shape == (4, 3) and masks.dtype == np.bool_
    assert masks[0].tolist() == [True, True, False] and masks[1].all()
    assert not venv("team").has_attr("action_masks")


def test_mismatched_teams_are_refused() -> None:
    make = line()
    with pytest.raises(TeamVectorError, match="at least one"):
        TeamVecEnv([])
    odd = make(**CONFIGS["team"])
    odd.possible_agents = ["robot_0"]
    with pytest.raises(TeamVectorError, match="every team"):
        TeamVecEnv([make(**CONFIGS["team"]), odd])


def test_ppo_runs_on_the_line() -> None:
    from stable_baselines3 import PPO

    vec = VecMonitor(venv("both", teams=2))
    model = PPO("MlpPolicy", vec, n_steps=32, batch_size=32, n_epochs=1, seed=0)
    model.learn(256)
    assert model.num_timesteps >= 256


def test_ppo_runs_on_simple_spread() -> None:
    simple_spread = pytest.importorskip("mpe2.simple_spread_v3")
    from stable_baselines3 import PPO

    near = {"disc": {"index": [4, 5], "center": [0.0, 0.0], "radius": 0.3}}

    def make() -> TeamTaskWrapper:
        env = simple_spread.parallel_env(N=2, max_cycles=25, continuous_actions=False)
        return TeamTaskWrapper(
            env, team="F[0,20] (near_agent_0 | near_agent_1)", labels={"near": near}, horizon=25
        )

    vec = TeamVecEnv([make(), make()])
    assert vec.observation_space.shape == (12 + vec.layout.team + 2,)
    model = PPO("MlpPolicy", VecMonitor(vec), n_steps=32, batch_size=32, n_epochs=1, seed=0)
    model.learn(256)
    assert model.num_timesteps >= 256
