"""Tabular environment steps per second: the vectorised product simulator (mitlc.learn.envs.vec)
beside a plain gymnasium step loop over the same product (mitlc.product.env.ProductEnv), in
one run on this machine.

    .venv/bin/python bench/learn_throughput.py [--seconds S]

Rows: the gymnasium loop with random actions (one Python ``step`` per environment step, what
a pure-Python tabular learner pays), the simulator alone with random valid actions, and the
simulator with the tabular Q-learning update (``QLearner.train_step``), for batch sizes from
64 to 16,384 episodes.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from mitlc.learn.config import resolve
from mitlc.learn.envs.envvec import VectorTask
from mitlc.learn.envs.vec import VecProduct
from mitlc.learn.envs.vector import ProductVectorEnv
from mitlc.learn.learners.base import random_valid
from mitlc.learn.learners.qlearning import QLearner
from mitlc.learn.run import prepare
from mitlc.product.env import ProductEnv

WORLD = "specs/paper/case1.yaml"


def rate(run: Callable[[], int], seconds: float) -> float:
    """Steps per second of ``run`` (which returns the steps it took) over ``seconds``."""
    run()  # warm up
    steps, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        steps += run()
    return steps / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=2.0, help="time per row")
    args = parser.parse_args()
    config = resolve({}, {}, discount=0.99, pomdp=False)
    setting = prepare(Path(WORLD), config)
    env = ProductEnv(setting.world, setting.automaton)
    env.reset(seed=0)
    rng = np.random.default_rng(0)

    def gym_loop() -> int:
        for _ in range(1000):
            _, _, terminated, truncated, _ = env.step(int(rng.integers(env.world.num_actions)))
            if terminated or truncated:
                env.reset()
        return 1000

    baseline = rate(gym_loop, args.seconds)
    rows = [("gymnasium ProductEnv.step loop", 1, baseline)]
    for n in (64, 1024, 16_384):
        vec = VecProduct(setting.tables, n, np.random.default_rng(1))

        def simulate(vec: VecProduct = vec) -> int:
            for _ in range(20):
                vec.step(random_valid(rng, vec.valid_actions()))
            return 20 * vec.num_envs

        rows.append(("VecProduct.step, random actions", n, rate(simulate, args.seconds)))
    for n in (1024, 16_384):
        vector = ProductVectorEnv(setting.tables, n, seed=1)
        vector.reset(seed=1)

        def through_api(vector: ProductVectorEnv = vector) -> int:
            for _ in range(20):
                vector.step(random_valid(rng, vector.action_masks()))
            return 20 * vector.num_envs

        rows.append(("ProductVectorEnv.step (gymnasium API)", n, rate(through_api, args.seconds)))
    for n in (1024, 16_384):
        learner_config = resolve({}, {"q.num_envs": n}, discount=0.99, pomdp=False)
        learner = QLearner(setting.tables, learner_config, np.random.default_rng(2))
        vec = VecProduct(setting.tables, n, np.random.default_rng(3))

        def learn(vec: VecProduct = vec, learner: QLearner = learner) -> int:
            for _ in range(20):
                learner.train_step(vec, 0.5)
            return 20 * vec.num_envs

        rows.append(("QLearner.train_step on VecProduct", n, rate(learn, args.seconds)))
        task = VectorTask(ProductVectorEnv(setting.tables, n, rng=np.random.default_rng(3)))

        def learn_api(task: VectorTask = task, learner: QLearner = learner) -> int:
            for _ in range(20):
                learner.train_step(task, 0.5)
            return 20 * task.num_envs

        rows.append(("QLearner.train_step, VectorEnv (runs)", n, rate(learn_api, args.seconds)))
    print(f"world {WORLD}: {setting.product.num_states} product states\n")
    print(f"{'what':<38} {'episodes':>9} {'steps/s':>13} {'vs gymnasium':>13}")
    for name, n, value in rows:
        print(f"{name:<38} {n:>9,} {value:>13,.0f} {value / baseline:>12.1f}x")


if __name__ == "__main__":
    main()
