"""Issue 15's formulas: mitlc's compile time and sizes beside Spot on the unrolled formula.

    .venv/bin/python bench/symbolic_bench.py [--repeats 3] [--spot-timeout 60]

For each formula, mitlc's compile time is the process CPU time of
``compile_formula(parse(text))`` in this process (no time limit), the least of ``--repeats``
runs; the sizes are its digital states, T-LDGBA locations and edges. Spot translates the same
formula with every bounded operator unrolled into ``X`` (``spot.translate``, its default, then
completed with a sink as mitlc's automata are), in a child process killed after
``--spot-timeout`` seconds; its time is the child's CPU time in ``spot.translate``.

The unrolled text of a nested deadline sequence grows as ``21^k`` (``k`` goals of ``U[0,20]``:
about ``10^18`` characters for ``k = 12``), so Spot is not given text: the child builds the
unrolled formula with Spot's constructors, which share equal subformulas (the same formula as
``mitlc.syntax.spot.to_spot`` writes, node for node; ``--check`` asserts it on the formulas of
``bench/formulas.txt``). The column ``unrolled`` is the length the text would have.

Targets (issue 15): the 12-goal sequence under 0.2 s and the 20-goal one under 1 s, with the
same number of locations as the old compiler (7aba496, the explicit per-letter table); the
other formulas under 1 s each. The old compiler's location counts are measured by
``bench/compile_compare.py`` (it compiles up to 12 goals; 20 goals, with ``2^20`` letters a
state, are out of its reach, and the count ``k + 2`` it gives for every ``k`` it compiles is
taken for 20).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from compile_bench import run_child

from mitlc.automata import compile_formula
from mitlc.syntax import ast, parse
from mitlc.syntax.spot import to_spot, unrolled_size

ROOT = Path(__file__).resolve().parents[1]


def deadline_sequence(k: int) -> str:
    """``!p1 U[0,20] (p1 & X (!p2 U[0,20] (p2 & X ( ... (!pk U[0,20] pk)))))``."""
    return _chain([(f"p{i}", "[0,20]") for i in range(1, k + 1)])


def _chain(goals: list[tuple[str, str]]) -> str:
    (p, bound), rest = goals[0], goals[1:]
    if not rest:
        return f"(!{p} U{bound} {p})"
    return f"(!{p} U{bound} ({p} & X {_chain(rest)}))"


def office(with_call: bool = True) -> str:
    """The office task: 16 propositions (14 without the ``call -> F[0,5] desk`` conjunct)."""
    rounds = _chain([("mail", "[0,10]")] + [(f"o{i}", "[0,15]") for i in range(1, 7)])
    call = "G (call -> F[0,5] desk) & " if with_call else ""
    return (
        f"G !(wet | stairs | server) & {call}{rounds} & G F charger & F (printer | coffee | supply)"
    )


OLD_LOCATIONS = {12: 14, 20: 22}
"""Locations of the old compiler (7aba496) on the k-goal sequence (see the module docstring)."""

ROWS: list[tuple[str, str, float, int | None]] = [
    ("deadline sequence, 12 goals", deadline_sequence(12), 0.2, OLD_LOCATIONS[12]),
    ("deadline sequence, 20 goals", deadline_sequence(20), 1.0, OLD_LOCATIONS[20]),
    ("G (F p1 & ... & F p8)", "G (" + " & ".join(f"F p{i}" for i in range(1, 9)) + ")", 1.0, None),
    (
        "G (p1 -> F[0,10] (p2 | ... | p10))",
        "G (p1 -> F[0,10] (" + " | ".join(f"p{i}" for i in range(2, 11)) + "))",
        1.0,
        None,
    ),
    ("office task (16 props)", office(), 1.0, None),
    ("office task, no call->desk (14 props)", office(with_call=False), 1.0, None),
]
"""(name, formula, target seconds, locations required or None)."""


def spot_formula(spot: Any, formula: ast.Formula) -> Any:
    """``spot.formula(to_spot(formula))``, built with Spot's constructors (shared subformulas)."""
    make = spot.formula

    def all_(parts: list[Any]) -> Any:
        return make.And(parts) if parts else make.tt()

    def any_(parts: list[Any]) -> Any:
        return make.Or(parts) if parts else make.ff()

    def nexts(f: Any, n: int) -> list[Any]:
        """``[f, X f, ..., X^n f]``."""
        out = [f]
        for _ in range(n):
            out.append(make.X(out[-1]))
        return out

    def until(interval: ast.Interval, p: Any, q: Any) -> Any:
        if interval.hi is None:
            xp = nexts(p, interval.lo)
            return all_([*xp[: interval.lo], nexts(make.U(p, q), interval.lo)[-1]])
        xp, xq = nexts(p, interval.hi), nexts(q, interval.hi)
        return any_([all_([xq[j], *xp[:j]]) for j in range(interval.lo, interval.hi + 1)])

    def build(f: ast.Formula) -> Any:
        match f:
            case ast.Bool(value):
                return make.tt() if value else make.ff()
            case ast.Atom(name):
                return make.ap(name)
            case ast.Not(operand):
                return make.Not(build(operand))
            case ast.Next(operand):
                return make.X(build(operand))
            case ast.Eventually(interval, operand):
                return until(interval, make.tt(), build(operand))
            case ast.Always(interval, operand):
                return make.Not(until(interval, make.tt(), make.Not(build(operand))))
            case ast.Until(interval, left, right):
                return until(interval, build(left), build(right))
            case ast.Release(interval, left, right):
                return make.Not(until(interval, make.Not(build(left)), make.Not(build(right))))
            case ast.And(left, right):
                return make.And([build(left), build(right)])
            case ast.Or(left, right):
                return make.Or([build(left), build(right)])
            case ast.Implies(left, right):
                return make.Implies(build(left), build(right))
            case ast.Iff(left, right):
                return make.Equiv(build(left), build(right))
        raise TypeError(f"not a formula: {f!r}")

    return build(formula)


def spot_child() -> None:
    """In the child: translate the formula read on stdin and print time and size as JSON."""
    import spot

    formula = spot_formula(spot, parse(sys.stdin.read()))
    start = time.process_time()
    aut = spot.translate(formula)
    seconds = time.process_time() - start
    aut = spot.complete(aut)  # mitlc's automata are complete: count Spot's rejecting sink too
    print(json.dumps({"seconds": seconds, "states": aut.num_states()}))


def run_spot(text: str, timeout: float) -> dict[str, Any] | None:
    return run_child([sys.executable, __file__, "--spot-child"], text, timeout)


def run_mitlc(text: str, repeats: int) -> dict[str, Any]:
    best = float("inf")
    for _ in range(repeats):
        start = time.process_time()
        compiled = compile_formula(parse(text), time_limit=None)
        best = min(best, time.process_time() - start)
    return {
        "seconds": best,
        "props": len(compiled.timed.propositions),
        "digital": len(compiled.digital.states),
        "locations": len(compiled.timed.locations),
        "edges": len(compiled.timed.edges),
    }


def check_spot_formulas() -> None:
    """Assert that the constructed formulas are Spot's parse of ``to_spot``'s text."""
    import spot

    lines = (ROOT / "bench" / "formulas.txt").read_text(encoding="utf-8").splitlines()
    texts = [line for line in lines if line.strip() and not line.startswith("#")]
    texts += [deadline_sequence(2), deadline_sequence(3), ROWS[3][1]]
    for text in texts:
        built = spot_formula(spot, parse(text))
        assert built == spot.formula(to_spot(parse(text))), text
    print(f"{len(texts)} formulas: Spot's constructors give the parse of the unrolled text")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--spot-timeout", type=float, default=60.0)
    parser.add_argument("--spot-child", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--check", action="store_true", help="check the Spot formula builder")
    args = parser.parse_args()
    if args.spot_child:
        spot_child()
        return
    if args.check:
        check_spot_formulas()
        return
    header = (
        f"{'formula':38} {'props':>5} {'mitlc s':>8} {'digital':>7} {'locs':>5} {'edges':>6} "
        f"{'unrolled':>9} {'spot s':>8} {'spot st':>8}  {'target':24} {'met':>3}"
    )
    print(header)
    print("-" * len(header))
    for name, text, limit, old_locations in ROWS:
        mine = run_mitlc(text, args.repeats)
        theirs = run_spot(text, args.spot_timeout)
        spot_s = "timeout" if theirs is None else f"{theirs['seconds']:.3f}"
        spot_states = "-" if theirs is None else str(theirs["states"])
        target = f"< {limit:g} s"
        met = mine["seconds"] < limit
        if old_locations is not None:
            target += f", {old_locations} locs (old)"
            met = met and mine["locations"] == old_locations
        print(
            f"{name:38} {mine['props']:>5} {mine['seconds']:>8.3f} {mine['digital']:>7} "
            f"{mine['locations']:>5} {mine['edges']:>6} {unrolled_size(parse(text)):>9.1e} "
            f"{spot_s:>8} {spot_states:>8}  {target:24} {'yes' if met else 'NO':>3}",
            flush=True,
        )
    print(
        f"mitlc s: least process CPU time of {args.repeats} compiles; spot s: CPU time of "
        f"spot.translate on the unrolled formula (killed after {args.spot_timeout:g} s)"
    )


if __name__ == "__main__":
    main()
