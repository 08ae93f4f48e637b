"""Stable-Baselines3 on a timed task, through mitlc's gymnasium wrapper.

The task, on gymnasium's slippery FrozenLake 4x4: reach the goal within 100 steps without
falling into a hole, ``!hole U[0,100] goal``. :class:`mitlc.gym.TaskWrapper` puts it on the env:
it labels each observation (``goal`` is state 15, ``hole`` states 5, 7, 11, 12), runs the
task's automaton beside the env, replaces the env's reward with the task's, ends the episode
when the task is decided or after ``horizon`` steps, and reports ``info["is_success"]`` (the
name SB3's loggers count) and ``action_masks()`` (what sb3-contrib's ``MaskablePPO`` reads).
With ``flatten=True`` the observation is one float vector (the one-hot state, the one-hot
automaton state and the frontier's bits), so SB3's ``MlpPolicy`` fits it.

The script trains ``MaskablePPO`` (or ``PPO``), measures the greedy policy's success over
seeded episodes of the wrapped env with a 95% Wilson interval, and prints it beside the exact
optimum of the same task, computed by mitlc from the env's own transition table
(``specs/gym/frozenlake4x4.yaml`` states this task; ``mitlc check`` prints the same number)::

    pip install 'mitlc[sb3]'
    python examples/sb3_frozenlake.py --steps 200000 --algo maskable-ppo
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path
from typing import Any

import gymnasium as gym

from mitlc.gym import TaskWrapper

SPEC = "!hole U[0,100] goal"
LABELS = {"goal": {"obs": [15]}, "hole": {"obs": [5, 7, 11, 12]}}
HORIZON = 110
"""The task's horizon, past its deadline (100). FrozenLake-v1's own time limit (100 steps) is
lifted to it: cut at 100, an episode would end before the task reads its last position, and a
task without acceptance sets that is still pending counts as a success so far
(``info["is_success"]``), so the measured success would exceed the optimum."""
WORLD = Path(__file__).resolve().parents[1] / "specs" / "gym" / "frozenlake4x4.yaml"


def make_env() -> TaskWrapper:
    """The wrapped env: FrozenLake with the task, rewarded 1 when the task is satisfied."""
    return TaskWrapper(
        gym.make("FrozenLake-v1", is_slippery=True, max_episode_steps=HORIZON),
        SPEC,
        LABELS,
        horizon=HORIZON,
        rewards={"satisfied": 1.0, "accept": 0.0},
        flatten=True,
    )


def train(algo: str, steps: int, seed: int) -> Any:
    """An SB3 model (``maskable-ppo`` or ``ppo``) trained for ``steps`` env steps on 8 copies
    of the wrapped env (rollouts of 8 x 256 steps, 4 epochs of minibatches of 256, a little
    entropy bonus: about twice as fast as SB3's defaults here, for the same success)."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_util import make_vec_env

    envs = make_vec_env(make_env, n_envs=8, seed=seed)
    settings: dict[str, Any] = {"n_steps": 256, "batch_size": 256, "n_epochs": 4, "ent_coef": 0.01}
    if algo == "maskable-ppo":
        from sb3_contrib import MaskablePPO

        model: Any = MaskablePPO("MlpPolicy", envs, seed=seed, verbose=0, **settings)
    else:
        model = PPO("MlpPolicy", envs, seed=seed, verbose=0, **settings)
    return model.learn(total_timesteps=steps)


def evaluate(model: Any, episodes: int, seed: int = 10_000) -> tuple[int, int]:
    """Successes of the greedy policy (``deterministic=True``) in ``episodes`` seeded episodes of
    the wrapped env, read from ``info["is_success"]`` at each episode's end."""
    env = make_env()
    masked = type(model).__name__ == "MaskablePPO"
    successes = 0
    for episode in range(episodes):
        obs, info = env.reset(seed=seed + episode)
        done = False
        while not done:
            extra = {"action_masks": env.action_masks()} if masked else {}
            action, _ = model.predict(obs, deterministic=True, **extra)
            obs, _, terminated, truncated, info = env.step(int(action))
            done = terminated or truncated
        successes += bool(info["is_success"])
    return successes, episodes


def wilson(successes: int, trials: int, z: float = 1.959963984540054) -> tuple[float, float]:
    """The 95% Wilson score interval of a success rate."""
    p = successes / trials
    centre = (p + z * z / (2 * trials)) / (1 + z * z / trials)
    half = z * math.sqrt(p * (1 - p) / trials + z * z / (4 * trials**2)) / (1 + z * z / trials)
    return max(0.0, centre - half), min(1.0, centre + half)


def optimum() -> float | None:
    """The task's exact optimum (``pmax_horizon`` of the product of FrozenLake's transition
    table with the task), or None where the shipped world file is not at hand."""
    if not WORLD.is_file():
        return None
    from mitlc.automata import translate
    from mitlc.check.solve import pmax_horizon
    from mitlc.product.explicit import build_product
    from mitlc.syntax import parse
    from mitlc.worlds import load_world

    world = load_world(WORLD)
    product = build_product(world, translate(parse(world.spec, world.spec_source)))
    best, _ = pmax_horizon(product, world.horizon, keep_history=False)
    return float(best)


def main(argv: list[str] | None = None) -> dict[str, Any]:
    """Train, evaluate and print the report; the figures as a dict."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--algo", choices=["maskable-ppo", "ppo"], default="maskable-ppo")
    parser.add_argument("--steps", type=int, default=200_000)
    parser.add_argument("--episodes", type=int, default=1_000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    import torch

    torch.set_num_threads(1)  # small networks: one thread is faster than several
    start = time.perf_counter()
    model = train(args.algo, args.steps, args.seed)
    seconds = time.perf_counter() - start
    successes, episodes = evaluate(model, args.episodes)
    low, high = wilson(successes, episodes)
    best = optimum()
    print(f"{args.algo}, {args.steps:,} steps in {seconds:.1f} s")
    print(f"greedy success  {successes / episodes:.4f}  95% [{low:.4f}, {high:.4f}]  "
          f"({successes}/{episodes} episodes)")  # fmt: skip
    if best is not None:
        print(f"exact optimum   {best:.6f}  (ratio {successes / episodes / best:.3f})")
    return {"success_rate": successes / episodes, "interval95": (low, high), "optimum": best,
            "episodes": episodes, "seconds": seconds}  # fmt: skip


if __name__ == "__main__":
    main()
