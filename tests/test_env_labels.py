"""Labels from the env's state and the step's events, and envs from installed packages by name
(issue 23): each new label form against a hand-made env, paths checked at set-up, world files
that import a package by its name (``tests/packages/mitlc_test_envs``) or refuse a file path,
wrappers applied in order, a finite env split by the events of its steps (the wrapper, the
product's simulator and the exact evaluation agree), and labels that never held reported."""

from __future__ import annotations

import random
import sys
import textwrap
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

from mitlc.automata import translate
from mitlc.gym import TaskWrapper
from mitlc.labels import LabelDeclarationError, Moment, compile_labels
from mitlc.learn.envs.vec import VecProduct, tables
from mitlc.learn.evaluation.exact import policy_success
from mitlc.product import build_product
from mitlc.syntax import parse, to_text
from mitlc.worlds import WorldError
from mitlc.worlds.door import is_finite, load_env_task, open_world
from mitlc.worlds.gym_world import GymWorldError
from mitlc.worlds.load import load_world
from tests.test_episode import REWARDS, ToyText, specs, world_of

PACKAGES = Path(__file__).parent / "packages"


@pytest.fixture
def package(monkeypatch: pytest.MonkeyPatch) -> Any:
    """The test package, importable by name as an installed one is."""
    monkeypatch.syspath_prepend(str(PACKAGES))
    import mitlc_test_envs

    return mitlc_test_envs


def probe_env(package: Any, size: int = 5) -> gym.Env[int, int]:
    return gym.make("MitlcTest/Probe-v0", size=size)


# -- the forms, step by step ---------------------------------------------------------------------

FORMS: dict[str, Any] = {
    "carry": {"attr": "carrying.kind", "equals": "key"},
    "at2": {"attr": "pos", "equals": [2, 0]},
    "mid": {"attr": "pos", "in": [[1, 0], [3, 0]]},
    "boxed": {"attr": "pos", "box": {"index": [0], "low": [2.5], "high": [9]}},
    "near": {"info": "vec", "disc": {"center": [1, 0], "radius": 0.5}},
    "fast": {"attr": "speed", "above": 0.5},
    "moving": {"attr": "speed"},
    "arrived": {"info": "rewards.arrived"},
    "fell": {"reward": {"below": -50}},
    "ended": {"terminated": True},
}


def test_each_form_reads_the_env_info_and_events_at_each_position(package: Any) -> None:
    """Walk left (a fall), then right to the end: the letters hold exactly where expected."""
    props = tuple(FORMS)
    env = TaskWrapper(probe_env(package), "G F arrived", FORMS, horizon=20)
    labels = env.labels
    env.reset(seed=0)
    seen = [labels(env._env_obs, env._env_info, Moment(env.unwrapped))]
    for action in (0, 1, 1, 1, 0, 1, 1):
        env.step(action)
        reward = -100.0 if seen and action == 0 and env.unwrapped.x == 0 else 0.0
        moment = Moment(env.unwrapped, reward, env.unwrapped.x == 4)
        seen.append(labels(env._env_obs, env._env_info, moment))
        if env.unwrapped.x == 4:
            break
    expected = [
        set(),  # reset at 0
        {"fell"},  # left from 0: a fall, back to 0
        {"fast", "moving", "near", "mid"},  # 1
        {"fast", "moving", "carry", "at2"},  # 2: the key is picked up
        {"fast", "moving", "carry", "mid", "boxed"},  # 3
        {"moving", "carry", "at2"},  # back to 2 (speed -1: truthy, not above 0.5)
        {"fast", "moving", "carry", "mid", "boxed"},  # 3
        {"fast", "moving", "carry", "boxed", "arrived", "ended"},  # 4: arrived, terminated
    ]
    assert [set(s) for s in seen] == expected
    assert set(props) == set(labels.propositions)


def test_the_wrapper_reads_events_and_state_into_its_letters(package: Any) -> None:
    """``F (fell & X ...)`` style tasks through the wrapper: the fall is seen, and
    ``held`` or-s every letter read."""
    env = TaskWrapper(probe_env(package), "F fell", {"fell": FORMS["fell"]}, horizon=5)
    env.reset(seed=0)
    assert env.held == 0
    _, _, terminated, _, info = env.step(0)  # the fall: read on the next step
    _, _, terminated, _, info = env.step(1)
    assert terminated and info["verdict"] == "satisfied" and env.held == 1
    env = TaskWrapper(probe_env(package), "F ended", {"ended": FORMS["ended"]}, horizon=9)
    env.reset(seed=0)
    for _ in range(3):
        assert not env.step(1)[2]
    _, _, terminated, _, info = env.step(1)  # ends the env: the rest is read at once
    assert terminated and info["success"] and info["env_ended"] and info["step"] == 5


BAD_PATHS = [
    ({"a": {"attr": "carrynig.kind"}}, r"labels\.a\.attr: env\.unwrapped \(a Probe\) has no "
     r"attribute 'carrynig'; did you mean 'carrying'\?"),
    ({"a": {"attr": "pos[7]"}}, r"labels\.a\.attr: index 7 is out of range at env\.unwrapped\."
     r"pos \(a tuple of length 2\)"),
    ({"a": {"info": "rewards.arived"}}, r"labels\.a\.info: info\.rewards has no key 'arived'; "
     r"did you mean 'arrived'\? \(keys: arrived\), after reset or the first step"),
    ({"a": {"attr": "reset"}}, r"labels\.a\.attr: env\.unwrapped\.reset is a method"),
    ({"a": {"attr": "pos"}}, r"labels\.a\.attr: found a vector of 2 numbers"),
    ({"a": {"info": "vec", "box": {"low": [0], "high": [1]}}},
     r"labels\.a\.info: the region reads 1 numbers, found 2"),
    ({"a": [{"obs": [1]}, {"attr": "carrying.kind", "below": 3}]}, None),  # None at reset: ok
    ({"a": {"info": "rewards", "above": 1}}, r"labels\.a\.info: below/above need a number"),
]  # fmt: skip


@pytest.mark.parametrize(("labels", "message"), BAD_PATHS)
def test_a_path_that_is_not_there_is_refused_at_the_first_steps(
    package: Any, labels: dict[str, Any], message: str | None
) -> None:
    env = TaskWrapper(probe_env(package), "F a", labels, horizon=5)
    if message is None:
        env.reset(seed=0)
        env.step(1)
        return
    with pytest.raises(LabelDeclarationError, match=f"^{message}"):
        env.reset(seed=0)
        env.step(1)


@pytest.mark.parametrize(
    ("declaration", "message"),
    [
        ({"attr": "_secret"}, "labels.a.attr: '_secret' is not a public attribute name"),
        ({"attr": "a..b"}, "labels.a.attr: an empty step"),
        ({"attr": "pos", "equals": 1, "in": [1]}, "labels.a: give one test, not equals and in"),
        ({"attr": "pos", "near": 1}, "labels.a.near: unknown test"),
        ({"reward": -5}, "labels.a.reward: expected a mapping of tests"),
        ({"reward": {"under": 3}}, "labels.a.reward: unknown test 'under'"),
        ({"terminated": False}, "labels.a.terminated: expected true"),
        ({"info": "x", "box": {"low": [1, 2], "high": [0, 3]}}, "labels.a.box: low is above"),
        ({"info": "x", "disc": {"center": [0], "radius": -1}}, "labels.a.disc.radius"),
        ({"info": "x", "obs": [1]}, "labels.a: expected exactly one of the forms"),
    ],
)
def test_bad_value_forms_name_the_field(declaration: dict[str, Any], message: str) -> None:
    with pytest.raises(LabelDeclarationError) as err:
        compile_labels({"a": declaration})
    assert str(err.value).startswith(message)


# -- world files: packages by name, wrappers ------------------------------------------------------


def world(tmp_path: Path, env: str, labels: str = "{a: {attr: carrying.kind, equals: key}}",
          formula: str = "F[0,8] a") -> Path:  # fmt: skip
    path = tmp_path / "world.yaml"
    text = f"env: {env}\nlabels: {labels}\nspec: {{formula: '{formula}'}}\nhorizon: 10\n"
    path.write_text(text)
    return path


def test_a_world_file_imports_an_installed_package_by_name(
    tmp_path: Path, package: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delitem(sys.modules, "mitlc_test_envs")
    monkeypatch.delitem(gym.registry, "MitlcTest/Probe-v0")
    path = world(tmp_path, "{import: [mitlc_test_envs], id: MitlcTest/Probe-v0}")
    task = load_env_task(path)
    assert "mitlc_test_envs" in sys.modules and task.propositions == ("a",)
    assert not is_finite(open_world(path))  # an attr label: learned through the wrapper
    monkeypatch.delitem(sys.modules, "mitlc_test_envs")
    monkeypatch.delitem(gym.registry, "MitlcTest/Probe-v0")
    load_env_task(world(tmp_path, "{id: 'mitlc_test_envs:MitlcTest/Probe-v0'}"))
    assert "MitlcTest/Probe-v0" in gym.registry


@pytest.mark.parametrize(
    ("env", "message"),
    [
        ("{import: [./evil.py], id: CartPole-v1}", "1:16: env.import[0]: expected an installed "
         "module's dotted name (e.g. minigrid), never a file"),
        ("{import: [no_such_module_x], id: CartPole-v1}", "env.import[0]: no installed module "
         "'no_such_module_x'"),
        ("{id: 'no_such_module_x:Foo-v0'}", "env.id: no installed module 'no_such_module_x'"),
        ("{id: '/tmp/evil.py:Foo-v0'}", "env.id: '/tmp/evil.py' is not a module's dotted name"),
        ("{id: mitlc/Task-v0}", "env.id: mitlc/Task-v0 is mitlc's own"),
        ("{import: [mitlc_test_envs], id: MitlcTest/Probe-v0, "
         "wrappers: ['mitlc_test_envs:NOT_A_WRAPPER']}",
         "env.wrappers[0]: mitlc_test_envs.NOT_A_WRAPPER is a int, not a gymnasium.Wrapper"),
        ("{id: MitlcTest/Probe-v0, wrappers: ['mitlc_test_envs.Recorder']}",
         "env.wrappers[0]: expected module:Class"),
        ("{import: [mitlc_test_envs], id: MitlcTest/Probe-v0, wrappers: [{class: "
         "'mitlc_test_envs:Recorder', kwargs: {nope: 1}}]}",
         "env.wrappers[0]: mitlc_test_envs:Recorder cannot wrap the env"),
    ],
)  # fmt: skip
def test_what_a_world_file_may_not_import_or_make_is_refused(
    tmp_path: Path, package: Any, env: str, message: str
) -> None:
    with pytest.raises(WorldError) as err:
        load_env_task(world(tmp_path, env))
    assert message in str(err.value)


def test_wrappers_are_applied_in_order_inside_the_task_wrapper(
    tmp_path: Path, package: Any
) -> None:
    recorder = "{class: 'mitlc_test_envs:Recorder', kwargs: {tag: %s}}"
    wrappers = f"[{recorder % 'first'}, {recorder % 'second'}]"
    env = f"{{import: [mitlc_test_envs], id: MitlcTest/Probe-v0, wrappers: {wrappers}}}"
    task = load_env_task(world(tmp_path, env))
    wrapped = task.task_env(translate(parse("F[0,8] a")))
    assert wrapped.unwrapped.wrapped == ["first", "second"]
    assert type(wrapped.env).__name__ == "Recorder" and isinstance(wrapped, TaskWrapper)


def test_a_label_path_missing_from_the_env_is_a_world_error_at_its_line(
    tmp_path: Path, package: Any
) -> None:
    labels = "{a: {attr: carrying.kind, equals: key}, b: {info: rewards.arived}}"
    path = world(tmp_path, "{id: MitlcTest/Probe-v0}", labels, "F a & F b")
    with pytest.raises(WorldError) as err:
        load_env_task(path)
    assert "world.yaml:2:" in str(err.value) and "labels.b.info: info.rewards has no key" in str(
        err.value
    )


# -- a finite env split by its events ------------------------------------------------------------


class EventfulToyText(ToyText):
    """:class:`ToyText` whose steps give random rewards (the events of the labels)."""

    def __init__(self, rng: random.Random, deterministic: bool) -> None:
        super().__init__(rng, deterministic)
        for s in self.P:
            for a in self.P[s]:
                self.P[s][a] = [(p, t, float(rng.choice([-1, 0, 0, 1])), end)
                                for p, t, _, end in self.P[s][a]]  # fmt: skip


@pytest.mark.parametrize("seed", range(4))
def test_event_labels_agree_between_wrapper_simulator_and_exact(seed: int) -> None:
    """``a`` an observation label, ``b`` the step's reward below 0 or its end: the converted
    world (states split by events) and the wrapper give the same success, episode by episode
    for deterministic envs and in rate for stochastic ones, and equal the exact value."""
    rng = random.Random(seed)
    checked = 0
    for k, formula in enumerate(specs(rng, 8)):
        deterministic = k % 2 == 0
        env = EventfulToyText(rng, deterministic)
        n = int(env.observation_space.n)
        labels = {"a": {"obs": sorted(rng.sample(range(n), rng.randint(1, n - 1)))},
                  "b": [{"reward": {"below": 0}}, {"terminated": True}]}  # fmt: skip
        automaton = translate(formula)
        horizon = rng.randint(2, 8)
        try:
            w = world_of(env, labels, to_text(formula), horizon)
        except GymWorldError as err:  # a label that holds in no reachable state
            assert "holds in no state" in str(err)
            continue
        checked += 1
        product = build_product(w, automaton)
        u = np.random.default_rng(seed * 10 + k).random((1 << product.num_sets, n, 64))
        counts = np.diff(product.choice_ptr)
        obs_of = np.array([c for _, c in w.cells])
        choice = np.full((1 << product.num_sets, product.num_states), -1)
        for x in np.flatnonzero(product.world_state >= 0):
            o, q = obs_of[product.world_state[x]], product.automaton_state[x]
            choice[:, x] = (u[:, o, q % 64] * counts[x]).astype(int)
        exact = policy_success(product, np.where(choice >= 0, product.choice_ptr[:-1] + choice,
                                                 -1), horizon)  # fmt: skip
        episodes = 1 if deterministic else 1200
        sim = VecProduct(tables(product, w), episodes, np.random.default_rng(seed))
        wins_sim, ended = 0, np.zeros(episodes, bool)
        while not ended.all():
            step = sim.step(np.maximum(choice[sim.mask, sim.state], 0))
            wins_sim += int((step.success & step.done & ~ended).sum())
            ended |= step.done
        wrapped = TaskWrapper(env, automaton, labels, rewards=REWARDS, horizon=horizon,
                              env_end="step")  # fmt: skip
        wins_env = 0
        for i in range(episodes):
            obs, _ = wrapped.reset(seed=seed * 10_000 + i)
            while True:
                o, q = int(obs["env"]), int(obs["automaton"])
                jumps = len(wrapped.monitor.jumps(q))
                a = int(u[wrapped.frontier, o, q % 64] * (wrapped._env_actions + jumps))
                obs, _, terminated, truncated, info = wrapped.step(a)
                if terminated or truncated:
                    wins_env += int(info["success"])
                    break
        if deterministic:
            assert wins_env == wins_sim == exact, to_text(formula)
        else:
            tolerance = 4.5 * np.sqrt(max(exact * (1 - exact), 1e-4) / episodes)
            assert abs(wins_env / episodes - exact) <= tolerance, to_text(formula)
            assert abs(wins_sim / episodes - exact) <= tolerance, to_text(formula)
    assert checked >= 3


def test_cliffwalking_with_the_cliff_as_an_event(tmp_path: Path) -> None:
    """The cliff is never a state CliffWalking is in: as an event, a finite world checks it."""
    path = tmp_path / "cliff.yaml"
    path.write_text(
        textwrap.dedent("""\
        env: {id: CliffWalking-v1}
        labels: {goal: {obs: [47]}, cliff: {reward: {below: -50}}}
        spec: {formula: "!cliff U[0,20] goal"}
        horizon: 25
    """)
    )
    w = load_world(path)
    start = w.cells[w.start]
    fell = [s for s, c in enumerate(w.cells) if c == start and w.letters[s]]
    assert len(fell) == 1 and w.propositions[int(w.letters[fell[0]]).bit_length() - 1] == "cliff"
    from mitlc.check import check

    report = check(w, translate(parse(w.spec)))
    assert report.pmax_horizon == pytest.approx(1.0)
    wrapped = TaskWrapper(gym.make("CliffWalking-v1"), w.spec,
                       {"goal": {"obs": [47]}, "cliff": {"reward": {"below": -50}}},
                       horizon=25)  # fmt: skip
    wrapped.reset(seed=0)
    wrapped.step(1)  # right from the start: into the cliff, back to the start
    _, _, terminated, _, info = wrapped.step(0)
    assert terminated and info["verdict"] == "violated"


def test_labels_that_never_held_are_reported_by_train_and_eval(
    tmp_path: Path, package: Any
) -> None:
    from mitlc.learn.config import TrainConfig
    from mitlc.learn.evaluation.evaluate import evaluate
    from mitlc.learn.run import train

    labels = "{a: {info: rewards.arrived}, ghost: {attr: carrying.kind, equals: lamp}}"
    path = world(tmp_path, "{id: MitlcTest/Probe-v0}", labels, "F a | F ghost")
    config = TrainConfig(algo="q", episodes=40, seed=1, log_every=20, eval_episodes=30)
    result = train(path, config, tmp_path / "run")
    assert result.never_held == ("ghost",)
    summary = (tmp_path / "run" / "summary.json").read_text()
    assert '"never_held": [\n    "ghost"\n  ]' in summary or '"ghost"' in summary
    report = evaluate(tmp_path / "run", episodes=30)
    assert report.never_held == ("ghost",) and report.summary()["never_held"] == ["ghost"]
