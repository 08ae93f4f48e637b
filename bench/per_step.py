"""Steps per second of mitlc's DQN (case 1), recurrent DQN (case 3), tabular Q (case 1) and the
task wrapper (flat FrozenLake), with the default settings (the one-hot observation, no
shaping): for a paired comparison of two versions, run alternately in the same minutes, each
from its own checkout (``PYTHONPATH`` picks the version). Prints one JSON line.

    git worktree add /tmp/oldtree REV
    for i in 1 2 3; do for v in /tmp/oldtree $PWD; do
      PYTHONPATH=$v .venv/bin/python bench/per_step.py; done; done
"""

from __future__ import annotations

import json
import time
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np

from mitlc.gym import TaskWrapper
from mitlc.learn.config import resolve
from mitlc.learn.envs.vec import VecProduct
from mitlc.learn.run import make_learner, prepare

ROOT = Path(__file__).resolve().parents[1]


def learner_rate(world: str, algo: str, steps: int) -> float:
    """Env steps per second of ``algo``'s training steps on ``world`` (after a warm-up)."""
    config = resolve({}, {"algo": algo}, discount=0.99, pomdp=algo == "drqn")
    setting = prepare(ROOT / world, config)
    learner = make_learner(setting, np.random.default_rng(0))
    assert setting.tables is not None
    env = VecProduct(setting.tables, learner.num_envs, np.random.default_rng(1))
    for _ in range(200):
        learner.train_step(env, 0.5)
    start = time.perf_counter()
    for _ in range(steps):
        learner.train_step(env, 0.5)
    return steps * learner.num_envs / (time.perf_counter() - start)


def wrapper_rate(steps: int = 30_000) -> float:
    """Steps per second of the flat task wrapper on slippery FrozenLake, seeded actions."""
    labels = {"goal": {"obs": [15]}, "hole": {"obs": [5, 7, 11, 12]}}
    lake = gym.make("FrozenLake-v1", is_slippery=True)
    env = TaskWrapper(lake, "!hole U[0,100] goal", labels, horizon=100, flatten=True)
    actions = np.random.default_rng(0).integers(4, size=steps)
    env.reset(seed=0)
    start = time.perf_counter()
    for action in actions:
        _, _, terminated, truncated, _ = env.step(int(action))
        if terminated or truncated:
            env.reset()
    return steps / (time.perf_counter() - start)


def main() -> None:
    warnings.filterwarnings("ignore")
    out = {
        "dqn_case1": learner_rate("specs/paper/case1.yaml", "dqn", 1500),
        "drqn_case3": learner_rate("specs/paper/case3-office.yaml", "drqn", 300),
        "q_case1": learner_rate("specs/paper/case1.yaml", "q", 300),
        "wrapper_flat": wrapper_rate(),
    }
    print(json.dumps(out))


if __name__ == "__main__":
    main()
