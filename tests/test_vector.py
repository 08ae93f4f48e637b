"""The finite product's simulator as a gymnasium vector env: the same episodes as gymnasium's
``SyncVectorEnv`` of ``ProductEnv`` copies (same-step autoreset) on deterministic worlds, its
spaces, masks and episode infos."""

from __future__ import annotations

import random

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

from mitlc.automata import DigitalAutomaton, translate
from mitlc.learn.envs.vec import tables
from mitlc.learn.envs.vector import ProductVectorEnv
from mitlc.product import ProductEnv, build_product
from mitlc.worlds.model import World
from tests.test_task_agreement import random_world, specs


@pytest.mark.parametrize("seed", range(4))
def test_the_vector_env_steps_as_gymnasiums_sync_vector_env(seed: int) -> None:
    rng = random.Random(seed)
    actions_rng = np.random.default_rng(seed)
    for formula in specs(seed, 6):
        automaton = translate(formula)
        world = random_world(rng, automaton.propositions, deterministic=True)
        product = build_product(world, automaton)
        if product.world_state[product.initial] < 0:
            continue  # decided at the start: the product keeps no cell (it shows cell 0)
        t = tables(product, world)
        n = 3
        ours = ProductVectorEnv(t, n, seed=seed)

        def make(world: World = world, automaton: DigitalAutomaton = automaton) -> ProductEnv:
            return ProductEnv(world, automaton)

        theirs = gym.vector.SyncVectorEnv([make] * n, autoreset_mode=AutoresetMode.SAME_STEP)
        obs, _ = ours.reset(seed=seed)
        expected, _ = theirs.reset(seed=seed)
        assert ours.observation_space.contains(obs)
        same_keys(obs, expected, np.ones(n, dtype=np.bool_))
        for _ in range(3 * world.horizon):
            masks = ours.action_masks()
            their_masks = np.stack(theirs.call("action_masks"))[:, : masks.shape[1]]
            assert (masks == their_masks).all()
            actions = (actions_rng.random(masks.shape) * masks).argmax(axis=1)
            obs, reward, term, trunc, info = ours.step(actions)
            exp_obs, exp_reward, exp_term, exp_trunc, exp_info = theirs.step(actions)
            assert (term == exp_term).all() and (trunc == exp_trunc).all()
            assert reward.tolist() == exp_reward.tolist()
            same_keys(obs, exp_obs, np.ones(n, dtype=np.bool_))
            ended = term | trunc
            if ended.any():
                assert (info["_success"] == ended).all()
                finals = exp_info["final_info"]["success"]
                assert (info["success"][ended] == finals[ended]).all()
                for i in np.flatnonzero(trunc).tolist():  # a decided end merges the state
                    final, exp_final = info["final_obs"][i], exp_info["final_obs"][i]
                    assert {k: int(v) for k, v in final.items()} == {
                        k: int(v) for k, v in exp_final.items()
                    }


def same_keys(
    obs: dict[str, np.ndarray], expected: dict[str, np.ndarray], rows: np.ndarray
) -> None:
    for key in ("world", "automaton", "frontier"):
        assert obs[key][rows].tolist() == expected[key][rows].tolist(), key


def test_episode_infos_and_speed_of_the_wrapper_are_the_simulators() -> None:
    """Episode returns and lengths in ``infos["episode"]`` are the simulator's, and the vector
    env passes the simulator's step through (``last_step``)."""
    from mitlc.learn.config import resolve
    from mitlc.learn.run import prepare
    from tests.conftest import ROOT

    path = ROOT / "specs" / "paper" / "case1.yaml"
    setting = prepare(path, resolve({}, {}, discount=0.99, pomdp=False))
    env = ProductVectorEnv(setting.tables, 64, seed=0)
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    ended = 0
    for _ in range(200):
        masks = env.action_masks()
        _, _, term, trunc, info = env.step((rng.random(masks.shape) * masks).argmax(axis=1))
        step = env.last_step
        assert step is not None
        if (term | trunc).any():
            done = term | trunc
            assert (info["episode"]["l"][done] == step.episode_steps[done]).all()
            assert (info["episode"]["r"][done] == step.episode_return[done]).all()
            ended += int(done.sum())
    assert ended > 100


class _Plain(gym.vector.VectorWrapper):
    """The vector env with nothing but gymnasium's API (no ``step_task`` fast path)."""


FIELDS = ("reward", "accepting", "terminated", "truncated", "episode_return", "episode_steps")
REACHED = ("next_mask", "next_observation", "next_automaton", "next_valid")


def test_the_learners_view_of_the_simulator_is_what_its_infos_say() -> None:
    """``VectorTask`` reads the simulator's own step (``step_task``) or decodes the gymnasium
    API's observations and infos: the same steps, product states included."""
    from mitlc.learn.config import resolve
    from mitlc.learn.envs.envvec import VectorTask
    from mitlc.learn.run import prepare
    from tests.conftest import ROOT

    for name in ("case1.yaml", "case2.yaml"):
        setting = prepare(ROOT / "specs" / "paper" / name, resolve({}, {}, discount=0.99,
                                                                   pomdp=False))  # fmt: skip
        fast = VectorTask(ProductVectorEnv(setting.tables, 32, seed=5))
        plain = VectorTask(_Plain(ProductVectorEnv(setting.tables, 32, seed=5)))
        assert not hasattr(plain.venv, "step_task")
        rng, ended = np.random.default_rng(0), 0
        for _ in range(120):
            assert (fast.valid_actions() == plain.valid_actions()).all()
            assert (fast.state == plain.state).all() and (fast.automaton == plain.automaton).all()
            masks = fast.valid_actions()
            actions = (rng.random(masks.shape) * masks).argmax(axis=1)
            a, b = fast.step(actions), plain.step(actions)
            for field in (*FIELDS, *REACHED, "next_state"):
                assert np.array_equal(getattr(a, field), getattr(b, field)), field
            assert np.array_equal(a.success[a.done], b.success[a.done])
            ended += int(a.done.sum())
        assert ended > 50


@pytest.mark.parametrize("seed", range(3))
def test_the_simulator_and_a_vector_of_wrapped_envs_give_the_learners_the_same_steps(
    seed: int,
) -> None:
    """On deterministic worlds, the learners' view of the product simulator and of gymnasium's
    ``SyncVectorEnv`` of ``ProductEnv`` (``TaskWrapper`` over the grid) agree step by step
    (the product merges decided states, so what a decided end reached is not compared)."""
    from mitlc.learn.envs.envvec import VectorTask, task_vector

    rng = random.Random(seed)
    actions_rng = np.random.default_rng(seed)
    for formula in specs(seed, 5):
        automaton = translate(formula)
        world = random_world(rng, automaton.propositions, deterministic=True)
        product = build_product(world, automaton)
        if product.world_state[product.initial] < 0:
            continue
        ours = VectorTask(ProductVectorEnv(tables(product, world), 3, seed=seed))
        theirs = task_vector([ProductEnv(world, automaton) for _ in range(3)], seed=seed)
        for _ in range(3 * world.horizon):
            masks = ours.valid_actions()
            assert (masks == theirs.valid_actions()[:, : masks.shape[1]]).all()
            actions = (actions_rng.random(masks.shape) * masks).argmax(axis=1)
            a, b = ours.step(actions), theirs.step(actions)
            for field in FIELDS:
                assert np.array_equal(getattr(a, field), getattr(b, field)), field
            assert np.array_equal(a.success[a.done], b.success[a.done])
            live = ~a.terminated
            for field in ("next_mask", "next_observation", "next_automaton"):
                assert np.array_equal(getattr(a, field)[live], getattr(b, field)[live]), field
            assert (a.next_valid[live] == b.next_valid[live][:, : masks.shape[1]]).all()
