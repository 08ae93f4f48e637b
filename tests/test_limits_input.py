"""The input limits of :mod:`mitlc.limits` (issue 11, part 3): each kind of input that raised a
traceback, generated here, is refused with mitlc's own message naming the file (and the line
and column where there is one); inputs just within a limit still work.

World files' limits are in ``tests/test_worlds_limits.py``."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

import pytest
from typer.testing import CliRunner

from mitlc.cli import app
from mitlc.errors import MitlcError, SourceLocation, SpecSemanticError, SpecSyntaxError
from mitlc.limits import MAX_BOUND, MAX_SPEC_CHARS, MAX_SPEC_DEPTH, MAX_TRACE_JSON_DEPTH
from mitlc.syntax import parse, parse_batch_file, parse_bytes, parse_file, to_text
from mitlc.traces import TraceError, read_trace

DEEP: dict[str, Callable[[int], str]] = {
    "not": lambda d: "!" * (d - 1) + "a",
    "parentheses": lambda d: "(" * (d - 1) + "a" + ")" * (d - 1),
    "next": lambda d: "X " * (d - 1) + "a",
    "until-chain": lambda d: "a U " * (d - 1) + "a",
    "and-chain": lambda d: " & ".join(["a"] * d),
    "eventually": lambda d: "F " * (d - 1) + "a",
    "release-chain": lambda d: "a R[0,2] " * (d - 1) + "a",
}
"""Formulas nested exactly ``d`` levels deep (operators and parentheses)."""


def run(*args: str, input: bytes | None = None) -> tuple[int, str]:
    """Run the command line in-process: its exit code and output; never an exception."""
    result = CliRunner().invoke(app, list(args), input=input)
    assert result.exception is None or isinstance(result.exception, SystemExit), repr(
        result.exception
    )
    assert "Traceback" not in result.output
    return result.exit_code, result.output


def refused(output: str, where: str) -> None:
    """A spec error: ``where:line:column: message``, the source line and a caret."""
    first, _, rest = output.partition("\n")
    assert first.startswith(where), output
    assert rest.rstrip().endswith("^"), output


# --- nesting ------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", DEEP)
def test_nesting_at_the_limit_works_through_every_pass(kind: str, tmp_path: Path) -> None:
    text = DEEP[kind](MAX_SPEC_DEPTH)
    formula = parse(text)
    assert parse(to_text(formula)) == formula
    spec = tmp_path / "deep.mitl"
    spec.write_text(text, encoding="utf-8")
    for command in (["fmt"], ["parse"], ["parse", "--json"], ["compile"], ["compile", "-f", "hoa"]):
        code, output = run(*command, str(spec))
        assert code == 0, output
    trace = tmp_path / "t.csv"
    trace.write_text("a\n1\n0\n1\n", encoding="utf-8")
    assert run("monitor", str(spec), str(trace))[0] == 0


@pytest.mark.parametrize("kind", DEEP)
@pytest.mark.parametrize("depth", [MAX_SPEC_DEPTH + 1, 300, 2000])
def test_nesting_past_the_limit_is_refused(kind: str, depth: int) -> None:
    text = DEEP[kind](depth)
    with pytest.raises(SpecSyntaxError, match="nested too deeply") as info:
        parse(text, "deep.mitl")
    assert info.value.location.line == 1
    if depth == MAX_SPEC_DEPTH + 1:
        code, output = run("fmt", "-e", text)
        assert code == 1 and "more than 100 levels" in output
        refused(output, "<expr>:1:")


def test_the_caret_points_at_the_first_level_too_deep() -> None:
    with pytest.raises(SpecSyntaxError) as info:
        parse("b & " + "!" * MAX_SPEC_DEPTH + "a")
    assert info.value.location.column == 5 + MAX_SPEC_DEPTH - 1  # the 100th '!', 101 deep


# --- size ---------------------------------------------------------------------------------


def test_a_one_megabyte_spec_is_refused_from_every_source(tmp_path: Path) -> None:
    text = "a & b | " * 131072 + "c"  # 1 MB, on one line
    with pytest.raises(SpecSyntaxError, match="too long") as info:
        parse(text, "big.mitl")
    assert (info.value.location.line, info.value.location.column) == (1, MAX_SPEC_CHARS + 1)
    spec = tmp_path / "big.mitl"
    spec.write_text(text, encoding="utf-8")
    with pytest.raises(SpecSyntaxError, match="too long"):
        parse_file(spec)
    for args, stdin in (((str(spec),), None), (("-e", text), None), (("-",), text.encode())):
        code, output = run("fmt", *args, input=stdin)
        assert code == 1 and "more than 50,000 characters" in output
        assert max(map(len, output.splitlines())) < 200  # the source line is cut around the caret


def test_a_spec_just_within_the_size_limit_parses() -> None:
    text = "(a & b)" + " " * (MAX_SPEC_CHARS - 7)
    assert parse(text) == parse("a & b")
    with pytest.raises(SpecSyntaxError, match="too long"):
        parse(text + " ")


@pytest.mark.skipif(not os.path.exists("/dev/zero"), reason="needs /dev/zero")
def test_an_endless_spec_file_is_refused_without_reading_it_all() -> None:
    code, output = run("fmt", "/dev/zero")  # a device: refused before it is opened
    assert code == 1 and output == "mitlc: /dev/zero: not a regular file (a character device)\n"


# --- interval bounds ----------------------------------------------------------------------


def test_a_bound_of_4400_digits_is_refused_at_the_bound() -> None:
    text = "G (req -> F[0," + "7" * 4400 + "] done)"
    with pytest.raises(SpecSemanticError, match="too large") as info:
        parse(text, "t.mitl")
    assert info.value.location.column == text.index("7") + 1
    assert "(4,400 digits)" in info.value.message
    code, output = run("compile", "-e", text)
    assert code == 1
    refused(output, "<expr>:1:15: interval bound 777777777777... (4,400 digits) is too large")


@pytest.mark.parametrize(
    ("bound", "accepted"),
    [(MAX_BOUND, True), (MAX_BOUND + 1, False), (10**30, False), ("0" * 5000 + "5", True)],
)
def test_bounds_up_to_the_limit_are_accepted(bound: int | str, accepted: bool) -> None:
    text = f"F[2,{bound}] a"
    if accepted:
        assert parse(text).interval.hi == int(str(bound).lstrip("0"))  # type: ignore[union-attr]
    else:
        with pytest.raises(SpecSemanticError, match=f"at most {MAX_BOUND:,}"):
            parse(text)


def test_a_huge_negative_bound_is_reported_as_negative() -> None:
    with pytest.raises(SpecSemanticError, match=r"non-negative.*\(5,000 digits\)"):
        parse("F[-" + "9" * 5000 + ",3] a")


# --- bytes that are not UTF-8, and other odd characters ----------------------------------


def test_non_utf8_batch_file_names_the_line_and_column(tmp_path: Path) -> None:
    batch = tmp_path / "formulas.txt"
    batch.write_bytes(b"a & b\n# fine\nF[0,3] \xff c\n")
    code, output = run("compile", "--batch", str(batch))
    assert code == 1
    refused(output, f"{batch}:3:8: invalid UTF-8: byte 0xff")


def test_a_batch_file_is_held_to_its_limits(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr("mitlc.syntax.parser.MAX_BATCH_FORMULAS", 3)
    batch = tmp_path / "formulas.txt"
    batch.write_text("a\n\n# skipped\nb\nc\n", encoding="utf-8")
    assert len(parse_batch_file(batch)) == 3
    batch.write_text("a\n\n# skipped\nb\nc\nd\n", encoding="utf-8")
    with pytest.raises(SpecSyntaxError, match="more than 3 in a batch file") as info:
        parse_batch_file(batch)
    assert info.value.location.line == 6
    monkeypatch.setattr("mitlc.syntax.parser.MAX_BATCH_BYTES", 8)
    with pytest.raises(SpecSyntaxError, match="the batch file is too large"):
        parse_batch_file(batch)


def test_non_utf8_after_a_byte_order_mark_is_located_in_the_text() -> None:
    with pytest.raises(SpecSyntaxError, match="byte 0xff") as info:
        parse_bytes(b"\xef\xbb\xbfa & \xff", "bom.mitl")
    assert info.value.location.column == 5


def test_non_utf8_standard_input_and_spec_file(tmp_path: Path) -> None:
    spec = tmp_path / "s.mitl"
    spec.write_bytes(b"a &\n  \xc3( b")
    code, output = run("fmt", str(spec))
    assert code == 1
    refused(output, f"{spec}:2:3: invalid UTF-8: byte 0xc3")
    code, output = run("parse", "-", input=b"\xfe\xff a")
    assert code == 1
    refused(output, "<stdin>:1:1: invalid UTF-8: byte 0xfe")


@pytest.mark.parametrize(("char", "shown"), [("\x00", "U+0000"), ("\x1b", "U+001B")])
def test_control_characters_are_named_not_printed(char: str, shown: str) -> None:
    code, output = run("fmt", "-e", f"a {char} b")
    assert code == 1 and f"unexpected character {shown}" in output
    assert char not in output


def test_a_long_line_is_cut_around_the_caret() -> None:
    location = SourceLocation("f", 1, 5001, "a" * 10_000)
    source, caret = location.caret().split("\n")
    assert len(source) <= 4 + 106 and source.strip().startswith("...")
    assert source[caret.index("^")] == "a"


# --- traces -------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("line", "words"),
    [
        ("[" * 100_000 + "]" * 100_000, "nested more than"),
        (
            '{"a": ' + "[" * (MAX_TRACE_JSON_DEPTH + 1) + "]" * (MAX_TRACE_JSON_DEPTH + 1) + "}",
            "nested",
        ),
        ('{"a": ' + "9" * 5000 + "}", "expected a list"),
        ('["a", ' + "1" * 5000 + ".5e99999]", "expected a list"),
        ('{"a": NaN}', "expected a list"),
        ('"' + "x" * 1000 + '"', "expected a list"),
    ],
)
def test_odd_json_lines_are_refused_at_their_line(tmp_path: Path, line: str, words: str) -> None:
    trace = tmp_path / "t.jsonl"
    trace.write_text('["a"]\n' + line + "\n", encoding="utf-8")
    with pytest.raises(TraceError, match=words) as info:
        read_trace(trace)
    assert str(info.value).startswith(f"{trace}:2: ")
    code, output = run("monitor", "specs/paper/case1.mitl", str(trace))
    assert code == 1 and output.startswith(f"{trace}:2: ")


def test_brackets_inside_strings_do_not_count_as_nesting(tmp_path: Path) -> None:
    trace = tmp_path / "t.jsonl"
    trace.write_text('["a", "[[[[[[[[[[[[[[[[[["]\n', encoding="utf-8")
    assert read_trace(trace) == [frozenset({"a", "[[[[[[[[[[[[[[[[[["})]


@pytest.mark.parametrize(
    ("name", "data", "words"),
    [
        ("t.csv", b"a,b\n1,0\n0,\xff\n", ":3:3: invalid UTF-8: byte 0xff"),
        ("t.jsonl", b'["a"]\n["\xe9"]\n', ":2:3: invalid UTF-8: byte 0xe9"),
        ("t.csv", b"a,b\n" + b'"1' + b"1" * 200_000 + b'",0\n', ":2: not CSV: field larger"),
        ("t.csv", b"a,b\n1,0\n0\x001\n", ":3: 1 values for 2 columns"),
    ],
)
def test_bad_traces_name_the_file_and_line(
    tmp_path: Path, name: str, data: bytes, words: str
) -> None:
    trace = tmp_path / name
    trace.write_bytes(data)
    with pytest.raises(TraceError) as info:
        read_trace(trace)
    assert str(info.value).startswith(f"{trace}{words}"), str(info.value)


def test_too_many_steps_are_refused(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr("mitlc.traces.MAX_TRACE_STEPS", 5)
    csv, jsonl = tmp_path / "t.csv", tmp_path / "t.jsonl"
    csv.write_text("a\n" + "1\n" * 5, encoding="utf-8")
    jsonl.write_text('["a"]\n' * 5, encoding="utf-8")
    assert len(read_trace(csv)) == len(read_trace(jsonl)) == 5
    csv.write_text("a\n" + "1\n" * 6, encoding="utf-8")
    jsonl.write_text('["a"]\n' * 6, encoding="utf-8")
    for path, line in ((csv, 7), (jsonl, 6)):
        with pytest.raises(TraceError, match=f"^{path}:{line}: the trace is too long"):
            read_trace(path)


@pytest.mark.skipif(not os.path.exists("/dev/zero"), reason="needs /dev/zero")
def test_an_endless_trace_is_refused(tmp_path: Path) -> None:
    code, output = run("monitor", "specs/paper/case1.mitl", "/dev/zero")
    assert code == 1 and output.startswith("/dev/zero: cannot read the trace: not a regular file")


@pytest.mark.parametrize("target", ["directory", "missing", "loop"])
def test_unreadable_inputs_name_the_file(tmp_path: Path, target: str) -> None:
    path = tmp_path / "x"
    if target == "directory":
        path.mkdir()
    elif target == "loop":
        path.symlink_to(path)
    for args in (
        ["fmt", str(path)],
        ["compile", "--batch", str(path)],
        ["monitor", "specs/paper/case1.mitl", str(path)],
        ["check", str(path)],
    ):
        code, output = run(*args)
        assert code == 1 and str(path) in output.splitlines()[0], (args, output)
    with pytest.raises(MitlcError):
        read_trace(path)
