"""``mitlc render`` within the command's limits (issue 42): a drawing too large to be read is
refused before Graphviz starts (``--max-states``), and Graphviz itself runs within the time left
to the command and the memory left under its limit (:func:`mitlc.limits.run_within`).

Graphviz is replaced by a fake ``dot`` on ``PATH`` (a shell script) wherever its own speed would
make a test slow or uncertain."""

from __future__ import annotations

import math
import os
import resource
import time
from pathlib import Path

import pytest
from typer.testing import CliRunner

from mitlc.automata import compile_formula
from mitlc.automata.artifact import to_json
from mitlc.automata.dot import render
from mitlc.cli import app
from mitlc.limits import DEFAULT_MAX_DRAWN_STATES, GB, LimitError, resident_bytes
from mitlc.syntax import parse
from tests.conftest import ROOT

runner = CliRunner()
CASE1 = str(ROOT / "specs" / "paper" / "case1.mitl")
NESTED = "F[0,5] " * 60 + "a"
"""The issue's formula: 60 nested windows, 121 states and 595 edges, which Graphviz did not lay
out in two minutes."""


def fake_dot(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, body: str) -> Path:
    """Put a ``dot`` running the shell ``body`` first on ``PATH``; its folder."""
    folder = tmp_path / "bin"
    folder.mkdir(exist_ok=True)
    script = folder / "dot"
    script.write_text(f"#!/bin/sh\n{body}\n", encoding="utf-8")
    script.chmod(0o755)
    monkeypatch.setenv("PATH", f"{folder}{os.pathsep}{os.environ.get('PATH', '')}")
    return folder


def one_line(output: str) -> str:
    lines = output.strip().splitlines()
    assert len(lines) == 1, output
    assert "Traceback" not in output
    return lines[0]


def test_the_nested_windows_are_refused_before_graphviz_starts(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    started = tmp_path / "started"
    fake_dot(tmp_path, monkeypatch, f"touch {started}; cat")
    out = tmp_path / "a.svg"
    begin = time.monotonic()
    result = runner.invoke(app, ["render", "-e", NESTED, "-o", str(out)])
    seconds = time.monotonic() - begin
    assert result.exit_code == 1
    line = one_line(result.output)
    assert line.startswith(
        f"the automaton has 121 states, more than --max-states {DEFAULT_MAX_DRAWN_STATES}"
    )
    assert "raise the limit with a larger --max-states" in line
    assert seconds < 20  # the compile (about a second), never a layout
    assert not started.exists() and not out.exists()


def test_an_artifact_is_refused_too_and_a_dot_file_written_at_any_size(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    started = tmp_path / "started"
    fake_dot(tmp_path, monkeypatch, f"touch {started}; cat")
    artifact = tmp_path / "nested.json"
    artifact.write_text(to_json(compile_formula(parse(NESTED)).timed), encoding="utf-8")
    refused = runner.invoke(app, ["render", str(artifact), "-o", str(tmp_path / "a.png")])
    assert refused.exit_code == 1
    assert "121 states, more than --max-states" in one_line(refused.output)
    small = runner.invoke(
        app, ["render", str(artifact), "-o", str(tmp_path / "b.png"), "--max-states", "10"]
    )
    assert small.exit_code == 1 and "more than --max-states 10 " in small.output
    text = runner.invoke(app, ["render", str(artifact), "-o", str(tmp_path / "a.dot")])
    assert text.exit_code == 0, text.output
    assert (tmp_path / "a.dot").read_text(encoding="utf-8").startswith("digraph")
    assert not started.exists()
    allowed = runner.invoke(
        app, ["render", str(artifact), "-o", str(tmp_path / "c.svg"), "--max-states", "121"]
    )
    assert allowed.exit_code == 0, allowed.output
    assert started.exists()  # the fake Graphviz drew it (it copies its input)


def roomy_limit() -> int:
    """A memory limit in whole GB a gigabyte above what this process holds (the test run may
    hold a lot by now)."""
    return math.ceil(resident_bytes() / GB) + 1


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return False
    return state != "Z"


def test_a_slow_graphviz_is_stopped_at_the_time_limit_with_its_group(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    pid_file = tmp_path / "sleep.pid"
    # The shell waits on a child of its own: killing the shell alone would leave the child
    # holding the output pipe open, and the command waiting for it.
    fake_dot(tmp_path, monkeypatch, f"sleep 30 & echo $! > {pid_file}; wait")
    out = tmp_path / "a.svg"
    begin = time.monotonic()
    result = runner.invoke(app, ["render", CASE1, "-o", str(out), "--time-limit", "1"])
    seconds = time.monotonic() - begin
    assert result.exit_code == 1
    assert one_line(result.output) == (
        "mitlc render stopped at the time limit of 1 s (during Graphviz's layout); "
        "raise it with --time-limit SECONDS (0 for none)"
    )
    assert 0.9 < seconds < 5
    assert not out.exists()
    pid = int(pid_file.read_text())
    for _ in range(100):
        if not _alive(pid):
            break
        time.sleep(0.02)
    assert not _alive(pid)


def test_the_library_render_has_a_time_limit_of_its_own(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    fake_dot(tmp_path, monkeypatch, "exec sleep 30")
    with pytest.raises(LimitError, match=r"time limit of 0\.5 s \(during Graphviz's layout\)"):
        render("digraph { a -> b }\n", tmp_path / "a.png", time_limit=0.5)


@pytest.mark.skipif(not hasattr(resource, "prlimit"), reason="no prlimit (Linux only)")
def test_graphviz_runs_under_the_memory_left_to_the_command(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    fake_dot(tmp_path, monkeypatch, "cat > /dev/null; ulimit -v")  # reads, then says its cap
    out = tmp_path / "a.svg"
    limit = roomy_limit()
    result = runner.invoke(app, ["render", CASE1, "-o", str(out), "--memory-limit", str(limit)])
    assert result.exit_code == 0, result.output
    kib = int(out.read_text(encoding="utf-8"))
    left = (limit * GB - resident_bytes()) // 1024  # the limit less what this process holds
    assert abs(kib - left) < 256 * 1024
    none = runner.invoke(app, ["render", CASE1, "-o", str(out), "--memory-limit", "0"])
    assert none.exit_code == 0, none.output
    assert out.read_text(encoding="utf-8").strip() == "unlimited"


@pytest.mark.skipif(not hasattr(resource, "prlimit"), reason="no prlimit (Linux only)")
def test_graphviz_failing_under_its_cap_stops_at_the_memory_limit(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # What a failed allocation looked like in the real `dot` under `ulimit -v`: SIGSEGV, or
    # GLib's "Error creating thread: Resource temporarily unavailable" and SIGTRAP.
    fake_dot(tmp_path, monkeypatch, "cat > /dev/null; kill -SEGV $$")
    limit = roomy_limit()
    result = runner.invoke(
        app, ["render", CASE1, "-o", str(tmp_path / "a.svg"), "--memory-limit", str(limit)]
    )
    assert result.exit_code == 1
    line = one_line(result.output)
    assert line.startswith(
        f"mitlc render stopped at the memory limit of {limit} GB (during Graphviz's layout): "
        "Graphviz was killed by SIGSEGV within the "
    )
    assert line.endswith("raise it with --memory-limit GB (0 for none)")


def test_graphviz_failing_otherwise_or_missing_is_one_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    fake_dot(tmp_path, monkeypatch, "cat > /dev/null; echo 'Error: <stdin>: syntax' >&2; exit 3")
    failed = runner.invoke(app, ["render", CASE1, "-o", str(tmp_path / "a.svg")])
    assert failed.exit_code == 1
    assert one_line(failed.output) == "Graphviz exited with status 3: Error: <stdin>: syntax"
    empty = tmp_path / "empty"
    empty.mkdir()
    monkeypatch.setenv("PATH", str(empty))
    missing = runner.invoke(app, ["render", CASE1, "-o", str(tmp_path / "a.svg")])
    assert missing.exit_code == 1
    assert "Graphviz's `dot` was not found" in one_line(missing.output)
