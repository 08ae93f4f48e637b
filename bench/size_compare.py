"""mitlc's automaton beside Spot's deterministic one, formula by formula, in one run.

    .venv/bin/python bench/size_compare.py [--ks 3,5,8,10] [--spot-timeout 60] [--json FILE]

For every formula of ``bench/formulas.txt`` and of the nested-deadline families (:data:`FAMILIES`
at each ``--ks``), mitlc compiles the formula (digital states, T-LDGBA locations and clocks,
whether it is deterministic or limit-deterministic) and Spot translates the same formula with
every bounded operator unrolled into ``X``, as issue 25 asks: ``spot.translate(f,
"deterministic", "complete")`` (transition-based generalized Büchi where Spot finds a
deterministic one, completed with a sink as mitlc's automata are), in a child process killed
after ``--spot-timeout`` seconds. A formula is *larger* when mitlc has more states than Spot's
automaton; it is *excused* when mitlc's is limit-deterministic and Spot's is deterministic of
another acceptance type or not deterministic at all (both sizes are listed, with the size of
Spot's deterministic parity automaton, ``translate(f, "deterministic", "parity", "complete")``).
Prints one table and a summary line; exits 1 when a formula is larger and not excused.
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

from mitlc.automata import compile_formula
from mitlc.syntax import parse
from mitlc.syntax.spot import to_spot, unrolled_size

ROOT = Path(__file__).resolve().parents[1]

FAMILIES: dict[str, Callable[[int], str]] = {
    "F[0,k] (a & F[0,k] b)": lambda k: f"F[0,{k}] (a & F[0,{k}] b)",
    "G (a -> F[0,k] (b & F[0,k] c))": lambda k: f"G (a -> F[0,{k}] (b & F[0,{k}] c))",
    "F[0,k] (a & X F[0,k] (b & X F[0,k] c))": lambda k: (
        f"F[0,{k}] (a & X F[0,{k}] (b & X F[0,{k}] c))"
    ),
    "F[0,k] G[0,k] a": lambda k: f"F[0,{k}] G[0,{k}] a",
    "G F[0,k] a | F G b": lambda k: f"G F[0,{k}] a | F G b",
}
SPOT_MAX_TEXT = 50_000_000

SPOT_CHILD = """
import json, sys, time, spot
text = sys.stdin.read()
start = time.perf_counter()
aut = spot.translate(text, "deterministic", "complete")
seconds = time.perf_counter() - start
found = {"seconds": seconds, "states": aut.num_states(),
         "deterministic": bool(spot.is_deterministic(aut)),
         "acceptance": aut.acc().name(),
         "gba": bool(aut.acc().is_t() or aut.acc().is_buchi()
                     or aut.acc().is_generalized_buchi())}
if not (found["deterministic"] and found["gba"]):  # no deterministic TGBA: Spot's parity one
    parity = spot.translate(text, "deterministic", "parity", "complete")
    found["parity_states"] = parity.num_states()
    found["parity_acceptance"] = parity.acc().name()
print(json.dumps(found))
"""


def formulas(ks: list[int]) -> list[str]:
    """The file's formulas, then the families at each bound."""
    lines = (ROOT / "bench" / "formulas.txt").read_text(encoding="utf-8").splitlines()
    found = [line.strip() for line in lines if line.strip() and not line.startswith("#")]
    for make in FAMILIES.values():
        found += [make(k) for k in ks if make(k) not in found]
    return found


def run_mitlc(text: str) -> dict[str, Any]:
    """Digital states, locations, clocks and the kind of mitlc's automaton (and its time)."""
    start = time.perf_counter()
    compiled = compile_formula(parse(text), time_limit=None)
    digital = compiled.digital
    limit = any(state.component == "accepting" for state in digital.states)
    return {
        "seconds": time.perf_counter() - start,
        "states": len(digital.states),
        "locations": len(compiled.timed.locations),
        "clocks": len(compiled.timed.clock_bounds),
        "kind": "LDGBA" if limit else "DGBA",
    }


def run_spot(text: str, timeout: float) -> dict[str, Any] | None:
    """Spot's deterministic complete automaton of the unrolled formula (None: timed out)."""
    if unrolled_size(parse(text)) > SPOT_MAX_TEXT:
        return None
    try:
        proc = subprocess.run(
            [sys.executable, "-c", SPOT_CHILD], input=to_spot(parse(text)),
            capture_output=True, text=True, timeout=timeout, check=True,
        )  # fmt: skip
    except subprocess.TimeoutExpired:
        return None
    result: dict[str, Any] = json.loads(proc.stdout)
    return result


def verdict(mine: dict[str, Any], theirs: dict[str, Any] | None) -> str:
    """``ok`` (no larger), ``larger`` or ``excused`` (see the module docstring), ``-``."""
    if theirs is None:
        return "-"
    if mine["states"] <= theirs["states"]:
        return "ok"
    spot_gba = theirs["deterministic"] and theirs["gba"]
    if mine["kind"] == "LDGBA" and not spot_gba:
        return "excused"
    return "larger"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ks", default="3,5,8,10")
    parser.add_argument("--spot-timeout", type=float, default=60.0)
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args()
    rows = []
    print("| formula | mitlc states | locations | clocks | kind | mitlc s | Spot states | "
          "Spot acceptance | Spot s | |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|---|")
    for text in formulas([int(k) for k in args.ks.split(",")]):
        mine = run_mitlc(text)
        theirs = run_spot(text, args.spot_timeout)
        mark = verdict(mine, theirs)
        rows.append({"formula": text, "mitlc": mine, "spot": theirs, "verdict": mark})
        spot = ("timeout", "-", "-") if theirs is None else (
            str(theirs["states"]),
            theirs["acceptance"] + ("" if theirs["deterministic"] else " (nondet.)")
            + (f"; deterministic {theirs['parity_acceptance']}: {theirs['parity_states']}"
               if "parity_states" in theirs else ""),
            f"{theirs['seconds']:.3f}",
        )  # fmt: skip
        shown = text.replace("|", "\\|")
        print(f"| `{shown}` | {mine['states']} | {mine['locations']} | {mine['clocks']} | "
              f"{mine['kind']} | {mine['seconds']:.3f} | {spot[0]} | {spot[1]} | {spot[2]} | "
              f"{'' if mark == 'ok' else mark} |", flush=True)  # fmt: skip
    counts = {m: sum(r["verdict"] == m for r in rows) for m in ("ok", "larger", "excused", "-")}
    print(f"\n{len(rows)} formulas: {counts['ok']} no larger than Spot's, {counts['larger']} "
          f"larger, {counts['excused']} larger but limit-deterministic beside Spot's other "
          f"acceptance, {counts['-']} where Spot did not finish")  # fmt: skip
    if args.json is not None:
        args.json.write_text(json.dumps(rows, indent=1) + "\n", encoding="utf-8")
    sys.exit(1 if counts["larger"] else 0)


if __name__ == "__main__":
    main()
