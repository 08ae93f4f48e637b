"""Teams of robots (issue 43): the exact joint optimum, its time and memory, beside Storm on the
same joint product, and the learners beside the optimum.

    .venv/bin/python bench/teams_bench.py --out build/bench-teams      # make bench-teams

Rows (each measured in this run; every figure printed is one this script computed):

* ``two-robots``: ``specs/teams/two-robots.yaml`` (the paper's 5x5 grid, two robots, a coupled
  task). mitlc's exact ``pmax_horizon`` (product build included) and ``pmax``, and Storm's
  ``Pmax`` of the same product read from DRN (build and check), side by side; then tabular
  learners of the team's task on the same budget (300,000 episodes): independent Q (a table per
  robot, ``team: independent``) and joint Q (one table over the joint state and action), each
  with its exact success and ratio to the optimum and its training seconds.
* ``two-robots-noisy``: robot_1 with the paper's noisy sensor. The independent learners' success
  (Monte Carlo) beside the joint MDP optimum (an upper bound) and the observation-based bound
  (``pmax_horizon_observed``, a lower bound on the best observation-based joint policy).
* ``scale``: three robots on a 10x10 depot with three deadlines, and four robots on 3x5
  (``bench/worlds/``): robots x cells x automaton states, the product, seconds and peak memory.
* ``warehouse``: ``specs/teams/warehouse.yaml``, three robots on an 8x8 grid. The exact optimum
  in a child process (its time and peak memory, ``ru_maxrss``), and independent Q under the
  per-robot shield with theta = 1 (its exact success, and the preventable violations and
  blocked actions of its training).

Results go to ``OUT/results.json`` and a table on stdout. A learning run finished in an earlier
sitting (its ``summary.json`` in ``OUT/runs``) is evaluated again, not trained again: delete
``OUT/runs`` for fresh runs.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

TEAMS = ROOT / "specs" / "teams"
EPISODES = 300_000
SCALE = ("depot-10x10", "four-robots")
"""The scale rows: three robots on a 10x10 depot with three deadlines, and four robots on
3x5 (near the joint-table limit), in ``bench/worlds/``."""


def exact_two_robots(world_path: Path) -> dict[str, Any]:
    """mitlc's exact figures and Storm's on the same product."""
    import stormpy

    from mitlc.automata import translate
    from mitlc.check.drn import storm_property, to_drn
    from mitlc.check.solve import pmax, pmax_horizon
    from mitlc.product.explicit import build_product
    from mitlc.syntax import parse
    from mitlc.worlds.door import load_world

    started = time.perf_counter()
    world = load_world(world_path)
    product = build_product(world, translate(parse(world.spec)))
    built = time.perf_counter()
    within, _ = pmax_horizon(product, world.horizon)
    horizon_done = time.perf_counter()
    infinite = float(pmax(product).values[product.initial])
    infinite_done = time.perf_counter()
    with tempfile.TemporaryDirectory() as folder:
        drn = Path(folder) / "product.drn"
        drn.write_text(to_drn(product), encoding="utf-8")
        storm_started = time.perf_counter()
        model = stormpy.build_model_from_drn(str(drn))
        prop = stormpy.parse_properties(storm_property(product))[0]
        result = stormpy.model_checking(model, prop)
        storm = float(result.get_value_vector()[model.initial_states[0]])
        storm_done = time.perf_counter()
    return {
        "product_states": product.num_states,
        "product_choices": product.num_choices,
        "pmax_horizon": float(within),
        "pmax": infinite,
        "seconds_build": built - started,
        "seconds_pmax_horizon": horizon_done - built,
        "seconds_exact": horizon_done - started,
        "seconds_pmax": infinite_done - horizon_done,
        "storm_pmax": storm,
        "storm_seconds": storm_done - storm_started,
    }


def learn(world_path: Path, out: Path, overrides: dict[str, Any]) -> dict[str, Any]:
    """Train with ``overrides`` and evaluate: exact success (where memoryless on an MDP), its
    Monte-Carlo estimate, the optimum, and the run's seconds and shield tallies."""
    from mitlc.learn.config import config_for
    from mitlc.learn.evaluation.evaluate import evaluate
    from mitlc.learn.run import train
    from mitlc.worlds.door import open_world

    world = open_world(world_path)
    config, _ = config_for(world, overrides)
    if (out / "summary.json").is_file():  # finished in an earlier sitting: evaluated again
        seconds = json.loads((out / "summary.json").read_text())["seconds"]
        episodes = json.loads((out / "summary.json").read_text())["episodes"]
    else:
        _fresh(out)
        result = train(world_path, config, out, world=world)
        seconds, episodes = result.seconds, result.episodes
    evaluation = evaluate(out, episodes=10_000)
    rows = [json.loads(x) for x in (out / "metrics.jsonl").read_text().splitlines()]
    learned = evaluation.exact if evaluation.exact is not None else evaluation.success_rate
    return {
        "episodes": episodes,
        "seconds_train": seconds,
        "exact": evaluation.exact,
        "monte_carlo": evaluation.success_rate,
        "optimum": evaluation.optimum,
        "ratio": learned / evaluation.optimum if evaluation.optimum else None,
        "observed_bound": evaluation.lower,
        "blocked_actions": sum(r.get("blocked_actions", 0) for r in rows),
        "preventable_violations": sum(r.get("preventable_violations", 0) for r in rows),
    }


CHILD = """
import json, resource, sys, time
from mitlc.automata import LazyAutomaton
from mitlc.check.solve import pmax_horizon
from mitlc.product.explicit import build_product
from mitlc.syntax import parse
from mitlc.worlds.door import load_world
started = time.perf_counter()
world = load_world(sys.argv[1])
automaton = LazyAutomaton(parse(world.spec))  # as mitlc check: the states the world reaches
product = build_product(world, automaton, max_product_states=None, time_limit=None,
                        memory_limit=16.0)
value, _ = pmax_horizon(product, world.horizon)
print(json.dumps({"pmax_horizon": float(value), "seconds_exact": time.perf_counter() - started,
                  "product_states": product.num_states, "product_choices": product.num_choices,
                  "joint_states": world.num_states, "robots": world.team.num_robots,
                  "free_cells": len(world.team.cells), "automaton_states": automaton.num_states,
                  "peak_gb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6}))
"""


def exact_in_child(world_path: Path) -> dict[str, Any]:
    """The exact optimum in a fresh process: its figures, seconds and peak memory."""
    done = subprocess.run(
        [sys.executable, "-c", CHILD, str(world_path)], capture_output=True, text=True, cwd=ROOT
    )
    if done.returncode:
        raise RuntimeError(f"the exact check of {world_path} failed:\n{done.stderr}")
    found: dict[str, Any] = json.loads(done.stdout.strip().splitlines()[-1])
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "build" / "bench-teams")
    parser.add_argument("--episodes", type=int, default=EPISODES)
    args = parser.parse_args()
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    results: dict[str, Any] = {"date": time.strftime("%Y-%m-%d"), "episodes": args.episodes}
    two = TEAMS / "two-robots.yaml"
    results["two_robots_exact"] = exact_two_robots(two)
    runs = out / "runs"
    budget = {"episodes": args.episodes, "seed": 0}
    for name, extra in (("independent", {"team": "independent"}), ("joint", {"team": "joint"})):
        where = runs / f"two-robots-{name}"
        results[f"two_robots_{name}_q"] = learn(two, where, {**budget, **extra})
    noisy = runs / "two-robots-noisy-independent"
    results["two_robots_noisy_independent_q"] = learn(
        TEAMS / "two-robots-noisy.yaml", noisy, {**budget, "team": "independent", "algo": "q"}
    )
    results["warehouse_exact"] = exact_in_child(TEAMS / "warehouse.yaml")
    for name in SCALE:
        results[f"scale_{name}"] = exact_in_child(ROOT / "bench" / "worlds" / f"{name}.yaml")
    shielded = runs / "warehouse-independent-shield"
    results["warehouse_independent_q_shield"] = learn(
        TEAMS / "warehouse.yaml", shielded, {**budget, "team": "independent", "shield": 1.0}
    )
    (out / "results.json").write_text(json.dumps(results, indent=2) + "\n", encoding="utf-8")
    print(table(results))
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6
    print(f"\n(this process's peak memory: {peak:.1f} GB; results in {out / 'results.json'})")


def _fresh(directory: Path) -> None:
    import shutil

    if directory.exists():
        shutil.rmtree(directory)


def table(r: dict[str, Any]) -> str:
    """The results as a plain table."""
    e, w = r["two_robots_exact"], r["warehouse_exact"]
    lines = [
        f"{'measure':62s} {'value':>14s}",
        f"{'two-robots: product states / choices':62s} "
        f"{e['product_states']:>6,} / {e['product_choices']:,}",
        f"{'two-robots: pmax_horizon (exact joint optimum)':62s} {e['pmax_horizon']:>14.6f}",
        f"{'  seconds (product build + pmax_horizon)':62s} {e['seconds_exact']:>14.2f}",
        f"{'two-robots: pmax, mitlc (s) | Storm from DRN (s)':62s} "
        f"{e['pmax']:.6f} ({e['seconds_pmax']:.2f}) | {e['storm_pmax']:.6f} "
        f"({e['storm_seconds']:.2f})",
    ]
    for key, label in (
        ("two_robots_independent_q", "two-robots: independent Q (exact, ratio, train s)"),
        ("two_robots_joint_q", "two-robots: joint Q (exact, ratio, train s)"),
    ):
        x = r[key]
        lines.append(f"{label:62s} {x['exact']:.4f} {x['ratio']:.4f} {x['seconds_train']:.1f}")
    n = r["two_robots_noisy_independent_q"]
    lower = "n/a" if n["observed_bound"] is None else f"{n['observed_bound']:.4f}"
    lines.append(
        f"{'two-robots-noisy: independent Q (MC) | MDP optimum | observed bound':62s} "
        f"{n['monte_carlo']:.4f} | {n['optimum']:.4f} | {lower}"
    )
    lines += [
        f"{'warehouse: robots x free cells x automaton states':62s} "
        f"{w['robots']} x {w['free_cells']} x {w['automaton_states']}",
        f"{'warehouse: joint states / product states':62s} "
        f"{w['joint_states']:,} / {w['product_states']:,}",
        f"{'warehouse: pmax_horizon, seconds, peak GB':62s} "
        f"{w['pmax_horizon']:.6f} {w['seconds_exact']:.1f} {w['peak_gb']:.1f}",
    ]
    for name in SCALE:
        x = r[f"scale_{name}"]
        lines.append(
            f"{'scale ' + name + ': robots x cells x automaton states':62s} "
            f"{x['robots']} x {x['free_cells']} x {x['automaton_states']}"
        )
        lines.append(
            f"{'  product states, pmax_horizon, seconds, peak GB':62s} "
            f"{x['product_states']:,} {x['pmax_horizon']:.6f} {x['seconds_exact']:.1f} "
            f"{x['peak_gb']:.1f}"
        )
    s = r["warehouse_independent_q_shield"]
    lines.append(
        f"{'warehouse: independent Q + shield 1 (exact, ratio, train s)':62s} "
        f"{s['exact']:.4f} {s['ratio']:.4f} {s['seconds_train']:.1f}"
    )
    lines.append(
        f"{'warehouse: preventable violations / blocked actions (training)':62s} "
        f"{s['preventable_violations']} / {s['blocked_actions']}"
    )
    return "\n".join(lines)


if __name__ == "__main__":
    main()
