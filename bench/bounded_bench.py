"""Bounded work (issue 11): compile time against the states built, and how soon a runaway
formula is stopped.

    .venv/bin/python bench/bounded_bench.py [--ks 1000,10000,100000] [--all-families]
                                            [--no-runaway]

For ``F[0,k] a`` (and with ``--all-families`` ``G(a -> F[0,k] b)`` and
``(!a U[k,2k] a) & (!b U[3k,4k] b)``) it prints k, the digital states, the locations, the
seconds of ``compile_formula`` plus the JSON artifact (what ``mitlc compile`` does after
parsing), the microseconds per digital state and their ratio to the first row's (1.0 is
linear). Then the whole process ``mitlc compile -e 'F[0,k] a'`` for the largest k (imports
included, CPU seconds from the operating system), and the seconds until ``mitlc compile -e
'F[0,1000] G[0,1000] a'`` is refused at the default limits.
"""

from __future__ import annotations

import argparse
import resource
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from mitlc.automata import compile_formula
from mitlc.automata.artifact import to_json
from mitlc.limits import DEFAULT_TIME_LIMIT
from mitlc.syntax import parse

FAMILIES: dict[str, Callable[[int], str]] = {
    "F[0,k] a": lambda k: f"F[0,{k}] a",
    "G(a -> F[0,k] b)": lambda k: f"G(a -> F[0,{k}] b)",
    "(!a U[k,2k] a) & (!b U[3k,4k] b)": lambda k: (
        f"(!a U[{k},{2 * k}] a) & (!b U[{3 * k},{4 * k}] b)"
    ),
}
RUNAWAY = "F[0,1000] G[0,1000] a"
MITLC = Path(sys.executable).parent / "mitlc"


def compile_row(text: str) -> tuple[int, int, float]:
    """Digital states, locations and seconds of compiling ``text`` and writing its JSON."""
    formula = parse(text)
    start = time.perf_counter()
    compiled = compile_formula(formula)
    to_json(compiled.timed)
    seconds = time.perf_counter() - start
    return len(compiled.digital.states), len(compiled.timed.locations), seconds


def process(args: list[str]) -> tuple[int, float, float, str]:
    """Exit status, wall and CPU seconds of ``mitlc ARGS``, and the last line of its stderr."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run([str(MITLC), *args], capture_output=True, text=True, check=False)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    last = (done.stderr.strip().splitlines() or [""])[-1]
    return done.returncode, wall, cpu, last


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ks", default="1000,10000,100000")
    parser.add_argument("--all-families", action="store_true")
    parser.add_argument("--no-runaway", action="store_true")
    options = parser.parse_args()
    ks = [int(k) for k in options.ks.split(",")]
    families = list(FAMILIES) if options.all_families else ["F[0,k] a"]
    print("| family | k | digital states | locations | seconds | us/state | ratio |")
    print("|---|---|---|---|---|---|---|")
    for family in families:
        first: float | None = None
        for k in ks:
            states, locations, seconds = compile_row(FAMILIES[family](k))
            per_state = seconds / states * 1e6
            first = per_state if first is None else first
            print(
                f"| `{family}` | {k} | {states} | {locations} | {seconds:.3f} | "
                f"{per_state:.1f} | {per_state / first:.2f} |",
                flush=True,
            )
    top = FAMILIES["F[0,k] a"](max(ks))
    status, wall, cpu, _ = process(["compile", "-e", top, "-o", "/dev/null"])
    print(f"\nmitlc compile -e '{top}': exit {status}, {wall:.2f} s wall, {cpu:.2f} s CPU")
    if not options.no_runaway:
        status, wall, cpu, last = process(["compile", "-e", RUNAWAY, "-o", "/dev/null"])
        print(
            f"mitlc compile -e '{RUNAWAY}' (default limits, time {DEFAULT_TIME_LIMIT:g} s): "
            f"exit {status} after {wall:.1f} s wall, {cpu:.1f} s CPU\n  {last}"
        )


if __name__ == "__main__":
    main()
