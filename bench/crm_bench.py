"""Counterfactual experience (CRM) for tabular Q-learning: episodes (and seconds) until the
greedy policy reaches 0.98 x the optimum, with and without it, side by side in one run.

Every ``--every`` episodes the greedy policy's exact success probability is computed on the
product (:func:`mitlc.learn.evaluation.exact.policy_success`) and compared with the optimum of the
same
event (``pmax_horizon``). Each world trains with its file's settings and seed, the schedules
stretched over ``--episodes``; the same seeds with CRM off and on.

    .venv/bin/python bench/crm_bench.py [--episodes 300000] [--every 10000]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from mitlc.check.solve import pmax_horizon  # noqa: E402
from mitlc.learn.config import resolve  # noqa: E402
from mitlc.learn.envs.vec import VecProduct  # noqa: E402
from mitlc.learn.evaluation.exact import policy_success  # noqa: E402
from mitlc.learn.learners.qlearning import QLearner  # noqa: E402
from mitlc.learn.run import Setting, make_learner, prepare  # noqa: E402
from mitlc.worlds.load import read_any_world_file  # noqa: E402

WORLDS = ("specs/paper/case1.yaml", "specs/gym/taxi.yaml", "specs/gym/frozenlake4x4.yaml")
TARGET = 0.98


def run(path: Path, crm: bool, episodes: int, every: int) -> tuple[int | None, float, float]:
    """Episodes and training seconds to reach the target (``None``: not within ``episodes``),
    and the last exact success."""
    raw = read_any_world_file(path)
    overrides = {"algo": "q", "episodes": episodes, "q.crm": crm}
    config = resolve(raw.training, overrides, discount=raw.discount, pomdp=False)
    base = prepare(path, config)
    setting = Setting(base.world_path, base.world, base.automaton, base.product, base.tables,
                      config)  # fmt: skip
    optimum, _ = pmax_horizon(setting.product, setting.world.horizon, keep_history=False)
    rng = np.random.default_rng(config.seed)
    learner = make_learner(setting, rng)
    assert isinstance(learner, QLearner)
    env = VecProduct(setting.tables, learner.num_envs, np.random.default_rng(config.seed + 1))
    done, seconds, next_check, value = 0, 0.0, every, 0.0
    while done < episodes:
        start = time.perf_counter()
        step = learner.train_step(env, done / episodes)
        seconds += time.perf_counter() - start
        done += int(step.done.sum())
        if done >= next_check:
            next_check += every
            value = policy_success(setting.product, learner.policy().choices(),
                                   setting.world.horizon)  # fmt: skip
            if value >= TARGET * optimum:
                return done, seconds, value / optimum
    return None, seconds, value / optimum


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=300_000)
    parser.add_argument("--every", type=int, default=10_000)
    parser.add_argument("worlds", nargs="*", default=list(WORLDS))
    args = parser.parse_args()
    print(f"target: greedy exact success >= {TARGET} x optimum; checked every {args.every:,} "
          f"episodes, at most {args.episodes:,}\n")  # fmt: skip
    print(f"{'world':32} {'CRM':>4} {'episodes':>10} {'train s':>8} {'ratio':>7}")
    for world in args.worlds:
        for crm in (False, True):
            reached, seconds, ratio = run(ROOT / world, crm, args.episodes, args.every)
            shown = f"{reached:,}" if reached is not None else "not reached"
            print(f"{world:32} {'on' if crm else 'off':>4} {shown:>10} {seconds:8.1f} {ratio:7.3f}")


if __name__ == "__main__":
    main()
