"""The task wrapper's cost per step, beside the bare env in the same run.

Steps per second of ``gymnasium.make("FrozenLake-v1", is_slippery=True)`` (with gymnasium's own
default wrappers: the time limit, the order enforcer and the passive checker), of the same env
under a one-line gymnasium wrapper that does nothing (the floor any wrapper pays), and under
``mitlc.gym.TaskWrapper`` with a timed task and declarative labels, plain and with the
observation flattened. Every env takes the same seeded action sequence; a run restarts on
``terminated`` or ``truncated``. Target (issue 12): the wrapped env runs at least 0.5x the bare
env's steps per second.

    .venv/bin/python bench/wrapper_bench.py [--steps 200000] [--repeats 3]
"""

from __future__ import annotations

import argparse
import time
import warnings
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np

from mitlc.gym import TaskWrapper

SPEC = "!hole U[0,100] goal"
LABELS = {"goal": {"obs": [15]}, "hole": {"obs": [5, 7, 11, 12]}}


class _Nothing(gym.Wrapper[Any, Any, Any, Any]):
    """A wrapper that passes everything through."""

    def step(self, action: Any) -> Any:
        return self.env.step(action)


def bare() -> gym.Env[Any, Any]:
    return gym.make("FrozenLake-v1", is_slippery=True)


MAKERS: dict[str, Callable[[], gym.Env[Any, Any]]] = {
    "bare FrozenLake-v1": bare,
    "a do-nothing wrapper": lambda: _Nothing(bare()),
    "TaskWrapper": lambda: TaskWrapper(bare(), SPEC, LABELS, horizon=100),
    "TaskWrapper, flattened": lambda: TaskWrapper(bare(), SPEC, LABELS, horizon=100, flatten=True),
}


def rate(env: gym.Env[Any, Any], actions: list[int]) -> float:
    """Steps per second over ``actions``."""
    env.reset(seed=0)
    step, reset = env.step, env.reset
    start = time.perf_counter()
    for a in actions:
        _, _, terminated, truncated, _ = step(a)
        if terminated or truncated:
            reset()
    return len(actions) / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=200_000)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    warnings.filterwarnings("ignore")
    actions = np.random.default_rng(0).integers(0, 4, size=args.steps).tolist()
    envs = {name: make() for name, make in MAKERS.items()}
    best = dict.fromkeys(envs, 0.0)
    for _ in range(args.repeats):  # interleaved, so load on the machine hits every env alike
        for name, env in envs.items():
            best[name] = max(best[name], rate(env, actions))
    base = best["bare FrozenLake-v1"]
    print(f"{'env':28} {'steps/s':>10} {'x bare':>7}   (best of {args.repeats})")
    for name, value in best.items():
        print(f"{name:28} {value:10,.0f} {value / base:7.2f}")


if __name__ == "__main__":
    main()
