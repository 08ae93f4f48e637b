"""Error messages for bad specs: golden files of the rendered message, and the CLI's exit code."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from mitlc.cli import app
from mitlc.errors import SpecError, SpecSemanticError, SpecSyntaxError
from mitlc.syntax import parse, parse_bytes
from tests.conftest import GOLDEN, check_golden

CASES = sorted((GOLDEN / "errors").glob("*.mitl"))


def render_error(path: Path) -> SpecError:
    with pytest.raises(SpecError) as info:
        parse_bytes(path.read_bytes(), path.name)
    return info.value


def test_there_are_at_least_15_error_cases() -> None:
    assert len(CASES) >= 15


@pytest.mark.parametrize("path", CASES, ids=[p.stem for p in CASES])
def test_error_message_matches_golden(path: Path, update_golden: bool) -> None:
    error = render_error(path)
    check_golden(path.with_suffix(".err"), error.render() + "\n", update_golden)


@pytest.mark.parametrize("path", CASES, ids=[p.stem for p in CASES])
def test_error_has_location_caret_and_expectation(path: Path) -> None:
    error = render_error(path)
    first, source, caret = error.render().split("\n")
    assert first.startswith(f"{path.name}:{error.location.line}:{error.location.column}: ")
    assert caret.strip() == "^"
    assert len(caret) - 4 == error.location.column  # the caret sits under the column
    assert source[4:] == error.location.line_text
    assert "Traceback" not in error.render()


@pytest.mark.parametrize(
    ("text", "kind", "line", "column", "words"),
    [
        ("F[10,5] a", SpecSemanticError, 1, 3, "reversed"),
        ("F[-1,5] a", SpecSemanticError, 1, 3, "non-negative"),
        ("F[inf,5] a", SpecSemanticError, 1, 3, "lower bound"),
        ("a &", SpecSyntaxError, 1, 4, "expected a formula"),
        ("(a & b", SpecSyntaxError, 1, 7, "unclosed '(' at line 1, column 1"),
        ("a\n  & (b |\n  c", SpecSyntaxError, 3, 4, "unclosed '(' at line 2, column 5"),
        ("a # b", SpecSyntaxError, 1, 1, None),
        ("a ? b", SpecSyntaxError, 1, 3, "unexpected character '?'"),
        ("F[5 a", SpecSyntaxError, 1, 5, "expected ',' or '..'"),
        ("a b", SpecSyntaxError, 1, 3, "expected a binary operator"),
        ("   ", SpecSyntaxError, 1, 1, "empty specification"),
    ],
)
def test_error_kind_and_position(
    text: str, kind: type[SpecError], line: int, column: int, words: str | None
) -> None:
    if words is None:  # a comment ends the formula early: `a # b` is just `a`
        assert parse(text) == parse("a")
        return
    with pytest.raises(kind) as info:
        parse(text, "t.mitl")
    assert (info.value.location.line, info.value.location.column) == (line, column)
    assert words in info.value.message


def test_expected_set_is_exact_not_lalr_merged() -> None:
    # At top level no '(' is open, so ')' must not be offered.
    with pytest.raises(SpecSyntaxError) as info:
        parse("a b")
    assert "')'" not in info.value.message
    with pytest.raises(SpecSyntaxError) as info:
        parse("(a b)")
    assert "')'" in info.value.message


@pytest.mark.parametrize("path", CASES[:6], ids=[p.stem for p in CASES[:6]])
def test_cli_reports_error_with_exit_1_and_no_traceback(path: Path) -> None:
    result = CliRunner().invoke(app, ["fmt", str(path)])
    assert result.exit_code == 1
    assert "Traceback" not in result.output
    assert f"{path}:" in result.output
    assert result.output.rstrip().endswith("^")
