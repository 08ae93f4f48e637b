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
from mitlc.learn.vec import tables
from mitlc.learn.vector import ProductVectorEnv
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
