"""Product build and solve time for growing grid worlds, beside Storm on the same exported model.

    .venv/bin/python bench/check_bench.py [--sizes 10,20,50,100]

For an n x n grid (a in the top-right corner, b in the bottom-left, the robot starting
bottom-right, motion 0.8 / 0.1 sideways) with the task windows scaled with the size,
``(!a U[n,2n] a) & (!b U[2n,4n] b)``, it times mitlc's translation, product build and exact
solve (``pmax``), exports the product to DRN, and times Storm (stormpy: build from DRN and check
``Pmax=? [G !"violated"]``) on it in the same run. Small products are solved several times by
both and the medians compared (the ``repeats`` column). Prints one table with the values and
ratios.

    .venv/bin/python bench/check_bench.py --memory --sizes 60,100,180 [--no-storm]

measures memory instead: each size's whole check (``bench/check_one.py``) runs in a child
process whose peak resident memory (``ru_maxrss``) is read, and Storm checks the same product,
exported to DRN by another child, in a third (``bench/storm_one.py``). Prints grid, product
states, transitions, wall-clock and CPU seconds, peak MB and bytes per product state for both,
and the ratios (of wall-clock seconds and of peaks).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from statistics import median

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from mitlc.automata import translate
from mitlc.check.drn import storm_property, to_drn
from mitlc.check.solve import pmax
from mitlc.product.explicit import build_product
from mitlc.syntax import parse
from mitlc.worlds import load_world


def world_yaml(n: int) -> str:
    return f"""
name: grid-{n}
grid: {{rows: {n}, cols: {n}}}
blocked: [[{n // 2}, {n // 2}]]
labels: {{a: [[0, {n - 1}]], b: [[{n - 1}, 0]]}}
start: [{n - 1}, {n - 1}]
actions: [up, down, left, right, stay]
motion: {{intended: 0.8, sideways: 0.1}}
observation: null
spec: {{formula: "(!a U[{n},{2 * n}] a) & (!b U[{2 * n},{4 * n}] b)"}}
reward: {{satisfied: 100, accept: 100, violated: 0, move: 0}}
horizon: {4 * n + 1}
discount: 0.99
"""


def repeats_for(states: int) -> int:
    """Solves per size, so that small ones are timed by a median, not one noisy call."""
    return 21 if states < 50_000 else 5 if states < 500_000 else 3


def storm_time(drn: str, prop: str, folder: Path) -> tuple[float, float]:
    import stormpy

    path = folder / "product.drn"
    path.write_text(drn, encoding="utf-8")
    start = time.perf_counter()
    model = stormpy.build_model_from_drn(str(path))
    built = time.perf_counter()
    result = stormpy.model_checking(model, stormpy.parse_properties(prop)[0])
    value = float(result.get_value_vector()[model.initial_states[0]])
    return value, (time.perf_counter() - built, built - start)[0]


def _child(*args: str) -> list[str]:
    """The last line of a bench script run as a child process, split into fields."""
    here = Path(__file__).resolve().parent
    done = subprocess.run(
        [sys.executable, str(here / args[0]), *args[1:]],
        check=True,
        capture_output=True,
        text=True,
    )
    return done.stdout.strip().splitlines()[-1].split()


def memory_table(sizes: list[int], storm: bool) -> None:
    """Peak memory of mitlc's whole check and of Storm's, each in its own child process."""
    header = (
        f"{'grid':>7} {'states':>10} {'transitions':>11} {'mitlc s':>8} {'cpu s':>7} "
        f"{'peak MB':>8} {'B/state':>7} {'storm s':>8} {'cpu s':>7} {'storm MB':>8} "
        f"{'B/state':>7} {'s ratio':>7} {'MB ratio':>8} {'pmax':>9} {'storm pmax':>10}"
    )
    print(header)
    print("-" * len(header))
    with tempfile.TemporaryDirectory() as folder:
        for n in sizes:
            fields = _child("check_one.py", str(n))
            states, transitions, seconds, value = fields[1], fields[3], fields[4], fields[5]
            peak, cpu = fields[7], fields[8]
            row = (
                f"{n:>3}x{n:<3} {int(states):>10} {int(transitions):>11} {float(seconds):>8.1f} "
                f"{float(cpu):>7.1f} {float(peak):>8.0f} "
                f"{float(peak) * 2**20 / int(states):>7.0f}"
            )
            if storm:
                drn = str(Path(folder) / "product.drn")
                _child("storm_one.py", "write", str(n), drn)
                theirs_fields = _child("storm_one.py", "check", drn)
                Path(drn).unlink()
                build, solve, theirs, storm_peak, storm_cpu = theirs_fields[2:7]
                storm_s = max(float(build) + float(solve), 1e-3)
                row += (
                    f" {storm_s:>8.1f} {float(storm_cpu):>7.1f} {float(storm_peak):>8.0f} "
                    f"{float(storm_peak) * 2**20 / int(states):>7.0f} "
                    f"{float(seconds) / storm_s:>7.2f} {float(peak) / float(storm_peak):>8.2f} "
                    f"{float(value):>9.6f} {float(theirs):>10.6f}"
                )
            else:
                row += (
                    f" {'-':>8} {'-':>7} {'-':>8} {'-':>7} {'-':>7} {'-':>8} {float(value):>9.6f}"
                )
            print(row, flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="10,20,50,100")
    parser.add_argument("--memory", action="store_true", help="peak memory, child processes")
    parser.add_argument("--no-storm", action="store_true", help="--memory without Storm")
    args = parser.parse_args()
    if args.memory:
        memory_table([int(x) for x in args.sizes.split(",")], not args.no_storm)
        return
    header = (
        f"{'grid':>7} {'states':>9} {'choices':>9} {'build s':>8} {'solve s':>8} "
        f"{'pmax':>9} {'storm s':>8} {'storm pmax':>10} {'solve/storm':>11} {'repeats':>7}"
    )
    print(header)
    print("-" * len(header))
    with tempfile.TemporaryDirectory() as folder:
        for n in (int(x) for x in args.sizes.split(",")):
            path = Path(folder) / f"grid{n}.yaml"
            path.write_text(world_yaml(n), encoding="utf-8")
            world = load_world(path)
            automaton = translate(parse(world.spec))
            start = time.perf_counter()
            product = build_product(world, automaton)
            build_seconds = time.perf_counter() - start
            repeats = repeats_for(product.num_states)
            solves = []
            for _ in range(repeats):
                start = time.perf_counter()
                solution = pmax(product)
                solves.append(time.perf_counter() - start)
            mine = float(solution.values[product.initial])
            drn, prop = to_drn(product), storm_property(product)
            runs = [storm_time(drn, prop, Path(folder)) for _ in range(repeats)]
            theirs = runs[0][0]
            solve, storm_seconds = median(solves), median([r[1] for r in runs])
            print(
                f"{n:>3}x{n:<3} {product.num_states:>9} {product.num_choices:>9} "
                f"{build_seconds:>8.2f} {solve:>8.4f} {mine:>9.6f} "
                f"{storm_seconds:>8.4f} {theirs:>10.6f} {solve / storm_seconds:>11.2f} "
                f"{repeats:>7}",
                flush=True,
            )


if __name__ == "__main__":
    main()
