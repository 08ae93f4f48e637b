"""Compiling specs: golden artifacts, canonical output, sizes, and the compile/render/monitor
commands."""

from __future__ import annotations

import json
import os
import stat
import subprocess
import sys
import threading
from pathlib import Path

import pytest
from typer.testing import CliRunner

from mitlc.automata import compile_formula
from mitlc.automata.artifact import from_data, to_json
from mitlc.automata.dot import to_dot
from mitlc.cli import app
from mitlc.files import write_atomically
from mitlc.syntax import parse, parse_file
from tests.conftest import GOLDEN, ROOT, check_golden

SPECS = sorted((ROOT / "specs").rglob("*.mitl"))
BENCHMARK = ROOT / "bench" / "formulas.txt"
runner = CliRunner()


def benchmark_formulas() -> list[str]:
    lines = BENCHMARK.read_text(encoding="utf-8").splitlines()
    return [line for line in lines if line.strip() and not line.startswith("#")]


@pytest.mark.parametrize("path", SPECS, ids=[p.stem for p in SPECS])
def test_spec_artifacts_match_golden(path: Path, update_golden: bool) -> None:
    timed = compile_formula(parse_file(path)).timed
    check_golden(GOLDEN / "automata" / f"{path.stem}.json", to_json(timed), update_golden)
    check_golden(GOLDEN / "automata" / f"{path.stem}.dot", to_dot(timed), update_golden)


def test_benchmark_sizes_match_golden(update_golden: bool) -> None:
    formulas = benchmark_formulas()
    assert len(formulas) >= 40
    rows = {}
    for text in formulas:
        compiled = compile_formula(parse(text))
        rows[text] = {
            "locations": len(compiled.timed.locations),
            "clocks": len(compiled.timed.clock_bounds),
            "edges": len(compiled.timed.edges),
            "digital_states": len(compiled.digital.states),
            "acceptance_sets": compiled.digital.num_sets,
            "deterministic": compiled.digital.is_deterministic,
        }
    text = json.dumps(rows, indent=2, ensure_ascii=False) + "\n"
    check_golden(GOLDEN / "sizes.json", text, update_golden)


def test_artifact_round_trips() -> None:
    for text in benchmark_formulas()[:20]:
        timed = compile_formula(parse(text)).timed
        assert to_json(from_data(json.loads(to_json(timed)))) == to_json(timed)


def test_output_is_byte_identical_across_processes(tmp_path: Path) -> None:
    """Hash randomisation must not leak into the artifact."""
    outputs = []
    for seed in ("1", "2", "3"):
        env = {**os.environ, "PYTHONHASHSEED": seed}
        proc = subprocess.run(
            [sys.executable, "-m", "mitlc", "compile", "--batch", str(BENCHMARK)],
            capture_output=True,
            env=env,
            check=True,
        )
        outputs.append(proc.stdout)
    assert outputs[0] == outputs[1] == outputs[2]
    assert outputs[0].count(b"\n") == len(benchmark_formulas())


def test_compile_formats_and_errors(tmp_path: Path) -> None:
    case1 = str(ROOT / "specs" / "paper" / "case1.mitl")
    data = json.loads(runner.invoke(app, ["compile", case1]).output)
    assert data["format"] == "mitlc.tldgba/1"
    assert data["propositions"] == ["a", "b"]
    assert runner.invoke(app, ["compile", case1, "-f", "dot"]).output.startswith("digraph")
    assert runner.invoke(app, ["compile", case1, "-f", "hoa"]).output.startswith("HOA: v1")
    out = tmp_path / "case1.json"
    assert runner.invoke(app, ["compile", case1, "-o", str(out)]).exit_code == 0
    assert json.loads(out.read_text(encoding="utf-8")) == data
    too_big = runner.invoke(app, ["compile", "-e", "G (a -> F[5,10] b)", "--max-states", "50"])
    assert too_big.exit_code == 1 and "--max-states 50" in too_big.output
    assert "Traceback" not in too_big.output


def test_batch_reports_the_failing_line(tmp_path: Path) -> None:
    batch = tmp_path / "formulas.txt"
    batch.write_text("G F a\n# a comment\n\nF[0,3 a\n", encoding="utf-8")
    result = runner.invoke(app, ["compile", "--batch", str(batch)])
    assert result.exit_code == 1
    assert f"{batch}:4:7:" in result.output
    batch.write_text("G F a\nF[0,3] a\n", encoding="utf-8")
    lines = runner.invoke(app, ["compile", "--batch", str(batch)]).output.splitlines()
    assert [json.loads(line)["source"] for line in lines] == ["G F a", "F[0,3] a"]
    hoa = runner.invoke(app, ["compile", "--batch", str(batch), "-f", "hoa"]).output
    assert hoa.count("--END--") == 2


def test_render_png_svg_dot_and_from_artifact(tmp_path: Path) -> None:
    case1 = str(ROOT / "specs" / "paper" / "case1.mitl")
    for name in ("a.png", "a.svg", "a.dot"):
        result = runner.invoke(app, ["render", case1, "-o", str(tmp_path / name)])
        assert result.exit_code == 0, result.output
    assert (tmp_path / "a.png").read_bytes().startswith(b"\x89PNG")
    assert b"<svg" in (tmp_path / "a.svg").read_bytes()
    artifact = tmp_path / "case1.json"
    runner.invoke(app, ["compile", case1, "-o", str(artifact)])
    result = runner.invoke(app, ["render", str(artifact), "-o", str(tmp_path / "b.dot")])
    assert result.exit_code == 0
    assert (tmp_path / "b.dot").read_text(encoding="utf-8") == (tmp_path / "a.dot").read_text(
        encoding="utf-8"
    )
    bad = runner.invoke(app, ["render", case1, "-o", str(tmp_path / "a.gif")])
    assert bad.exit_code == 1 and "unknown output format" in bad.output


def test_monitor_verdicts(tmp_path: Path) -> None:
    case1 = str(ROOT / "specs" / "paper" / "case1.mitl")
    rows = ["a,b"] + ["0,0"] * 7 + ["1,0"] + ["0,0"] * 8 + ["0,1"]
    trace = tmp_path / "trace.csv"
    trace.write_text("\n".join(rows) + "\n", encoding="utf-8")
    result = runner.invoke(app, ["monitor", case1, str(trace), "--json"])
    verdicts = [json.loads(line)["verdict"] for line in result.output.splitlines()]
    assert verdicts == ["pending"] * 16 + ["satisfied"]  # a at step 7, b at step 16
    early = tmp_path / "early.jsonl"
    early.write_text('[]\n["a"]\n[]\n', encoding="utf-8")
    result = runner.invoke(app, ["monitor", case1, str(early), "--json"])
    assert [json.loads(line)["verdict"] for line in result.output.splitlines()] == [
        "pending",
        "violated",
        "violated",
    ]
    missing = tmp_path / "missing.csv"
    missing.write_text("a\n0\n", encoding="utf-8")
    result = runner.invoke(app, ["monitor", case1, str(missing)])
    assert result.exit_code == 1 and "no column" in result.output and "b" in result.output
    broken = tmp_path / "broken.csv"
    broken.write_text("a,b\n0,2\n", encoding="utf-8")
    result = runner.invoke(app, ["monitor", case1, str(broken)])
    assert result.exit_code == 1 and f"{broken}:2:" in result.output


def test_atomic_writes_replace_whole_files_with_the_usual_permissions(tmp_path: Path) -> None:
    from mitlc.files import write_atomically

    target = tmp_path / "deep" / "out.json"
    old = os.umask(0o027)
    try:
        write_atomically(target, b"first")
        write_atomically(target, b"second")
    finally:
        os.umask(old)
    assert target.read_bytes() == b"second"
    assert target.stat().st_mode & 0o777 == 0o640
    assert [p.name for p in target.parent.iterdir()] == ["out.json"]  # no temporary left


def test_output_to_a_device_or_pipe_is_written_in_place(tmp_path: Path) -> None:
    # `-o /dev/null` once renamed a regular file over /dev/null (as root): a path that is not a
    # regular file is written into, never replaced. A named pipe stands in for the device.
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    received: list[bytes] = []
    reader = threading.Thread(target=lambda: received.append(fifo.read_bytes()))
    reader.start()
    write_atomically(fifo, b"through the pipe\n")
    reader.join(timeout=10)
    assert received == [b"through the pipe\n"]
    assert stat.S_ISFIFO(fifo.lstat().st_mode)
    with pytest.raises(IsADirectoryError):
        write_atomically(tmp_path, b"x")
    regular = tmp_path / "out.json"
    write_atomically(regular, b"1\n")
    write_atomically(regular, b"2\n")
    assert regular.read_bytes() == b"2\n" and stat.S_ISREG(regular.lstat().st_mode)
