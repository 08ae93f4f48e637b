"""Cross-check of the finite-trace semantics against rtamt's discrete-time offline STL monitor.

Each random formula is translated to rtamt's STL, parsed once, and evaluated on several random
traces; the sign of rtamt's robustness at every position must be mitlc's truth value there.
Atoms are float signals of 0.0/1.0 written ``(a>0.5)``, so robustness is +-0.5 or +-inf, never 0.

rtamt has no ``true``/``false``, no bounded release and no ``[a,inf)`` intervals, and its ``iff``
is ``-|l - r|`` (0 for equal operands); the translation writes them out (``_to_rtamt``). Its
offline ``evaluate`` fails on a one-sample trace (``UnboundLocalError`` in its sampling-period
check), so a one-letter trace ``w`` is given to rtamt as ``w w`` and read at position 1: rtamt's
future-time operators make the value at a position depend only on the samples from there on.
"""

from __future__ import annotations

import math
import random
import time
from collections.abc import Sequence
from dataclasses import dataclass

import rtamt

from mitlc.semantics import Letter, evaluate_finite
from mitlc.syntax import ast, to_text
from tests.strategies import random_formula, random_trace

ATOMS = ("a", "b", "c")
SEED = 20240607
FORMULAS = 2000
TRACES_PER_FORMULA = 5
MAX_LENGTH = 15
MAX_BOUND = 5
UNBOUNDED_SHARE = 0.3  # the share of formulas whose intervals may be [lo,inf)

_TRUE = "(one>0.5)"


def _to_rtamt(formula: ast.Formula) -> str:
    """The rtamt STL text of ``formula``, fully parenthesised."""
    match formula:
        case ast.Bool(value):
            return _TRUE if value else f"not{_TRUE}"
        case ast.Atom(name):
            return f"({name}>0.5)"
        case ast.Not(operand):
            return f"not({_to_rtamt(operand)})"
        case ast.Next(operand):  # LTLf's strong next: rtamt's next is weak at the last sample
            return f"eventually[1,1]({_to_rtamt(operand)})"
        case ast.And(left, right):
            return f"(({_to_rtamt(left)}) and ({_to_rtamt(right)}))"
        case ast.Or(left, right):
            return f"(({_to_rtamt(left)}) or ({_to_rtamt(right)}))"
        case ast.Implies(left, right):
            return f"(({_to_rtamt(left)}) implies ({_to_rtamt(right)}))"
        case ast.Iff(left, right):
            p, q = _to_rtamt(left), _to_rtamt(right)
            return f"((({p}) and ({q})) or (not({p}) and not({q})))"
        case ast.Eventually(interval, operand):
            return _eventually(interval, _to_rtamt(operand))
        case ast.Always(interval, operand):
            return _always(interval, _to_rtamt(operand))
        case ast.Until(interval, left, right):
            return _until(interval, _to_rtamt(left), _to_rtamt(right))
        case ast.Release(interval, left, right):
            return f"not({_until(interval, f'not({_to_rtamt(left)})', f'not({_to_rtamt(right)})')})"
    raise TypeError(f"not a formula: {formula!r}")


def _eventually(interval: ast.Interval, p: str) -> str:
    lo, hi = interval.lo, interval.hi
    if hi is not None:
        return f"eventually[{lo},{hi}]({p})"
    if lo == 0:
        return f"eventually({p})"
    return f"eventually[{lo},{lo}](eventually({p}))"


def _always(interval: ast.Interval, p: str) -> str:
    lo, hi = interval.lo, interval.hi
    if hi is not None:
        return f"always[{lo},{hi}]({p})"
    if lo == 0:
        return f"always({p})"
    return f"always[{lo},{lo}](always({p}))"


def _until(interval: ast.Interval, p: str, q: str) -> str:
    lo, hi = interval.lo, interval.hi
    if hi is not None:
        return f"(({p}) until[{lo},{hi}] ({q}))"
    if lo == 0:
        return f"(({p}) until ({q}))"
    return f"(always[0,{lo - 1}]({p}) and eventually[{lo},{lo}](({p}) until ({q})))"


def _parse_rtamt(text: str) -> object:
    spec = rtamt.StlDiscreteTimeSpecification()
    for name in (*ATOMS, "one"):
        spec.declare_var(name, "float")
    spec.spec = text
    spec.parse()
    return spec


def _dataset(trace: Sequence[Letter]) -> dict[str, list[float]]:
    data: dict[str, list[float]] = {"time": [float(i) for i in range(len(trace))]}
    for name in ATOMS:
        data[name] = [1.0 if name in letter else 0.0 for letter in trace]
    data["one"] = [1.0] * len(trace)
    return data


def _rtamt_robustness(spec: object, trace: Sequence[Letter]) -> list[float]:
    """rtamt's robustness at every position of ``trace`` (a one-letter ``w`` is run as ``w w``)."""
    padded = tuple(trace) if len(trace) > 1 else (trace[0], trace[0])
    rows = spec.evaluate(_dataset(padded))  # type: ignore[attr-defined]
    return [float(r) for _, r in rows][len(padded) - len(trace) :]


@dataclass
class _Disagreement:
    formula: ast.Formula
    rtamt_text: str
    trace: tuple[Letter, ...]
    position: int
    mitlc: bool
    rtamt: bool

    def __str__(self) -> str:
        letters = " ".join("{" + ",".join(sorted(letter)) + "}" for letter in self.trace)
        return (
            f"formula {to_text(self.formula)!r}\n  rtamt   {self.rtamt_text!r}\n"
            f"  trace   {letters} (length {len(self.trace)})\n"
            f"  position {self.position}: mitlc {self.mitlc}, rtamt {self.rtamt}"
        )


def _formulas(rng: random.Random) -> list[ast.Formula]:
    return [
        random_formula(
            rng,
            depth=rng.randint(1, 5),
            atoms=ATOMS,
            bounded=rng.random() >= UNBOUNDED_SHARE,
            max_bound=MAX_BOUND,
        )
        for _ in range(FORMULAS)
    ]


def _unbounded_count(formulas: Sequence[ast.Formula]) -> int:
    return sum(1 for f in formulas for i in ast.intervals(f) if i.hi is None)


def test_finite_semantics_agree_with_rtamt_offline() -> None:
    started = time.perf_counter()
    rng = random.Random(SEED)
    formulas = _formulas(rng)
    checked, traces, disagreements = 0, 0, list[_Disagreement]()
    for formula in formulas:
        text = _to_rtamt(formula)
        spec = _parse_rtamt(text)
        for _ in range(TRACES_PER_FORMULA):
            trace = random_trace(rng, rng.randint(1, MAX_LENGTH), ATOMS)
            expected = evaluate_finite(formula, trace)
            robustness = _rtamt_robustness(spec, trace)
            traces += 1
            for position, (mine, value) in enumerate(zip(expected, robustness, strict=True)):
                checked += 1
                case = _Disagreement(formula, text, trace, position, mine, value > 0)
                assert value != 0.0 and not math.isnan(value), f"robustness {value} at\n{case}"
                if mine != case.rtamt:
                    disagreements.append(case)
    elapsed = time.perf_counter() - started
    print(
        f"rtamt cross-check: {len(formulas)} formulas ({_unbounded_count(formulas)} [lo,inf) "
        f"intervals), {traces} traces, {checked} positions, {checked - len(disagreements)} "
        f"agreements, {len(disagreements)} disagreements, {elapsed:.1f} s"
    )
    assert not disagreements, f"{len(disagreements)} disagreements with rtamt; the first:\n" + (
        "\n".join(str(d) for d in disagreements[:5])
    )
    assert traces == FORMULAS * TRACES_PER_FORMULA
    assert checked >= 25_000


def test_every_operator_and_unbounded_form_is_exercised() -> None:
    formulas = _formulas(random.Random(SEED))
    kinds = {type(node) for f in formulas for node in ast.subformulas(f)}
    assert kinds == {
        ast.Bool, ast.Atom, ast.Not, ast.Next, ast.Eventually, ast.Always,
        ast.And, ast.Or, ast.Implies, ast.Iff, ast.Until, ast.Release,
    }  # fmt: skip
    unbounded = {
        (type(node), node.interval.lo > 0)
        for f in formulas
        for node in ast.subformulas(f)
        if isinstance(node, ast.Eventually | ast.Always | ast.Until | ast.Release)
        and node.interval.hi is None
    }
    assert len(unbounded) == 8  # each of F, G, U, R with [0,inf) and with [lo,inf), lo >= 1


def test_rtamt_translation_of_the_hard_cases() -> None:
    """The hand-written rewritings rtamt needs, spelled out once."""
    a, b = ast.Atom("a"), ast.Atom("b")
    assert _to_rtamt(ast.Iff(a, b)) == (
        "((((a>0.5)) and ((b>0.5))) or (not((a>0.5)) and not((b>0.5))))"
    )
    assert _to_rtamt(ast.Eventually(ast.Interval(2, None), a)) == (
        "eventually[2,2](eventually((a>0.5)))"
    )
    assert _to_rtamt(ast.Until(ast.Interval(3, None), a, b)) == (
        "(always[0,2]((a>0.5)) and eventually[3,3](((a>0.5)) until ((b>0.5))))"
    )
    assert _to_rtamt(ast.Release(ast.Interval(1, 2), a, b)) == (
        "not(((not((a>0.5))) until[1,2] (not((b>0.5)))))"
    )
