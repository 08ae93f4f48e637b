"""A learner on a continuous world today: Stable-Baselines3's PPO on the task wrapper of a
``plane:`` world (``mitlc.worlds.plane_env.make_plane_env(path, flatten=True)``), then the
greedy policy's success over seeded episodes with its 95% Wilson interval, beside the exact
optimum of the grid version of the same case (a reference, not a bound: the continuous world
is another world).

    .venv/bin/python bench/continuous_sb3.py [--world specs/continuous/case1.yaml]
        [--grid specs/paper/case1.yaml] [--steps 100000] [--episodes 1000]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from mitlc.automata import translate  # noqa: E402
from mitlc.check import check  # noqa: E402
from mitlc.learn.evaluation.evaluate import wilson  # noqa: E402
from mitlc.syntax import parse  # noqa: E402
from mitlc.worlds import load_world  # noqa: E402
from mitlc.worlds.plane_env import make_plane_env  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--world", default="specs/continuous/case1.yaml")
    parser.add_argument("--grid", default="specs/paper/case1.yaml")
    parser.add_argument("--steps", type=int, default=100_000)
    parser.add_argument("--episodes", type=int, default=1000)
    parser.add_argument("--envs", type=int, default=8)
    args = parser.parse_args()
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_util import make_vec_env

    world = str(ROOT / args.world)
    vec = make_vec_env(lambda: make_plane_env(world, flatten=True), n_envs=args.envs, seed=0)
    start = time.perf_counter()
    model = PPO("MlpPolicy", vec, seed=0, device="cpu", verbose=0).learn(args.steps)
    seconds = time.perf_counter() - start
    env = make_plane_env(world, flatten=True)
    wins = 0
    for episode in range(args.episodes):
        obs, info = env.reset(seed=10_000 + episode)
        done = False
        while not done:
            action, _ = model.predict(obs, deterministic=True)
            obs, _, terminated, truncated, info = env.step(int(action))
            done = terminated or truncated
        wins += bool(info["is_success"])
    grid = load_world(ROOT / args.grid)
    optimum = check(grid, translate(parse(grid.spec, grid.spec_source))).pmax_horizon
    low, high = wilson(wins, args.episodes)
    rate = wins / args.episodes
    print(f"{args.world}: PPO, {args.steps:,} steps in {seconds:.1f} s")
    print(f"greedy success {rate:.4f} [{low:.4f}, {high:.4f}] over {args.episodes:,} episodes")
    print(f"grid optimum (a reference, not a bound) {optimum:.6f}; ratio {rate / optimum:.3f}")


if __name__ == "__main__":
    main()
