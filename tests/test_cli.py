"""The command line: fmt and parse, files, standard input and -e, and their errors."""

from __future__ import annotations

import json
import subprocess
import sys

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
