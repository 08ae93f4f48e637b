"""Compile time and sizes of mitlc beside Spot's translation of the unrolled formula.

    .venv/bin/python bench/compile_bench.py [--ks 5,10,20,40,100,1000] [--spot-timeout 60]

For each family and bound k, mitlc compiles the formula (translation to the digital automaton
and folding into the T-LDGBA, in this process), and Spot translates the same formula with every
bounded operator unrolled into X (``spot.translate``, its default: a small TGBA, completed with
a sink as mitlc's are, for the size comparison), in a child
process killed after ``--spot-timeout`` seconds; an unrolled text of more than a billion
characters counts as a timeout without being built. Once Spot times out on a family, larger k
are not tried. Prints one table: times, sizes, and the ratios Spot/mitlc.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from mitlc.automata import TranslationError, compile_formula
from mitlc.syntax import parse
from mitlc.syntax.spot import to_spot, unrolled_size

FAMILIES: dict[str, Callable[[int], str]] = {
    "F[0,k] a": lambda k: f"F[0,{k}] a",
    "G(a -> F[0,k] b)": lambda k: f"G (a -> F[0,{k}] b)",
    "G(a -> F[k/2,k] b)": lambda k: f"G (a -> F[{k // 2},{k}] b)",
    "(!a U[k,2k] a) & (!b U[3k,4k] b)": lambda k: (
        f"(!a U[{k},{2 * k}] a) & (!b U[{3 * k},{4 * k}] b)"
    ),
}
MITLC_MAX_STATES = 200_000
SPOT_MAX_TEXT = 1_000_000_000
"""Unrolled formulas longer than this (characters) are not given to Spot."""

SPOT_CHILD = """
import json, sys, time, spot
text = sys.stdin.read()
start = time.perf_counter()
aut = spot.translate(text)
seconds = time.perf_counter() - start
aut = spot.complete(aut)  # mitlc's automata are complete: count Spot's rejecting sink too
print(json.dumps({"seconds": seconds, "states": aut.num_states(),
                  "deterministic": bool(spot.is_deterministic(aut))}))
"""


def run_mitlc(text: str) -> dict[str, object]:
    start = time.perf_counter()
    try:
        compiled = compile_formula(parse(text), max_states=MITLC_MAX_STATES)
    except TranslationError:
        return {"seconds": time.perf_counter() - start, "states": None}
    return {
        "seconds": time.perf_counter() - start,
        "states": len(compiled.digital.states),
        "locations": len(compiled.timed.locations),
        "clocks": len(compiled.timed.clock_bounds),
    }


def run_child(argv: list[str], stdin: str, timeout: float) -> dict[str, Any] | None:
    """The JSON a child process prints for ``stdin``; ``None`` when killed at ``timeout``."""
    try:
        proc = subprocess.run(
            argv, input=stdin, capture_output=True, text=True, timeout=timeout, check=True
        )
    except subprocess.TimeoutExpired:
        return None
    result: dict[str, Any] = json.loads(proc.stdout)
    return result


def run_spot(text: str, timeout: float) -> dict[str, Any] | None:
    if unrolled_size(parse(text)) > SPOT_MAX_TEXT:
        return None
    return run_child([sys.executable, "-c", SPOT_CHILD], to_spot(parse(text)), timeout)


def _cell(value: object, fmt: str = "{}") -> str:
    return "-" if value is None else fmt.format(value)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ks", default="5,10,20,40,100,1000")
    parser.add_argument("--spot-timeout", type=float, default=60.0)
    args = parser.parse_args()
    ks = [int(k) for k in args.ks.split(",")]
    header = (
        f"{'family':34} {'k':>5} {'mitlc s':>9} {'digital':>8} {'locs':>5} {'clocks':>6} "
        f"{'spot s':>9} {'spot st':>8} {'time x':>8} {'size x':>7}"
    )
    print(header)
    print("-" * len(header))
    for family, make in FAMILIES.items():
        spot_done = True
        for k in ks:
            text = make(k)
            mine = run_mitlc(text)
            theirs = run_spot(text, args.spot_timeout) if spot_done else None
            if theirs is None:
                spot_done = False
            states = mine["states"]
            time_ratio = size_ratio = None
            if theirs is not None:
                time_ratio = f"{float(theirs['seconds']) / max(float(mine['seconds']), 1e-9):.1f}"  # type: ignore[arg-type]
                if states is not None:
                    size_ratio = f"{int(theirs['states']) / int(states):.2f}"  # type: ignore[call-overload]
            spot_time = None if theirs is None else f"{theirs['seconds']:.3f}"
            spot_states = "timeout" if theirs is None and spot_done is False else None
            if theirs is not None:
                spot_states = str(theirs["states"])
            print(
                f"{family:34} {k:>5} {mine['seconds']:>9.3f} "
                f"{_cell(states if states is not None else f'>{MITLC_MAX_STATES}'):>8} "
                f"{_cell(mine.get('locations')):>5} {_cell(mine.get('clocks')):>6} "
                f"{_cell(spot_time):>9} {_cell(spot_states):>8} {_cell(time_ratio):>8} "
                f"{_cell(size_ratio):>7}",
                flush=True,
            )


if __name__ == "__main__":
    main()
