"""The installed wheel carries the grammar and parses with it, away from the source checkout."""

from __future__ import annotations

import subprocess
import sys
import zipfile
from pathlib import Path

from tests.conftest import ROOT


def test_wheel_carries_the_grammar_and_parses(tmp_path: Path) -> None:
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "wheel",
            "--no-deps",
            "--no-build-isolation",
            "-q",
            "-w",
            str(tmp_path / "dist"),
            str(ROOT),
        ],
        check=True,
        capture_output=True,
    )
    (wheel,) = (tmp_path / "dist").glob("mitlc-*.whl")
    with zipfile.ZipFile(wheel) as archive:
        names = archive.namelist()
        assert "mitlc/grammars/mitl.lark" in names
        assert "mitlc/grammars/mitl.lalr.json" in names
        packaged = archive.read("mitlc/grammars/mitl.lark")
        archive.extractall(tmp_path / "site")
    assert packaged == (ROOT / "grammars" / "mitl.lark").read_bytes()
    # Import mitlc from the unpacked wheel only (the checkout is not on the path), in a fresh
    # interpreter, and check which grammar file it read.
    probe = (
        "import mitlc.syntax.grammar as g, mitlc.syntax as s;"
        "print(g.grammar_path());"
        "print(s.to_text(s.parse('(!a U_[5,10] a) & (!b U[15..20] b)')))"
    )
    proc = subprocess.run(
        [sys.executable, "-c", probe],
        cwd=tmp_path,
        env={"PYTHONPATH": str(tmp_path / "site"), "PATH": "/usr/bin:/bin"},
        capture_output=True,
        text=True,
        check=True,
    )
    grammar_file, printed = proc.stdout.splitlines()
    assert Path(grammar_file) == tmp_path / "site" / "mitlc" / "grammars" / "mitl.lark"
    assert printed == "(!a U[5,10] a) & (!b U[15,20] b)"
