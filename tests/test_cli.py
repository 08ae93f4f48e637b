"""The command line: fmt and parse, files, standard input and -e, and their errors."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from typer.testing import CliRunner

from mitlc.cli import app
from mitlc.syntax import parse
from tests.conftest import ROOT

CASE1 = ROOT / "specs" / "paper" / "case1.mitl"
runner = CliRunner()


def test_fmt_file() -> None:
    result = runner.invoke(app, ["fmt", str(CASE1)])
    assert result.exit_code == 0, result.output
    assert result.output == "(!a U[5,10] a) & (!b U[15,20] b)\n"


def test_fmt_expression_and_stdin_agree() -> None:
    expr = runner.invoke(app, ["fmt", "-e", "□◇_[2..5] a"])
    stdin = runner.invoke(app, ["fmt", "-"], input="G F[2:5] a  # a comment\n")
    assert expr.exit_code == stdin.exit_code == 0
    assert expr.output == stdin.output == "G F[2,5] a\n"


def test_parse_json_is_the_ast_with_spans() -> None:
    result = runner.invoke(app, ["parse", "--json", "-e", "a U[5,10] b"])
    assert result.exit_code == 0
    data = json.loads(result.output)
    assert data["op"] == "until" and data["interval"] == [5, 10]
    assert data["left"] == {
        "op": "atom",
        "name": "a",
        "span": {"start": 0, "end": 1, "line": 1, "column": 1},
    }
    assert data["right"]["span"]["column"] == 11


def test_parse_tree_view() -> None:
    result = runner.invoke(app, ["parse", "-e", "G (req -> F[0,5] done)"])
    assert result.exit_code == 0
    assert result.output.splitlines() == [
        "Always [0,inf)  @1:1",
        "└── Implies  @1:4",
        "    ├── Atom req  @1:4",
        "    └── Eventually [0,5]  @1:11",
        "        └── Atom done  @1:18",
    ]


def test_errors_exit_1_without_traceback() -> None:
    for args in (["fmt", "-e", "a &"], ["fmt", "missing.mitl"], ["fmt"], ["fmt", "x", "-e", "a"]):
        result = runner.invoke(app, args)
        assert result.exit_code == 1, args
        assert "Traceback" not in result.output
    assert "missing.mitl" in runner.invoke(app, ["fmt", "missing.mitl"]).output


def test_stdin_bad_bytes() -> None:
    result = runner.invoke(app, ["fmt", "-"], input=b"a & \xfe")
    assert result.exit_code == 1
    assert result.output.startswith("<stdin>:1:5: invalid UTF-8")


def test_python_dash_m_and_version() -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "mitlc", "fmt", "-e", "F[0,inf) a"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert proc.returncode == 0 and proc.stdout == "F a\n"
    assert runner.invoke(app, ["--version"]).output.startswith("mitlc ")


def test_fmt_output_parses_back() -> None:
    text = runner.invoke(app, ["fmt", str(ROOT / "specs" / "paper" / "case3.mitl")]).output
    assert parse(text) == parse(CASE1.with_name("case3.mitl").read_text(encoding="utf-8"))


WORLD = ROOT / "specs" / "paper" / "case1.yaml"


def _check_json(*args: str) -> dict[str, object]:
    result = runner.invoke(app, ["check", str(WORLD), "--json", *args])
    assert result.exit_code == 0, result.output
    report: dict[str, object] = json.loads(result.output)
    del report["seconds"]  # the only figure that changes from run to run
    return report


def test_check_expr_is_the_spec_file_given_inline(tmp_path: Path) -> None:
    spec = tmp_path / "task.mitl"
    spec.write_text("F[0,10] a\n", encoding="utf-8")
    inline = _check_json("-e", "F[0,10] a")
    assert inline == _check_json("--spec", str(spec))
    assert inline == _check_json("--expr", "F_[0..10] a")  # read as --spec reads its text
    assert inline["spec"] == "F[0,10] a" and inline["pmax"] != _check_json()["pmax"]
    plain = runner.invoke(app, ["check", str(WORLD), "-e", "F[0,10] a"])
    assert plain.exit_code == 0 and "F[0,10] a" in plain.output


def test_check_refuses_spec_and_expr_together_and_points_at_a_bad_expr(tmp_path: Path) -> None:
    spec = tmp_path / "task.mitl"
    spec.write_text("F a\n", encoding="utf-8")
    both = runner.invoke(app, ["check", str(WORLD), "--spec", str(spec), "-e", "F a"])
    assert both.exit_code == 1 and "Traceback" not in both.output
    assert both.output == "mitlc: give the task once: --spec SPEC or -e FORMULA, not both\n"
    bad = runner.invoke(app, ["check", str(WORLD), "-e", "F[0,10 a"])
    assert bad.exit_code == 1 and "Traceback" not in bad.output
    # the same form as compile's: the source, line, column, the text and a caret under the fault
    assert bad.output == runner.invoke(app, ["compile", "-e", "F[0,10 a"]).output
    head, text, caret = bad.output.splitlines()
    assert head.startswith("<expr>:1:8: ") and text.strip() == "F[0,10 a"
    assert caret.strip() == "^" and caret.index("^") == text.index("F") + 7
