"""When a run first succeeds, with and without counterfactual experience: many short
``mitlc train`` runs of one world at once (one core each), each stopped at a wall-clock limit,
then a table of the env steps at which a training window first held a success and the
training success of the last window, per setting and seed. For the question of
``docs/deadlines.md`` (counterfactuals on PointMaze), on a machine with many cores.

    python bench/crm_probe.py specs/envs/pointmaze.yaml --seeds 0,1,2,3 --steps 60000 \\
        --wall 380 --arm none=sb3.crm=false --arm crm=sb3.crm=true \\
        --arm share=sb3.crm=true,sb3.crm_share=0.5 --out build/crm-probe
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from mitlc.learn.rundir.files import read_metrics_rows


def first_success(metrics: Path) -> tuple[int | None, int, float]:
    """The steps of the first window with a success (None: none), the steps reached and the
    last window's training success (the run's ``metrics.jsonl``, read as mitlc reads it)."""
    first, steps, last = None, 0, 0.0
    if not metrics.is_file():
        return first, steps, last
    for row in read_metrics_rows(metrics):
        steps, last = int(row["steps"]), float(row["success_rate"])
        if first is None and last > 0:
            first = steps
    return first, steps, last


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("world")
    parser.add_argument("--seeds", default="0,1,2,3")
    parser.add_argument("--steps", type=int, default=60_000)
    parser.add_argument("--wall", type=float, default=380.0, help="seconds each run may take")
    parser.add_argument("--arm", action="append", required=True, help="NAME=SETTING,SETTING")
    parser.add_argument("--out", type=Path, default=Path("build/crm-probe"))
    args = parser.parse_args()
    seeds = [int(s) for s in args.seeds.split(",")]
    arms = dict(arm.split("=", 1) for arm in args.arm)
    env = {**os.environ, "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    runs: dict[tuple[str, int], subprocess.Popen[bytes]] = {}
    for name, settings in arms.items():
        for seed in seeds:
            out = args.out / f"{name}-s{seed}"
            sets = [x for s in settings.split(",") for x in ("--set", s)]
            line = [sys.executable, "-m", "mitlc", "train", args.world, "--seed", str(seed),
                    "--set", f"sb3.steps={args.steps}", *sets, "--out", str(out),
                    "--quiet", "--no-eval", "--device", "cpu"]  # fmt: skip
            runs[(name, seed)] = subprocess.Popen(line, env=env, stderr=subprocess.DEVNULL)
    start = time.monotonic()
    while any(p.poll() is None for p in runs.values()):
        if time.monotonic() - start > args.wall:
            for p in runs.values():
                if p.poll() is None:
                    p.send_signal(signal.SIGINT)  # mitlc train checkpoints and logs, then stops
            break
        time.sleep(2)
    for p in runs.values():
        try:
            p.wait(timeout=60)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()
    print(f"{args.world}: {len(runs)} runs at once, {args.wall:.0f} s each at most")
    print("| arm | settings | seed | first success (steps) | steps reached | last window |")
    print("|---|---|---|---|---|---|")
    for (name, seed), _ in sorted(runs.items()):
        first, steps, last = first_success(args.out / f"{name}-s{seed}" / "metrics.jsonl")
        shown = f"{first:,}" if first is not None else f"none in {steps:,}"
        print(f"| {name} | {arms[name]} | {seed} | {shown} | {steps:,} | {last:.2f} |")


if __name__ == "__main__":
    main()
