"""Sweeps at scale: the same trials on Ray on this machine's cores, one after another in one
process, and on a two-node Ray cluster started here (``ray.cluster_utils.Cluster``), in one run.

The trials: ``--seeds-q`` seeds of case 1 with tabular Q-learning and ``--seeds-drqn`` seeds of
case 3 (the office POMDP) with the recurrent DQN, each with its world file's settings (case 3's
budget can be cut with ``--drqn-episodes``), each trained and evaluated as ``mitlc sweep`` does
(:func:`mitlc.sweep.trial.run_trial`). Printed: wall time of each way and the speed-up over
the sequential run, and that the results agree trial by trial (the same final figures: every
trial is seeded).

    .venv/bin/python bench/sweep_bench.py [--seeds-q 20] [--seeds-drqn 10]
        [--drqn-episodes 40000] [--skip-cluster]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from mitlc.sweep.ray_run import run_sweep  # noqa: E402
from mitlc.sweep.spec import load_sweep  # noqa: E402
from mitlc.sweep.trial import run_trial  # noqa: E402

KEYS = ("success_rate", "exact", "train_episodes", "train_steps")
BUSY = "s = 0\nfor i in range(30_000_000):\n    s += i\n"


def ceiling(cores: int, tries: int = 5) -> float:
    """The machine's own parallel speed-up: ``cores`` plain CPU-bound Python processes at
    once beside one after another, the median of ``tries`` interleaved pairs (a shared or
    throttled host gives less than ``cores``)."""
    import statistics
    import subprocess

    ratios = []
    for _ in range(tries):
        start = time.perf_counter()
        subprocess.run([sys.executable, "-c", BUSY], check=True)
        one = time.perf_counter() - start
        start = time.perf_counter()
        running = [subprocess.Popen([sys.executable, "-c", BUSY]) for _ in range(cores)]
        for process in running:
            process.wait()
        ratios.append(cores * one / (time.perf_counter() - start))
    return statistics.median(ratios)


def sweep_file(folder: Path, seeds_q: int, seeds_drqn: int, drqn_episodes: int) -> Path:
    """Two sweeps in one file is not a thing: write two and return the folder's q sweep."""
    case1, case3 = ROOT / "specs/paper/case1.yaml", ROOT / "specs/paper/case3-office.yaml"
    (folder / "q.yaml").write_text(
        f"name: bench-q\nworlds: [{case1}]\nlearners: {{q: {{algo: q}}}}\n"
        f"seeds: {seeds_q}\neval_episodes: 10000\n"
    )
    (folder / "drqn.yaml").write_text(
        f"name: bench-drqn\nworlds: [{case3}]\nlearners: {{drqn: {{algo: drqn}}}}\n"
        f"seeds: {seeds_drqn}\nepisodes: {drqn_episodes}\neval_episodes: 10000\n"
    )
    return folder


def timed_ray(
    folder: Path, out: Path, address: str | None = None
) -> tuple[float, dict[str, dict[str, object]]]:
    """Both sweeps on one Ray session (started here, or the cluster at ``address``): its
    start-up counts."""
    import ray

    start = time.perf_counter()
    ray.init(address=address, include_dashboard=False, log_to_driver=False)
    results = {}
    try:
        for name in ("q.yaml", "drqn.yaml"):
            done = run_sweep(load_sweep(folder / name), out / name)
            assert not done.failed, done.failed
            results.update({r["trial_id"]: r for r in done.results})
    finally:
        ray.shutdown()
    return time.perf_counter() - start, results


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds-q", type=int, default=20)
    parser.add_argument("--seeds-drqn", type=int, default=10)
    parser.add_argument("--drqn-episodes", type=int, default=40_000)
    parser.add_argument("--skip-cluster", action="store_true")
    parser.add_argument("--ceiling-only", action="store_true", help="only the machine's own")
    args = parser.parse_args()
    import os

    cores = os.cpu_count() or 1
    limit = ceiling(cores)
    print(
        f"this machine: {cores} plain CPU-bound processes at once run {limit:.2f}x as fast as "
        "one after another (median of 5 tries; the ceiling of any parallel speed-up here)\n"
    )
    if args.ceiling_only:
        return
    with tempfile.TemporaryDirectory() as scratch:
        base = sweep_file(Path(scratch), args.seeds_q, args.seeds_drqn, args.drqn_episodes)
        trials = [t for n in ("q.yaml", "drqn.yaml") for t in load_sweep(base / n).trials]
        start = time.perf_counter()
        sequential = {t.trial_id: run_trial(t, base / "sequential") for t in trials}
        rows = [("one after another, one process", time.perf_counter() - start, sequential)]
        seconds, local = timed_ray(base, base / "ray-local")
        rows.append((f"Ray on this machine ({cores} cores)", seconds, local))
        if not args.skip_cluster:
            import ray
            from ray.cluster_utils import Cluster

            half = max(cores // 2, 1)
            cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": half})
            cluster.add_node(num_cpus=max(cores - half, 1))
            cluster.wait_for_nodes()
            try:
                seconds, clustered = timed_ray(base, base / "ray-cluster", cluster.address)
                ray.init(address=cluster.address, include_dashboard=False, log_to_driver=False)
                nodes = len([n for n in ray.nodes() if n["Alive"]])
                ray.shutdown()
            finally:
                cluster.shutdown()
            rows.append((f"Ray cluster of {nodes} nodes (ray.cluster_utils)", seconds, clustered))
    base_seconds = rows[0][1]
    print(f"{args.seeds_q} seeds of case 1 (tabular Q, its file's settings) and "
          f"{args.seeds_drqn} seeds of case 3 (recurrent DQN, {args.drqn_episodes:,} episodes); "
          f"10,000 greedy evaluation episodes each\n")  # fmt: skip
    print(f"{'how':<48} {'wall s':>8} {'speed-up':>9} {'same results':>13}")
    for name, seconds, results in rows:
        same = all(
            {k: results[i][k] for k in KEYS} == {k: sequential[i][k] for k in KEYS}
            for i in sequential
        )
        print(f"{name:<48} {seconds:>8.1f} {base_seconds / seconds:>8.2f}x {same!s:>13}")
    q = [r["score"] for r in sequential.values() if r["algo"] == "q"]
    d = [r["score"] for r in sequential.values() if r["algo"] == "drqn"]
    print(
        f"\nmean score: case 1 tabular {sum(q) / len(q):.4f} (success / optimum), "
        f"case 3 recurrent DQN {sum(d) / len(d):.4f} (success / fully observable bound)"
    )
    print(json.dumps({"cores": cores}))


if __name__ == "__main__":
    main()
