"""The memory limit beside the time limit (issue 26): every command takes ``--memory-limit``,
the library's entry points take ``memory_limit``, the long loops look at the resident size,
a watchdog stops what they cannot, and the time limit is looked at inside one state's
transitions. A tiny limit stands in for an explosive formula: the process already holds more
than it, so the first look stops the work, with the message a real run would end with."""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest
import typer

from mitlc.automata import compile_formula
from mitlc.cli import app
from mitlc.limits import (
    CLI_MEMORY_HOW,
    GB,
    LIBRARY_MEMORY_HOW,
    Deadline,
    LimitError,
    memory_limit,
    memory_setting,
    resident_bytes,
    set_memory_limit,
)
from mitlc.syntax import parse

ROOT = Path(__file__).resolve().parents[1]
START = time.monotonic()
TINY = "0.02"  # GB: less than any Python process holds with mitlc imported
EXPLOSIVE = "F[0,1000] G[0,1000] a"  # about a million states of hundreds of atoms each


def _mitlc(*args: str, timeout: float = 120) -> subprocess.CompletedProcess[str]:
    """The command in a process of its own (the watchdog ends the process it runs in)."""
    return subprocess.run(
        [sys.executable, "-m", "mitlc", *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        cwd=ROOT,
    )


PEAK_SCRIPT = """
import atexit, os, sys

def peak():  # the high-water mark of this process's own memory, set anew at exec
    with open("/proc/self/status") as status, open(os.environ["PEAK_FILE"], "w") as out:
        out.write(next(line.split()[1] for line in status if line.startswith("VmHWM")))

atexit.register(peak)
real_exit = os._exit  # a command stopped at a limit ends at once, without atexit


def exit_now(code):
    peak()
    real_exit(code)


os._exit = exit_now
sys.argv = ["mitlc", *sys.argv[1:]]
from mitlc.cli import main
main()
"""


def _run_measured(
    args: list[str], timeout: float
) -> tuple[subprocess.CompletedProcess[str], float]:
    """Run ``mitlc ARGS``; its result and the peak resident size of its own process in GB
    (the kernel's ``VmHWM`` at exit: ``ru_maxrss`` would count the memory of the test process
    it was forked from)."""
    with tempfile.NamedTemporaryFile("r") as peak:
        done = subprocess.run(
            [sys.executable, "-c", PEAK_SCRIPT, *args],
            capture_output=True,
            text=True,
            timeout=timeout,
            cwd=ROOT,
            env={**os.environ, "PEAK_FILE": peak.name},
        )
        return done, int(peak.read() or 0) * 1024 / GB


def _one_line(stderr: str) -> str:
    lines = [line for line in stderr.splitlines() if line.strip()]
    assert len(lines) == 1, stderr
    assert "Traceback" not in stderr
    return lines[0]


def test_every_command_takes_a_memory_limit() -> None:
    group = typer.main.get_command(app)
    assert isinstance(group, typer.core.TyperGroup)
    missing = [
        name
        for name, command in group.commands.items()
        if "--memory-limit" not in {opt for p in command.params for opt in p.opts}
    ]
    assert not missing, f"commands without --memory-limit: {missing}"


@pytest.mark.parametrize(
    ("command", "stage"),
    [
        (("compile", "-e", EXPLOSIVE, "-o", "/dev/null"), "translation"),
        (("check", "specs/paper/case1.yaml", "-e", EXPLOSIVE), "the product build"),
    ],
)
def test_an_explosive_formula_stops_at_the_memory_limit(
    command: tuple[str, ...], stage: str
) -> None:
    # 0.1 GB: above what a command holds when it starts, so the formula's own growth (about
    # 20 MB a second) reaches it; the library's check stops it, not the watchdog.
    done, peak = _run_measured([*command, "--memory-limit", "0.1"], 120)
    assert done.returncode == 1
    line = done.stderr.splitlines()[-1]
    assert "Traceback" not in done.stderr
    assert f"mitlc {command[0]} stopped at the memory limit of 0.1 GB" in line, line
    assert f"during {stage}" in line
    assert "--memory-limit GB (0 for none)" in line
    assert 0.05 < peak < 0.1 * 1.1, peak  # it grew to the limit, and no further


def test_a_command_that_starts_past_its_limit_stops_at_once() -> None:
    done = _mitlc("check", "specs/paper/case1.yaml", "--memory-limit", TINY)
    assert done.returncode == 1
    line = _one_line(done.stderr)
    assert "mitlc check stopped at the memory limit of 0.02 GB" in line, line


def test_without_a_memory_limit_the_command_runs() -> None:
    done = _mitlc("compile", "-e", "F[0,3] a", "--memory-limit", "0", "-o", "/dev/null")
    assert done.returncode == 0, done.stderr


def test_the_watchdog_stops_memory_taken_outside_mitlc_loops() -> None:
    # One allocation in a library call, where no loop of mitlc's looks: the watchdog ends the
    # process with one line and status 1.
    script = (
        "import time\n"
        "from mitlc.cli_memory import _Watchdog\n"
        "from mitlc.limits import resident_bytes\n"
        "dog = _Watchdog((resident_bytes() + 50_000_000) / 1e9)\n"
        "block = bytearray(300_000_000)\n"
        "block[::4096] = b'x' * len(block[::4096])\n"
        "time.sleep(5)\n"
        "print('not stopped')\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 1
    assert "not stopped" not in done.stdout
    assert "stopped at the memory limit" in _one_line(done.stderr)


def test_the_library_takes_a_memory_limit() -> None:
    with pytest.raises(LimitError, match=r"memory limit of 0.02 GB.*memory_limit argument"):
        compile_formula(parse(EXPLOSIVE), memory_limit=float(TINY))
    # None: no limit (the small formula compiles)
    compile_formula(parse("F[0,5] a"), memory_limit=None)


def test_a_deadline_takes_the_commands_memory_limit_by_default() -> None:
    assert Deadline(None, "x").memory == memory_limit()
    assert Deadline(None, "x", memory=None).memory is None
    assert Deadline.none().memory is None


def test_reserve_refuses_what_would_pass_the_limit() -> None:
    deadline = Deadline(None, "the product build", memory=(resident_bytes() + GB) / GB)
    deadline.reserve(1000, "a small table")  # fits
    with pytest.raises(LimitError, match=r"a big table would take about 2\.0 GB more"):
        deadline.reserve(2 * GB, "a big table")


def test_the_time_limit_is_looked_at_inside_one_states_transitions() -> None:
    # The progression of one state of 20 independent eventualities is a long computation of its
    # own (decision diagrams over 20 propositions); it used to run 38 s past a 5 s limit.
    wide = parse(" & ".join(f"F p{i}" for i in range(20)))
    start = time.monotonic()
    with pytest.raises(LimitError, match=r"time limit of 0\.5 s"):
        compile_formula(wide, time_limit=0.5, memory_limit=None)
    assert time.monotonic() - start < 2.0


def test_a_library_deadline_inside_a_command_says_how_the_command_raises_it() -> None:
    # `mitlc plot` sets its run up through the library: the message must name --memory-limit.
    before = memory_setting()
    try:
        set_memory_limit(0.5, CLI_MEMORY_HOW)
        inside = Deadline.of(None, 60, "setting up the run")
        assert (inside.memory, inside.memory_how) == (0.5, CLI_MEMORY_HOW)
    finally:
        set_memory_limit(*before)
    outside = Deadline.of(None, 60, "setting up the run")
    assert outside.memory_how == LIBRARY_MEMORY_HOW


def test_a_command_stops_at_its_time_limit_counted_from_its_start() -> None:
    # The wide formula through the command line: the limit counts the process's start-up, the
    # stop is looked at inside one state's transitions, and the process ends without tearing
    # down what it built (it used to run 38 s past a 5 s limit).
    wide = " & ".join(f"F p{i}" for i in range(62))
    start = time.monotonic()
    done = _mitlc(
        "compile", "-e", wide, "--time-limit", "3", "--memory-limit", "0", "-o", "/dev/null"
    )
    seconds = time.monotonic() - start
    assert done.returncode == 1
    assert "mitlc compile stopped at the time limit of 3 s (during translation)" in _one_line(
        done.stderr
    )
    assert seconds < 3 + 1.5, seconds


def test_a_command_run_in_a_longer_lived_process_counts_its_time_from_its_own_start() -> None:
    # This test process has lived longer than the limit: a command it runs (as a test, or a
    # program, through typer's runner) has the whole limit all the same.
    from typer.testing import CliRunner

    time.sleep(max(0.0, 1.5 - time.monotonic() + START))
    done = CliRunner().invoke(
        app, ["compile", "-e", "F[0,3] a", "--time-limit", "1", "-o", "/dev/null"]
    )
    assert done.exit_code == 0, done.output
