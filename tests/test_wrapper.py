"""TaskWrapper: gymnasium's checks on toy-text, Box, Dict and grid envs (and flattened), vector
envs with masks, the letter convention, stutter on inner termination, invalid jumps, reward
modes, and agreement step by step with a direct TaskMonitor run over the same letters."""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from dataclasses import fields as dataclass_fields
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces
from gymnasium.utils.env_checker import check_env

from mitlc.automata import DigitalAutomaton, translate
from mitlc.gym import ENV_ID, EpisodeCutWarning, TaskWrapper, TaskWrapperError
from mitlc.gym.wrapper import RewardMode
from mitlc.labels import compile_labels
from mitlc.product import ProductEnv, make_env
from mitlc.syntax import parse
from mitlc.task import VERDICT_NAMES, Outcome, TaskMonitor
from mitlc.worlds import Rewards, World
from tests.conftest import ROOT

LAKE = {"goal": {"obs": [15]}, "hole": {"obs": [5, 7, 11, 12]}}
TAXI = {"radices": [5, 5, 5, 4], "fields": ["row", "col", "passenger", "destination"]}
REWARDS = Rewards(accept=10.0, satisfied=100.0, violated=-50.0)
RIGHT, DOWN = 2, 1  # FrozenLake's actions: 0 left, 1 down, 2 right, 3 up


class Point(gym.Env[Any, Any]):
    """A point on the plane: stay, +x, -x, +y, -y by 0.5 (a little noise with ``noise``), in
    [-5, 5]^2; reward -1 per step; terminates at ``end`` (x >= end) when given."""

    metadata: dict[str, Any] = {"render_modes": []}  # noqa: RUF012

    def __init__(self, noise: float = 0.0, end: float | None = None) -> None:
        self.observation_space = spaces.Box(-5.0, 5.0, (2,), np.float32)
        self.action_space = spaces.Discrete(5)
        self.noise, self.end = noise, end
        self.pos = np.zeros(2, dtype=np.float32)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        self.pos = np.zeros(2, dtype=np.float32)
        return self.pos.copy(), {"x": 0.0}

    def step(self, action: int) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        move = [(0, 0), (0.5, 0), (-0.5, 0), (0, 0.5), (0, -0.5)][int(action)]
        jitter = self.np_random.normal(0, self.noise, 2) if self.noise else 0.0
        self.pos = np.clip(self.pos + move + jitter, -5, 5).astype(np.float32)
        ended = self.end is not None and bool(self.pos[0] >= self.end)
        return self.pos.copy(), -1.0, ended, False, {"x": float(self.pos[0])}


class Parts(Point):
    """:class:`Point` with a Dict observation: the position and a door (open after x >= 1)."""

    def __init__(self) -> None:
        super().__init__(noise=0.1)
        self.observation_space = spaces.Dict(
            {"pos": spaces.Box(-5.0, 5.0, (2,), np.float32), "door": spaces.Discrete(3)}
        )

    def _parts(self, pos: np.ndarray) -> dict[str, Any]:
        return {"pos": pos, "door": 2 if pos[0] >= 1.0 else 0}

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        pos, info = super().reset(**kwargs)
        return self._parts(pos), info

    def step(self, action: int) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        pos, reward, terminated, truncated, info = super().step(action)
        return self._parts(pos), reward, terminated, truncated, info


PLANE = {
    "goal": {"disc": {"index": [0, 1], "center": [1.0, 1.0], "radius": 0.3}},
    "wall": {"box": {"index": [0], "low": [-5.0], "high": [-1.0]}},
}
DOOR = {
    "open": {"obs": [2], "key": "door"},
    "far": {"box": {"index": [1], "low": [1.0], "high": [5.0], "key": "pos"}},
}


def checked(env: gym.Env[Any, Any]) -> None:
    """gymnasium's ``check_env``, every warning an error except the one about checking a
    wrapper (this *is* a wrapper) and the render re-check where no env spec exists. Toy-text
    envs list a ``human`` render mode that needs pygame (absent here): those skip the render
    re-check."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warnings.filterwarnings("ignore", message=".*different from the unwrapped")
        warnings.filterwarnings("ignore", message=".*Not able to test alternative render")
        human = "human" in env.metadata.get("render_modes", ())
        check_env(env, skip_render_check=human)


# -- gymnasium ---------------------------------------------------------------------------------


@pytest.mark.parametrize("flatten", [False, True])
def test_check_env_toy_text(flatten: bool) -> None:
    lake = TaskWrapper(gym.make("FrozenLake-v1"), "F goal & G !hole", LAKE, horizon=50,
                       flatten=flatten)  # fmt: skip
    checked(lake)
    taxi_labels = {"in_taxi": {"decoded": {**TAXI, "where": {"passenger": [4]}}}}
    taxi = TaskWrapper(gym.make("Taxi-v4"), "F[0,30] in_taxi", taxi_labels, horizon=60,
                       flatten=flatten)  # fmt: skip
    checked(taxi)
    assert taxi.env.spec is not None and lake.spec is not None
    assert lake.spec.additional_wrappers[-1].name == "TaskWrapper"


@pytest.mark.parametrize("flatten", [False, True])
def test_check_env_box_and_dict(flatten: bool) -> None:
    checked(TaskWrapper(Point(noise=0.1), "F goal & G !wall", PLANE, horizon=40, flatten=flatten))
    checked(TaskWrapper(Parts(), "F (open & far)", DOOR, horizon=40, flatten=flatten))


@pytest.mark.parametrize("name", ["case1.yaml", "case2.yaml"])
def test_check_env_grid_worlds(name: str) -> None:
    env = make_env(ROOT / "specs" / "paper" / name, render_mode="ansi")
    checked(env)
    assert isinstance(env.observation_space, spaces.Dict)
    assert set(env.observation_space.spaces) == {"world", "automaton", "frontier"}


def test_registered_task_env() -> None:
    env = gym.make(ENV_ID, env_id="FrozenLake-v1", env_kwargs={"is_slippery": False},
                   spec="F goal & G !hole", labels=LAKE, horizon=20)  # fmt: skip
    checked(env)
    again = env.spec.make() if env.spec is not None else None
    assert again is not None and again.observation_space == env.observation_space
    obs, info = again.reset(seed=0)
    assert obs == {"env": 0, "automaton": 0, "frontier": 0} and info["verdict"] == "pending"


def test_the_flat_layout() -> None:
    env = TaskWrapper(gym.make("FrozenLake-v1"), "G F goal & G F hole", LAKE, horizon=9,
                      flatten=True)  # fmt: skip
    q_count, sets = env.num_q, env.monitor.num_sets
    assert env.observation_space.shape == (16 + q_count + sets,)
    obs, _ = env.reset(seed=0)
    assert obs.dtype == np.float32 and obs[0] == 1 and obs[:16].sum() == 1
    assert obs[16 + env.automaton_state] == 1 and obs[16 : 16 + q_count].sum() == 1
    assert obs[16 + q_count :].tolist() == [0.0] * sets
    rng = np.random.default_rng(0)
    for _ in range(30):  # the env's part is gymnasium's flatten of the env's observation
        obs, _, terminated, truncated, _ = env.step(int(rng.integers(4)))
        expected = gym.spaces.flatten(env.env.observation_space, env._env_obs)
        assert obs[:16].tolist() == expected.tolist()
        if terminated or truncated:
            env.reset()


# -- vector envs -------------------------------------------------------------------------------


def lake() -> TaskWrapper:
    return TaskWrapper(gym.make("FrozenLake-v1"), "F G !hole", LAKE, horizon=30)


@pytest.mark.parametrize("vector", [gym.vector.SyncVectorEnv, gym.vector.AsyncVectorEnv])
def test_vector_envs_with_masked_random_actions(vector: Any) -> None:
    envs = vector([lake, lake])
    try:
        rng = np.random.default_rng(0)
        envs.reset(seed=3)
        ends = 0
        for _ in range(300):
            masks = envs.call("action_masks")
            assert len(masks) == 2 and all(m.dtype == np.bool_ and m[:4].all() for m in masks)
            actions = np.array([rng.choice(np.flatnonzero(m)) for m in masks])
            _, _, terminated, truncated, infos = envs.step(actions)
            assert not infos["invalid_action"].any()
            ends += int(np.sum(terminated | truncated))
        assert ends > 2
    finally:
        envs.close()


# -- semantics ---------------------------------------------------------------------------------


def test_a_verdict_shows_one_step_after_arrival() -> None:
    env = TaskWrapper(Point(), "F goal", PLANE, rewards=REWARDS, horizon=10)
    env.reset(seed=0)
    steps = [env.step(a) for a in (1, 3, 1, 3)]  # arrives at (1, 1) on the 4th step
    assert [s[4]["verdict"] for s in steps] == ["pending"] * 4
    _, reward, terminated, truncated, info = env.step(0)  # reads the goal
    assert (info["verdict"], terminated, truncated, info["step"]) == ("satisfied", True, False, 5)
    assert reward == 100.0 + 10.0 * len(info["marks"]) and info["success"] and info["is_success"]
    assert info["x"] == 1.0  # the env's info passes through


def test_reward_modes_replace_and_add() -> None:
    modes: tuple[tuple[RewardMode, float], ...] = (("replace", 0.0), ("add", -1.0))
    for mode, cost in modes:
        env = TaskWrapper(Point(), "F goal", PLANE, rewards=REWARDS, horizon=10, reward_mode=mode)
        env.reset(seed=0)
        steps = [env.step(a) for a in (1, 3, 1, 3, 0)]
        task = 100.0 + 10.0 * len(steps[4][4]["marks"])
        assert [s[1] for s in steps] == [cost] * 4 + [task + cost]


def test_callable_labels() -> None:
    def far(obs: Any, info: dict[str, Any]) -> set[str]:
        return {"goal"} if info["x"] >= 1.0 else set()

    env = TaskWrapper(Point(), "F goal", far, rewards=REWARDS, horizon=10)
    env.reset(seed=0)
    steps = [env.step(1) for _ in range(3)]  # x = 0.5, 1.0 (arrival), then read
    assert [s[4]["verdict"] for s in steps] == ["pending", "pending", "satisfied"]


def absorbing(letters: list[int], monitor: TaskMonitor, horizon: int) -> list[Any]:
    """The monitor's outcomes over ``letters``, the last one repeated (an absorbing state) until
    the task is decided or the horizon reached."""
    state, outcomes = monitor.reset(), []
    for t in range(horizon):
        out = monitor.step(state, letters[min(t, len(letters) - 1)])
        outcomes.append(out)
        state = out.state
        if out.terminated:
            break
    return outcomes


@pytest.mark.parametrize(
    ("spec", "horizon", "success", "steps"),
    [
        ("F[8,10] goal", 20, True, 9),  # reads the goal at 6, 7, 8: satisfied at the 9th read
        ("!goal U[8,10] goal", 20, False, 7),  # the goal at 6 is too early
        ("F goal", 7, True, 7),  # one read of the goal within the horizon
        ("F goal", 6, False, 6),  # arrives with the last step: never read
    ],
)
def test_stutter_on_inner_termination_reads_the_last_position_again(
    spec: str, horizon: int, success: bool, steps: int
) -> None:
    inner = gym.make("FrozenLake-v1", is_slippery=False)
    env = TaskWrapper(inner, spec, LAKE, horizon=horizon)
    env.reset(seed=0)
    path = [RIGHT, RIGHT, DOWN, DOWN, DOWN, RIGHT]  # 0 1 2 6 10 14 15: the goal at position 6
    results = [env.step(a) for a in path]
    _, _, terminated, truncated, info = results[-1]
    assert not any(r[2] or r[3] for r in results[:-1])
    assert info["env_ended"] and not any(r[4]["env_ended"] for r in results[:-1])
    decided = info["verdict"] != "pending"  # decided: terminated; pending at the horizon: truncated
    assert (terminated, truncated) == (decided, not decided)
    assert (info["success"], info["step"]) == (success, min(steps, horizon))
    outcomes = absorbing([0] * 6 + [1], env.monitor, horizon)  # letter 1: goal (bit 0)
    assert env.automaton.propositions == ("goal",)
    assert outcomes[-1].success == success and len(outcomes) == info["step"]
    assert sum(r[1] for r in results) == sum(o.reward for o in outcomes)


def test_ignoring_the_mask_costs_steps_and_every_episode_ends() -> None:
    env = lake()
    jump = 4
    assert isinstance(env.action_space, spaces.Discrete) and env.max_jumps == 1
    assert env.action_space.n == jump + env.max_jumps
    env.reset(seed=0)
    env.action_space.seed(0)
    calls, longest, invalid, episodes = 0, 0, 0, 0
    for _ in range(10_000):
        _, reward, terminated, truncated, info = env.step(env.action_space.sample())
        calls += 1
        if info["invalid_action"]:
            invalid += 1
            assert reward == 0.0 and not terminated
        if terminated or truncated:
            longest, calls, episodes = max(longest, calls), 0, episodes + 1
            env.reset()
    assert invalid > 100 and episodes > 100 and longest <= env.horizon + env.max_jumps
    obs, _ = env.reset(seed=1)
    env.step(jump)  # the initial state's one jump
    assert env.steps == 0 and not env.action_masks()[jump]
    after, reward, _, _, info = env.step(jump)
    assert info["invalid_action"] and env.steps == 1
    assert after == {**obs, "automaton": env.automaton_state}
    with pytest.raises(ValueError, match="not in"):
        env.step(jump + 1)


@pytest.mark.parametrize("slippery", [True, False])
def test_the_wrapper_is_the_monitor_over_the_same_letters(slippery: bool) -> None:
    """Random masked play on FrozenLake: every step's reward, verdict, success, end and
    automaton state equal a direct TaskMonitor run over the letters of the observations (the
    last one read again after the env terminates: one read per action where the task has
    jumps, all at once where it has none)."""
    labels = compile_labels(LAKE)
    for spec in ("F G !hole", "G F goal | F[3,6] hole", "!hole U[4,12] goal"):
        env = TaskWrapper(gym.make("FrozenLake-v1", is_slippery=slippery), spec, LAKE,
                          rewards=REWARDS, horizon=25)  # fmt: skip
        monitor = TaskMonitor(env.automaton, REWARDS)
        letter_of = labels.letter_reader(env.automaton.propositions)
        desc: Any = env.env.unwrapped.desc  # type: ignore[attr-defined]
        rng = np.random.default_rng(7)
        for episode in range(40):
            obs, info = env.reset(seed=episode)
            state, letter, done = monitor.reset(), letter_of(obs["env"], info), False
            out: Outcome
            ended = False
            while not done:
                action = int(rng.choice(np.flatnonzero(env.action_masks())))
                obs, reward, terminated, truncated, info = env.step(action)
                if action >= 4:
                    jumped = monitor.jump(state, action - 4)
                    assert jumped is not None
                    out, total = jumped, jumped.reward
                else:
                    out = monitor.step(state, letter)
                    total, letter = out.reward, letter_of(obs["env"], info)
                    ended = desc.flat[obs["env"]] in b"GH"
                    assert info["env_ended"] == ended
                    while env._finish and ended and not out.terminated and out.state.steps < 25:
                        out = monitor.step(out.state, letter)
                        total += out.reward
                state = out.state
                assert reward == total and info["verdict"] == VERDICT_NAMES[out.verdict]
                assert info["success"] == info["is_success"] == out.success
                assert (info["automaton_state"], info["step"]) == (state.q, state.steps)
                assert obs["automaton"] == state.q and obs["frontier"] == state.frontier
                done = terminated or truncated
            assert terminated == out.terminated and truncated == (not out.terminated)
            assert info["success"] == monitor.success(state)


# -- construction ------------------------------------------------------------------------------


class Lazy:
    """A digital automaton seen through the monitor's interface only (no ``states``)."""

    def __init__(self, automaton: DigitalAutomaton) -> None:
        self._a = automaton
        self.formula = automaton.formula
        self.propositions, self.num_sets, self.initial = (
            automaton.propositions, automaton.num_sets, automaton.initial
        )  # fmt: skip

    def successor(self, state: int, letter: int) -> tuple[int, int]:
        return self._a.successor(state, letter)

    def verdict(self, state: int) -> str:
        return self._a.verdict(state)

    def jumps(self, state: int) -> tuple[int, ...]:
        return self._a.jumps(state)

    def end(self, state: int) -> bool:
        return self._a.end(state)


def test_a_lazy_automaton_needs_a_bound_and_keeps_to_it() -> None:
    lazy = Lazy(translate(parse("!goal U[8,10] goal")))
    with pytest.raises(TaskWrapperError, match="max_automaton_states"):
        TaskWrapper(Point(), lazy, PLANE, horizon=20)
    env = TaskWrapper(Point(), lazy, PLANE, horizon=20, max_automaton_states=3)
    assert isinstance(env.observation_space, spaces.Dict)
    assert env.observation_space["automaton"] == spaces.Discrete(3)
    env.reset(seed=0)
    with pytest.raises(TaskWrapperError, match="reached state"):
        for _ in range(5):
            env.step(0)


def test_bad_construction_is_one_typed_line() -> None:
    class Planar(Point):
        def __init__(self) -> None:
            super().__init__()
            self.action_space = spaces.Box(-1.0, 1.0, (2,), np.float32)

    with pytest.raises(TaskWrapperError, match="epsilon jumps, so the env's actions must be"):
        TaskWrapper(Planar(), "F G !wall", PLANE, horizon=5)
    bad: list[tuple[dict[str, Any], str]] = [
        ({"horizon": 0}, "horizon: expected a positive integer"),
        ({"horizon": 5, "reward_mode": "mix"}, "reward_mode: expected"),
        ({"horizon": 5, "rewards": {"bonus": 1.0}}, "rewards: unknown term 'bonus'"),
        ({"horizon": 5, "env_key": "frontier"}, "env_key: 'frontier' is the name"),
    ]
    for kwargs, message in bad:
        with pytest.raises(TaskWrapperError, match=message):
            TaskWrapper(Point(), "F goal", PLANE, **kwargs)
    env = TaskWrapper(Point(), "F goal", PLANE, horizon=1, rewards={"satisfied": 5.0})
    env.reset(seed=0)
    assert env.step(0)[3] and env.monitor.rewards.satisfied == 5.0
    with pytest.raises(RuntimeError, match="reset"):
        env.step(0)


@dataclass(frozen=True, slots=True)
class Drawn(World):
    """A world with a start distribution (for as long as World itself may lack the field)."""

    start_distribution: tuple[tuple[int, float], ...] = ()


def test_grid_env_draws_its_start() -> None:
    base = make_env(ROOT / "specs" / "paper" / "case1.yaml")
    fields = {f.name: getattr(base.world, f.name) for f in dataclass_fields(World)}
    fields["start_distribution"] = ((0, 0.5), (3, 0.5))
    env = ProductEnv(Drawn(**fields), base.automaton)
    starts = [env.reset(seed=seed)[1]["state"] for seed in range(40)]
    assert set(starts) == {0, 3} and env.world_state == starts[-1]
    assert [env.reset(seed=seed)[1]["state"] for seed in range(40)] == starts
    assert ProductEnv(base.world, base.automaton).reset(seed=1)[1]["state"] == base.world.start


def test_an_env_time_limit_below_the_horizon_is_warned_and_the_world_stays() -> None:
    """FrozenLake-v1 stops at 100 steps by itself: with a horizon of 110 the wrapper warns once,
    and the cut ends the world, not the task: the agent stands still (the env is not stepped
    again) until the task's horizon, and a pending deadline then fails (truncated)."""
    with pytest.warns(EpisodeCutWarning, match=r"own time limit \(100 steps\).*horizon \(110\)"):
        lake = gym.make("FrozenLake-v1", is_slippery=False)
        env = TaskWrapper(lake, "!hole U[0,105] goal", LAKE, horizon=110, env_end="step")
    env.reset(seed=0)
    results = [env.step(0) for _ in range(106)]  # left, left, ...: stays at the start
    assert [r[4]["env_ended"] for r in results] == [False] * 99 + [True] * 7
    assert all(r[4]["step"] == t + 1 for t, r in enumerate(results))
    assert not any(r[2] or r[3] for r in results[:105])
    _, _, terminated, _, info = results[105]  # the window closed at position 105
    assert terminated and info["verdict"] == "violated" and not info["success"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        lake = gym.make("FrozenLake-v1", is_slippery=False)
        env = TaskWrapper(lake, "!hole U[0,105] goal", LAKE, horizon=110)  # no jumps: "finish"
    env.reset(seed=0)
    results = [env.step(0) for _ in range(100)]  # the rest of the episode within the 100th
    assert not any(r[2] or r[3] for r in results[:99]) and results[99][2]
    assert (results[99][4]["step"], results[99][4]["verdict"]) == (106, "violated")
    lifted = gym.make("FrozenLake-v1", is_slippery=False, max_episode_steps=110)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert TaskWrapper(lifted, "!hole U[0,100] goal", LAKE, horizon=110).horizon == 110


def test_making_the_wrapper_learns_the_automatons_states_at_once(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # Learning them one by one rebuilt the monitor's arrays each time: quadratic in the states
    # (F[0,300] G[0,300] a, 45,000 states: 217 s to make the wrapper, 3.8 s learned at once).
    calls: list[int] = []
    learn = TaskMonitor._learn_states

    def counted(self: TaskMonitor, q: int) -> None:
        calls.append(q)
        learn(self, q)

    monkeypatch.setattr(TaskMonitor, "_learn_states", counted)
    wrapper = TaskWrapper(
        gym.make("FrozenLake-v1"), "F[0,20] G[0,20] a", labels=lambda obs, info: set(), horizon=50
    )
    states = len(wrapper.automaton.states)
    assert states > 100
    assert len(calls) <= 2, f"{len(calls)} passes over {states} states"
