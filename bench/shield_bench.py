"""Shielded beside unshielded learning, same seeds, same budget (issue 27).

    .venv/bin/python bench/shield_bench.py [--seeds 0,1,2] [--out build/bench-shield]

For case 1, FrozenLake 8x8 with ``!hole U[0,100] goal`` and Taxi, tabular Q-learning runs
twice per seed: *plain*, under an audit of the shield (computed, not kept to: the run records
the actions it takes that the shield blocks and the violations after one), and *shielded*,
kept to ``--shield 1 --shield-violation 0``. Printed per task and setting, over the seeds:
training episodes ended violated, the preventable ones (a violated episode that took a
blocked action), blocked actions taken, the episodes until a logged window's success reached
0.98 x the optimum (the behaviour policy's, exploration included; "-" when never), and the
greedy policy's exact success after training beside the optimum (``mitlc eval``'s figures).
Runs that finished are read again, not retrained (delete ``--out`` to start over).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from statistics import mean

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from mitlc.learn.config import config_for
from mitlc.learn.evaluation.evaluate import evaluate
from mitlc.learn.run import train
from mitlc.worlds.door import open_world

ROOT = Path(__file__).resolve().parents[1]
TASKS = {
    "case1": (ROOT / "specs/paper/case1.yaml", None, 300_000),
    "frozenlake8x8": (ROOT / "specs/gym/frozenlake8x8.yaml", "!hole U[0,100] goal", 300_000),
    "taxi": (ROOT / "specs/gym/taxi.yaml", None, 300_000),
}
SETTINGS = {
    "plain": {"shield": 1.0, "shield_violation": 0.0, "shield_audit": True},
    "shielded": {"shield": 1.0, "shield_violation": 0.0},
}


def run(task: str, setting: str, seed: int, out: Path) -> dict[str, float | int | None]:
    world, spec, episodes = TASKS[task]
    directory = out / f"{task}-{setting}-s{seed}"
    overrides = {**SETTINGS[setting], "seed": seed, "episodes": episodes}
    if not (directory / "summary.json").exists():
        config, _ = config_for(open_world(world, spec), overrides)
        started = time.perf_counter()
        train(world, config, directory, spec=spec)
        print(f"  {directory.name}: {time.perf_counter() - started:.1f} s", flush=True)
    summary = json.loads((directory / "summary.json").read_text())
    lines = [json.loads(line) for line in (directory / "metrics.jsonl").open()]
    report = evaluate(directory, episodes=2000)
    optimum = summary["shield"]["optimum"]
    reached = next((r["episodes"] for r in lines if r["success_rate"] >= 0.98 * optimum), None)
    return {
        "violations": summary["violations"],
        "preventable": summary["preventable_violations"],
        "blocked": summary["blocked_actions"],
        "to_098": reached,
        "exact": report.exact,
        "optimum": optimum,
        "seconds": summary["seconds"],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", default="0,1,2")
    parser.add_argument("--out", type=Path, default=ROOT / "build" / "bench-shield")
    parser.add_argument("--tasks", default=",".join(TASKS))
    args = parser.parse_args()
    seeds = [int(s) for s in args.seeds.split(",")]
    rows = []
    for task in args.tasks.split(","):
        for setting in SETTINGS:
            results = [run(task, setting, seed, args.out) for seed in seeds]
            reached = [r["to_098"] for r in results]
            rows.append((task, setting, results, reached))
    print()
    print("| task | setting | violations (mean) | preventable (mean) | blocked actions taken "
          "(mean) | episodes to 0.98 x optimum (per seed) | exact greedy success (per seed) | "
          "optimum | train s (mean) |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|")
    for task, setting, results, reached in rows:
        shown = ", ".join("-" if r is None else f"{r:,}" for r in reached)
        exact = ", ".join(f"{r['exact']:.4f}" for r in results)
        print(
            f"| {task} | {setting} | {mean(r['violations'] for r in results):,.0f} | "
            f"{mean(r['preventable'] for r in results):,.0f} | "
            f"{mean(r['blocked'] for r in results):,.0f} | {shown} | {exact} | "
            f"{results[0]['optimum']:.4f} | {mean(r['seconds'] for r in results):.1f} |"
        )


if __name__ == "__main__":
    main()
