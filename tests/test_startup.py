"""The command line's start-up: what ``mitlc fmt`` and ``mitlc compile`` import, and typer's
coercion without pydantic (:mod:`mitlc.cli_coercion`) giving typer's own values.

The time itself is measured by ``bench/startup_bench.py``; these tests are about imports only.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from enum import Enum
from pathlib import Path
from typing import Any

import pytest

from tests.conftest import ROOT

HEAVY = ("numpy", "torch", "yaml", "gymnasium", "ray", "scipy", "matplotlib", "pydantic", "rich")
"""Packages that neither ``fmt`` nor ``compile`` needs."""

HEAVY_MITLC = ("mitlc.check", "mitlc.product", "mitlc.worlds", "mitlc.task", "mitlc.sweep",
               "mitlc.gym", "mitlc.labels", "mitlc.automata.lazy")  # fmt: skip
"""Parts of mitlc that neither needs (``mitlc.learn`` is checked apart: ``mitlc.learn.names``,
the learners' names for ``--algo``, is light)."""

PROBE = """
import json, sys
sys.argv = ["mitlc", *json.loads(sys.argv[1])]
from mitlc.cli import main
try:
    main()
except SystemExit as stop:
    code = stop.code
else:
    code = 0
sys.stderr.write("\\n" + json.dumps({"code": code, "modules": sorted(sys.modules)}))
"""


def modules_after(*argv: str) -> set[str]:
    """The modules imported by a fresh ``mitlc ARGV`` run (it must succeed)."""
    proc = subprocess.run(
        [sys.executable, "-c", PROBE, json.dumps(argv)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=True,
    )
    report = json.loads(proc.stderr.splitlines()[-1])
    assert report["code"] in (0, None), proc.stderr
    return set(report["modules"])


def imported(modules: set[str], package: str) -> list[str]:
    return sorted(m for m in modules if m == package or m.startswith(package + "."))


@pytest.mark.parametrize(
    "argv",
    [
        ("fmt", "-e", "a U[0,3] b"),
        ("fmt", str(ROOT / "specs" / "paper" / "case1.mitl")),
        ("compile", "-e", "a U[0,3] b"),
        ("compile", "-e", "a U[0,3] b", "--format", "hoa", "--max-states", "100"),
    ],
)
def test_fmt_and_compile_import_no_heavy_stack(argv: tuple[str, ...]) -> None:
    modules = modules_after(*argv)
    for package in (*HEAVY, *HEAVY_MITLC):
        assert not imported(modules, package), f"mitlc {' '.join(argv)} imports {package}"
    assert imported(modules, "mitlc.learn") in ([], ["mitlc.learn", "mitlc.learn.names"])
    if argv[0] == "fmt":
        assert not imported(modules, "mitlc.automata")
    else:
        assert "mitlc.automata" in modules


# --- typer's coercion, plain values first (mitlc.cli_coercion) ----------------------------

SAMPLES: dict[Any, list[Any]] = {
    str: ["x", "", " a U b ", "-", "ünï"],
    int: ["0", "1", "7", "007", "100", "101", "1000000", "-1", "1.5", "abc", " 5", "1_000",
          "+3", "99999999999999999999", 0, 5, 12345, True],
    float: ["0", "60", "0.5", "007.50", "-1", "1e3", "inf", "nan", "abc", ".5", "60.", 0, 60,
            60.0, 0.25, -1.0],
}  # fmt: skip
"""Values each annotation is coerced from (strings as given on the command line, numbers as
defaults)."""


def _outcome(runtime: Any, value: Any, param: Any, ctx: Any) -> tuple[str, Any]:
    """What a runtime parameter (typer's coercion of one parameter) makes of ``value``."""
    try:
        result = runtime.coerce(value, param=param, ctx=ctx)
    except Exception as err:  # the error typer reports, compared by type and message
        return ("error", (type(err).__name__, str(err)))
    return ("value", (type(result), result))


def _same(a: Any, b: Any) -> bool:
    """Equal outcomes, a NaN equal to a NaN (``--shield nan`` coerces to NaN both ways; the
    settings' bounds refuse it later)."""

    def is_nan(o: Any) -> bool:
        return o[0] == "value" and isinstance(o[1][1], float) and math.isnan(o[1][1])

    return bool(a == b or (is_nan(a) and is_nan(b) and a[1][0] is b[1][0]))


def test_plain_coercion_gives_typers_values_for_every_parameter() -> None:
    typer_coercion = pytest.importorskip("typer._coercion")
    from typer._click import Context
    from typer.main import get_command

    from mitlc.cli import app

    group = get_command(app)
    assert getattr(type(group.params[0]), "_mitlc_plain", False), "the coercion is not installed"
    checked = 0
    for name, command in group.commands.items():
        ctx = Context(command, info_name=name)
        for param in command.params:
            descriptor = param.type_descriptor
            annotation = descriptor.annotation
            values = [*SAMPLES.get(annotation, []), param.default, None]
            if isinstance(annotation, type) and issubclass(annotation, Enum):
                values += [*annotation, *(m.value for m in annotation), "JSON", "xml", 3]
            plain = param.get_runtime_param()
            full = typer_coercion.build_runtime_param(descriptor)
            for value in values:
                expected = _outcome(full, value, param, ctx)
                got = _outcome(plain, value, param, ctx)
                assert _same(got, expected), (name, param.name, value)
                checked += 1
    assert checked > 300


def test_a_path_option_still_goes_through_typer(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from mitlc.cli import app

    out = tmp_path / "a.json"
    result = CliRunner().invoke(app, ["compile", "-e", "F[0,2] a", "-o", str(out)])
    assert result.exit_code == 0, result.output
    assert json.loads(out.read_text())["formula"] == "F[0,2] a"
