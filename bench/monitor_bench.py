"""The task monitor's speed: letters per second of the batched form for 1,024 episodes, beside
the scalar form stepping the same episodes one at a time, in the same run.

Target (issue 12): the batched monitor reads at least 10 million letters a second for 1,024
episodes. The letters are drawn at random over the task's propositions; the monitor's tables are
warmed first (every (state, letter) pair reached is made once, as in a long run).

    .venv/bin/python bench/monitor_bench.py [--episodes 1024] [--steps 2000]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from mitlc.automata import translate
from mitlc.syntax import parse
from mitlc.task import TaskMonitor
from mitlc.worlds.model import Rewards

TASKS = (
    "(!a U[5,10] a) & (!b U[15,20] b)",
    "G F a & G F b & G !c",
    "F G a | G F b",
)


def batched(monitor: TaskMonitor, letters: np.ndarray) -> float:
    """Seconds to read ``letters[t, i]`` into episode ``i`` for every step ``t``; decided
    episodes restart."""
    episodes = letters.shape[1]
    initial = monitor.reset().q
    q = np.full(episodes, initial, dtype=np.int64)
    frontier = np.zeros(episodes, dtype=np.int64)
    rounds = np.zeros(episodes, dtype=np.int64)
    start = time.perf_counter()
    for row in letters:
        out = monitor.read_batch(q, frontier, rounds, row)
        ended = out.terminated
        q = np.where(ended, initial, out.q)
        frontier = np.where(ended, 0, out.frontier)
        rounds = np.where(ended, 0, out.rounds)
    return time.perf_counter() - start


def scalar(monitor: TaskMonitor, letters: np.ndarray) -> float:
    """The same with :meth:`TaskMonitor.step`, one episode at a time."""
    episodes = letters.shape[1]
    rows = letters.T.tolist()
    start = time.perf_counter()
    for i in range(episodes):
        state = monitor.reset()
        for letter in rows[i]:
            outcome = monitor.step(state, letter)
            state = monitor.reset() if outcome.terminated else outcome.state
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=1024)
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--scalar-steps", type=int, default=100)
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    print(f"{'task':38} {'batched letters/s':>18} {'scalar letters/s':>17} {'ratio':>7}")
    for task in TASKS:
        automaton = translate(parse(task))
        monitor = TaskMonitor(automaton, Rewards())
        size = 1 << len(automaton.propositions)
        letters = rng.integers(0, size, size=(args.steps, args.episodes))
        batched(monitor, letters[:50])  # warm the tables
        fast = args.steps * args.episodes / batched(monitor, letters)
        few = letters[: args.scalar_steps]
        slow = few.size / scalar(monitor, few)
        print(f"{task:38} {fast:18,.0f} {slow:17,.0f} {fast / slow:7.1f}")


if __name__ == "__main__":
    main()
