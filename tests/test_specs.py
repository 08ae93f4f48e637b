"""The shipped specs: each parses, is commented, and means what its comment says."""

from __future__ import annotations

from pathlib import Path

import pytest

from mitlc.semantics import Lasso, holds_lasso
from mitlc.syntax import parse, parse_file, to_text
from tests.conftest import ROOT

SPECS = sorted((ROOT / "specs").rglob("*.mitl"))
PAPER = ROOT / "specs" / "paper"


def word(length: int, visits: dict[int, str], loop: int = 1) -> Lasso:
    """A lasso of ``length`` letters with the given propositions at the given steps, then a
    loop of ``loop`` empty letters."""
    letters = tuple(frozenset({visits[i]}) if i in visits else frozenset() for i in range(length))
    return Lasso(letters, (frozenset(),) * loop)


def test_the_paper_specs_are_shipped() -> None:
    names = {p.name for p in PAPER.glob("*.mitl")}
    assert {
        "case1.mitl",
        "case1-patrol.mitl",
        "case1-literal.mitl",
        "case2.mitl",
        "case3.mitl",
    } <= names


@pytest.mark.parametrize("path", SPECS, ids=[p.stem for p in SPECS])
def test_spec_parses_and_is_commented(path: Path) -> None:
    formula = parse_file(path)
    assert parse(to_text(formula)) == formula
    assert path.read_text(encoding="utf-8").lstrip().startswith("#")


def test_case1_is_the_described_task() -> None:
    case1 = parse_file(PAPER / "case1.mitl")
    assert holds_lasso(case1, word(25, {7: "a", 17: "b"}))
    assert holds_lasso(case1, word(25, {5: "a", 20: "b"}))
    assert not holds_lasso(case1, word(25, {3: "a", 7: "a", 17: "b"}))  # a visited too early
    assert not holds_lasso(case1, word(25, {11: "a", 17: "b"}))  # a too late
    assert not holds_lasso(case1, word(25, {7: "a", 12: "b", 17: "b"}))  # b too early
    assert not holds_lasso(case1, word(25, {7: "a"}))  # b never


def test_case1_patrol_repeats_rounds_from_the_step_after_b() -> None:
    patrol = parse_file(PAPER / "case1-patrol.mitl")
    # Rounds of 18 steps: a at offset 7, b at offset 17, the next round starts at offset 18.
    loop = tuple(
        frozenset({"a"}) if i == 7 else frozenset({"b"}) if i == 17 else frozenset()
        for i in range(18)
    )
    assert holds_lasso(patrol, Lasso((), loop))
    # One round only: the second round never sees a.
    assert not holds_lasso(patrol, word(18, {7: "a", 17: "b"}))
    # Second round's a comes 4 steps after the first round's b: too early.
    late = Lasso(loop + tuple(frozenset({"a"}) if i == 3 else frozenset() for i in range(5)), loop)
    assert not holds_lasso(patrol, late)


def test_case1_literal_means_recurring_windows() -> None:
    literal = parse_file(PAPER / "case1-literal.mitl")
    # The described task's run does not satisfy the literal formula ...
    assert not holds_lasso(literal, word(25, {7: "a", 17: "b"}))
    # ... but shuttling with a and b each at most 5 steps apart forever does, early visits too.
    shuttle = (frozenset({"a"}), frozenset(), frozenset({"b"}), frozenset())
    assert holds_lasso(literal, Lasso((), shuttle))
    # With a and b 6 steps apart in each 12-step cycle, every window of 6 still has both ...
    cycle = tuple(
        frozenset({"a"}) if i in (0, 6) else frozenset({"b"}) if i in (3, 9) else frozenset()
        for i in range(12)
    )
    assert holds_lasso(literal, Lasso((), cycle))
    # ... but a gap of 7 between visits to a breaks it.
    gap = tuple(
        frozenset({"a"}) if i == 0 else frozenset({"b"}) if i in (3, 6) else frozenset()
        for i in range(7)
    )
    assert not holds_lasso(literal, Lasso((), gap))


def test_case2_and_case3_windows() -> None:
    case2 = parse_file(PAPER / "case2.mitl")
    assert holds_lasso(case2, word(35, {12: "a", 27: "b"}))
    assert not holds_lasso(case2, word(35, {9: "a", 27: "b"}))
    case3 = parse_file(PAPER / "case3.mitl")
    assert holds_lasso(case3, word(20, {6: "printer", 12: "a"}))
    assert not holds_lasso(case3, word(20, {4: "printer", 12: "a"}))  # printer too early
    assert not holds_lasso(case3, word(20, {6: "printer", 9: "a"}))  # a too early
    assert not holds_lasso(case3, word(20, {11: "a", 14: "printer"}))  # a before the printer
