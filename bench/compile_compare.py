"""Compile time of every formula of ``bench/formulas.txt`` under an older revision and now.

    .venv/bin/python bench/compile_compare.py [REV] [--rounds 9] [--seconds 0.1] [--only REGEX]

Checks out ``REV`` (default 7aba496, the compiler before symbolic letters) into a temporary
``git worktree`` (removed at the end) and times ``compile_formula`` (the formula parsed
beforehand, no time limit) in two long-lived child processes, one importing mitlc from that
tree and one from this working tree. Each round asks both children for each formula in turn,
one right after the other (which goes first alternates), so that the two measurements of a pair
see the same load on the machine. A child compiles the formula once untimed the first time,
then again and again until ``--seconds`` of process CPU time have passed, and reports the mean.

The table shows, per formula, the least mean of each side over the rounds, and two ratios
new/old: that of the least means, and the median over the rounds of each pair's ratio (the
*paired* ratio, which slow spells of the machine move least: both sides of a pair share them).
A formula is flagged when its paired ratio exceeds ``--flag`` (1.10). The locations of both
T-LDGBAs are shown (``*``: they differ).

Besides the file, the k-goal deadline sequences of ``--sequences`` (default 8,12) are timed
once, each in a child of its own; an old child is killed after ``--old-timeout`` seconds.
"""

from __future__ import annotations

import argparse
import json
import re
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

from symbolic_bench import deadline_sequence

ROOT = Path(__file__).resolve().parents[1]

CHILD = """
import json, sys, time
tree = sys.argv[1]
sys.path.insert(0, tree)
import mitlc
assert mitlc.__file__.startswith(tree), mitlc.__file__
from mitlc.automata import compile_formula
from mitlc.syntax import parse
seconds = float(sys.argv[2])
parsed = {}
for line in sys.stdin:
    text = json.loads(line)
    if text not in parsed:
        parsed[text] = parse(text)
        compiled = compile_formula(parsed[text], time_limit=None)
        locations = len(compiled.timed.locations)
    formula = parsed[text]
    runs, spent = 0, 0.0
    while runs == 0 or spent < seconds:
        start = time.process_time()
        compiled = compile_formula(formula, time_limit=None)
        spent += time.process_time() - start
        runs += 1
    print(json.dumps({"text": text, "seconds": spent / runs, "runs": runs,
                      "locations": len(compiled.timed.locations)}), flush=True)
"""


def formulas() -> list[str]:
    lines = (ROOT / "bench" / "formulas.txt").read_text(encoding="utf-8").splitlines()
    return [line.strip() for line in lines if line.strip() and not line.startswith("#")]


class Child:
    """A child process importing mitlc from one tree, timing one formula per request."""

    def __init__(self, tree: Path, seconds: float) -> None:
        self.tree = tree
        self.proc = subprocess.Popen(
            [sys.executable, "-c", CHILD, str(tree), str(seconds)],
            cwd=tree,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
        )

    def time(self, text: str) -> dict[str, Any]:
        stdin, stdout = self.proc.stdin, self.proc.stdout
        assert stdin is not None and stdout is not None
        stdin.write(json.dumps(text) + "\n")
        stdin.flush()
        line = stdout.readline()
        if not line:
            sys.exit(f"child in {self.tree} failed on {text!r}")
        row: dict[str, Any] = json.loads(line)
        return row

    def close(self) -> None:
        if self.proc.stdin is not None:
            self.proc.stdin.close()
        self.proc.wait(timeout=60)


def run_once(tree: Path, text: str, seconds: float, timeout: float) -> dict[str, Any] | None:
    """Time one (slow) formula in a child of its own; None when it ran past ``timeout``."""
    try:
        proc = subprocess.run(
            [sys.executable, "-c", CHILD, str(tree), str(seconds)],
            cwd=tree,
            input=json.dumps(text) + "\n",
            capture_output=True,
            text=True,
            timeout=timeout,
        )
    except subprocess.TimeoutExpired:
        return None
    if proc.returncode != 0:
        sys.exit(f"child in {tree} failed:\n{proc.stderr}")
    row: dict[str, Any] = json.loads(proc.stdout.splitlines()[-1])
    return row


def measure(
    trees: dict[str, Path], texts: list[str], rounds: int, seconds: float
) -> tuple[dict[str, dict[str, dict[str, Any]]], dict[str, list[float]]]:
    """The least mean per side and formula, and each formula's paired ratios per round."""
    best: dict[str, dict[str, dict[str, Any]]] = {"old": {}, "new": {}}
    paired: dict[str, list[float]] = {t: [] for t in texts}
    children = {side: Child(tree, seconds) for side, tree in trees.items()}
    try:
        for r in range(rounds):
            for i, text in enumerate(texts):
                order = ["old", "new"] if (r + i) % 2 == 0 else ["new", "old"]
                got = {side: children[side].time(text) for side in order}
                for side, row in got.items():
                    held = best[side].get(text)
                    if held is None or row["seconds"] < held["seconds"]:
                        best[side][text] = row
                paired[text].append(got["new"]["seconds"] / got["old"]["seconds"])
            print(f"round {r + 1}/{rounds} done", file=sys.stderr, flush=True)
    finally:
        for child in children.values():
            child.close()
    return best, paired


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("rev", nargs="?", default="7aba496")
    parser.add_argument("--rounds", type=int, default=9)
    parser.add_argument("--seconds", type=float, default=0.1, help="CPU time per measurement")
    parser.add_argument("--only", help="time only the formulas matching this regex")
    parser.add_argument("--sequences", default="8,12", help="k of the k-goal sequences timed")
    parser.add_argument("--old-timeout", type=float, default=120.0)
    parser.add_argument("--flag", type=float, default=1.10)
    args = parser.parse_args()

    texts = formulas()
    if args.only:
        texts = [t for t in texts if re.search(args.only, t)]
    sequences = [deadline_sequence(int(k)) for k in args.sequences.split(",") if k]
    names = {s: f"deadline sequence, {s.count(' U[')} goal(s)" for s in sequences}

    with tempfile.TemporaryDirectory(prefix="mitlc-old-") as tmp:
        old_tree = Path(tmp) / "tree"
        subprocess.run(
            ["git", "worktree", "add", "--detach", "--quiet", str(old_tree), args.rev],
            cwd=ROOT,
            check=True,
        )
        try:
            trees = {"old": old_tree, "new": ROOT}
            best, paired = measure(trees, texts, args.rounds, args.seconds)
            for text in sequences:  # slow for the old compiler: once, alone
                for side, timeout in (("old", args.old_timeout), ("new", 600.0)):
                    row = run_once(trees[side], text, args.seconds, timeout)
                    if row is not None:
                        best[side][text] = row
        finally:
            subprocess.run(
                ["git", "worktree", "remove", "--force", str(old_tree)], cwd=ROOT, check=False
            )

    print(
        f"compile_formula CPU ms, {args.rev} (old) vs working tree (new); least of "
        f"{args.rounds} interleaved rounds, each the mean of runs filling {args.seconds:g} s; "
        "paired: the median of the rounds' new/old ratios"
    )
    header = f"{'formula':64} {'old ms':>9} {'new ms':>9} {'least':>6} {'paired':>6} {'locs':>7}"
    print(header)
    print("-" * len(header))
    flagged = []
    for text in texts + sequences:
        old, new = best["old"].get(text), best["new"].get(text)
        old_ms = "timeout" if old is None else f"{1000 * old['seconds']:.3f}"
        new_ms = "-" if new is None else f"{1000 * new['seconds']:.3f}"
        least, pair, flag, locs = "-", "-", "", "-"
        if old is not None and new is not None:
            value = new["seconds"] / old["seconds"]
            least = f"{value:.2f}" if value >= 0.1 else f"{value:.3f}"
            if paired.get(text):
                median = statistics.median(paired[text])
                pair = f"{median:.2f}" if median >= 0.1 else f"{median:.3f}"
                if median > args.flag:
                    flag = f"  > {args.flag:.2f}"
                    flagged.append(text)
            same = old["locations"] == new["locations"]
            locs = f"{old['locations']}/{new['locations']}{'' if same else '*'}"
        elif new is not None:
            locs = f"?/{new['locations']}"
        name = names.get(text, text)
        print(f"{name[:64]:64} {old_ms:>9} {new_ms:>9} {least:>6} {pair:>6} {locs:>7}{flag}")
    print(
        f"{len(flagged)} of {len(texts)} formulas of the file slower than old by more than "
        f"{100 * (args.flag - 1):.0f}% (paired ratio)"
        + (": " + "; ".join(flagged) if flagged else "")
    )


if __name__ == "__main__":
    main()
