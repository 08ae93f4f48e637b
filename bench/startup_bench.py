"""The command line's start-up: process CPU time of small ``mitlc`` commands beside bare Python.

Runs each command ``--repeats`` times in a fresh process (round-robin, so load on the machine
hits every command alike) and prints the median CPU time of the child (user + sys, from
``getrusage(RUSAGE_CHILDREN)``) and its least (what a run costs when nothing else on the
machine slows it), the median wall time, and the median CPU time as a multiple of ``python -c
pass``. Target (issue 15): ``mitlc fmt`` and ``mitlc compile`` of a small formula under 0.2 s
of CPU.

The children compile their bytecode once, into a temporary ``PYTHONPYCACHEPREFIX``, before
they are timed (an installed package has its bytecode; a checkout run with
``PYTHONDONTWRITEBYTECODE`` would otherwise recompile mitlc's sources on every start);
``--as-is`` runs them with this environment unchanged instead.

    .venv/bin/python bench/startup_bench.py [--repeats 10] [--as-is]
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

FORMULA = "a U[0,3] b"


def commands() -> dict[str, list[str]]:
    """The commands timed, by name; ``mitlc`` is the console script beside this Python."""
    python = sys.executable
    script = Path(python).with_name("mitlc")
    mitlc = [str(script)] if script.is_file() else [python, "-m", "mitlc"]
    return {
        "python -c pass": [python, "-c", "pass"],
        "python -c 'import mitlc.cli'": [python, "-c", "import mitlc.cli"],
        f"mitlc fmt -e '{FORMULA}'": [*mitlc, "fmt", "-e", FORMULA],
        f"mitlc compile -e '{FORMULA}' (JSON)": [*mitlc, "compile", "-e", FORMULA],
        "mitlc --help": [*mitlc, "--help"],
    }


def run_once(argv: list[str], env: dict[str, str]) -> tuple[float, float]:
    """CPU seconds (user + sys) and wall seconds of one run of ``argv``; it must succeed."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run(argv, env=env, capture_output=True)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(argv)} failed ({done.returncode}):\n{done.stderr.decode()}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return cpu, wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=10)
    parser.add_argument(
        "--as-is", action="store_true", help="Run with this environment's bytecode settings."
    )
    args = parser.parse_args()
    env = dict(os.environ)
    with tempfile.TemporaryDirectory(prefix="mitlc-startup-") as cache:
        if not args.as_is:
            env.pop("PYTHONDONTWRITEBYTECODE", None)
            env["PYTHONPYCACHEPREFIX"] = cache
        named = commands()
        for argv in named.values():  # warm-up: bytecode compiled, files in the page cache
            run_once(argv, env)
        cpu: dict[str, list[float]] = {name: [] for name in named}
        wall: dict[str, list[float]] = {name: [] for name in named}
        for _ in range(args.repeats):
            for name, argv in named.items():
                c, w = run_once(argv, env)
                cpu[name].append(c)
                wall[name].append(w)
    base = statistics.median(cpu["python -c pass"])
    header = f"{'command':42} {'CPU ms':>7} {'least':>6} {'wall ms':>8} {'x python':>9}"
    print(f"{header}   (median of {args.repeats})")
    for name in named:
        c, w = statistics.median(cpu[name]), statistics.median(wall[name])
        least = min(cpu[name])
        print(f"{name:42} {c * 1e3:7.0f} {least * 1e3:6.0f} {w * 1e3:8.0f} {c / base:9.1f}")


if __name__ == "__main__":
    main()
