"""Compile time of every formula of ``bench/formulas.txt`` under an older revision and now.

    .venv/bin/python bench/compile_compare.py [REV] [--rounds 5] [--seconds 0.2] [--only REGEX]

Checks out ``REV`` (default 7aba496, the compiler before symbolic letters) into a temporary
``git worktree`` (removed at the end) and times ``compile_formula`` (the formula parsed
beforehand, no time limit) in child processes, one importing mitlc from that tree and one from
this working tree. The formulas go in chunks, and for each round and chunk the old and the new
child run one after the other (which goes first alternates), so that load on the machine falls
on both alike. A child compiles each formula once untimed, then again and again until
``--seconds`` of process CPU time have passed, and reports the mean; the table shows the least
mean over the rounds, the ratio new/old, and flags ratios above ``--flag`` (1.10). It also
shows the locations of both T-LDGBAs (``*``: they differ).

Besides the file, the k-goal deadline sequences of ``--sequences`` (default 8,12) are timed; a
formula that takes the old compiler more than ``--slow`` seconds is timed in the first round
only, and an old child is killed after ``--old-timeout`` seconds.
"""

from __future__ import annotations

import argparse
import json
import re
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
for text in json.loads(sys.stdin.read()):
    formula = parse(text)
    compiled = compile_formula(formula, time_limit=None)
    runs, spent = 0, 0.0
    while runs == 0 or spent < seconds:
        start = time.process_time()
        compile_formula(formula, time_limit=None)
        spent += time.process_time() - start
        runs += 1
    print(json.dumps({"text": text, "seconds": spent / runs, "runs": runs,
                      "locations": len(compiled.timed.locations)}), flush=True)
"""


def formulas() -> list[str]:
    lines = (ROOT / "bench" / "formulas.txt").read_text(encoding="utf-8").splitlines()
    return [line.strip() for line in lines if line.strip() and not line.startswith("#")]


def run_child(tree: Path, texts: list[str], seconds: float, timeout: float) -> list[dict[str, Any]]:
    """Time ``texts`` in a child importing mitlc from ``tree``; those done before a timeout."""
    command = [sys.executable, "-c", CHILD, str(tree), str(seconds)]
    try:
        proc = subprocess.run(
            command,
            cwd=tree,
            input=json.dumps(texts),
            capture_output=True,
            text=True,
            timeout=timeout,
        )
        out, err, failed = proc.stdout, proc.stderr, proc.returncode != 0
    except subprocess.TimeoutExpired as exc:
        out = exc.stdout.decode() if isinstance(exc.stdout, bytes) else exc.stdout or ""
        err, failed = "", False
    if failed:
        sys.exit(f"child in {tree} failed:\n{err}")
    return [json.loads(line) for line in out.splitlines() if line.strip()]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("rev", nargs="?", default="7aba496")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--seconds", type=float, default=0.2, help="CPU time per formula a child")
    parser.add_argument("--chunk", type=int, default=6, help="formulas per child")
    parser.add_argument("--only", help="time only the formulas matching this regex")
    parser.add_argument("--sequences", default="8,12", help="k of the k-goal sequences timed")
    parser.add_argument("--slow", type=float, default=2.0)
    parser.add_argument("--old-timeout", type=float, default=120.0)
    parser.add_argument("--flag", type=float, default=1.10)
    args = parser.parse_args()

    texts = formulas()
    sequences = [deadline_sequence(int(k)) for k in args.sequences.split(",") if k]
    if args.only:
        texts = [t for t in texts if re.search(args.only, t)]
    chunks = [texts[i : i + args.chunk] for i in range(0, len(texts), args.chunk)]
    chunks += [[s] for s in sequences]  # alone: a timeout loses only that one
    names = {s: f"deadline sequence, {s.count(' U[')} goal(s)" for s in sequences}

    best: dict[str, dict[str, dict[str, Any]]] = {"old": {}, "new": {}}
    with tempfile.TemporaryDirectory(prefix="mitlc-old-") as tmp:
        old_tree = Path(tmp) / "tree"
        subprocess.run(
            ["git", "worktree", "add", "--detach", "--quiet", str(old_tree), args.rev],
            cwd=ROOT,
            check=True,
        )
        try:
            trees = {"old": old_tree, "new": ROOT}
            slow: set[str] = set()
            for r in range(args.rounds):
                for c, chunk in enumerate(chunks):
                    order = ["old", "new"] if (r + c) % 2 == 0 else ["new", "old"]
                    for side in order:
                        todo = [t for t in chunk if r == 0 or t not in slow]
                        if not todo:
                            continue
                        timeout = args.old_timeout if side == "old" else 600.0
                        for row in run_child(trees[side], todo, args.seconds, timeout):
                            held = best[side].get(row["text"])
                            if held is None or row["seconds"] < held["seconds"]:
                                best[side][row["text"]] = row
                        if side == "old":  # past --slow or killed: first round only
                            slow.update(
                                t
                                for t in todo
                                if t not in best["old"] or best["old"][t]["seconds"] > args.slow
                            )
                print(f"round {r + 1}/{args.rounds} done", file=sys.stderr, flush=True)
        finally:
            subprocess.run(
                ["git", "worktree", "remove", "--force", str(old_tree)], cwd=ROOT, check=False
            )

    print(
        f"compile_formula CPU ms, {args.rev} (old) vs working tree (new); least of "
        f"{args.rounds} rounds, each the mean of runs filling {args.seconds:g} s"
    )
    header = f"{'formula':64} {'old ms':>9} {'new ms':>9} {'ratio':>6} {'locs':>9}"
    print(header)
    print("-" * len(header))
    flagged = []
    for text in texts + sequences:
        old, new = best["old"].get(text), best["new"].get(text)
        old_ms = "timeout" if old is None else f"{1000 * old['seconds']:.3f}"
        new_ms = "-" if new is None else f"{1000 * new['seconds']:.3f}"
        ratio, flag, locs = "-", "", "-"
        if old is not None and new is not None:
            value = new["seconds"] / old["seconds"]
            ratio = f"{value:.2f}" if value >= 0.1 else f"{value:.3f}"
            if value > args.flag:
                flag = f"  > {args.flag:.2f}"
                flagged.append(text)
            same = old["locations"] == new["locations"]
            locs = f"{old['locations']}/{new['locations']}{'' if same else '*'}"
        elif new is not None:
            locs = f"?/{new['locations']}"
        name = names.get(text, text)
        print(f"{name[:64]:64} {old_ms:>9} {new_ms:>9} {ratio:>6} {locs:>9}{flag}")
    print(
        f"{len(flagged)} of {len(texts) + len(sequences)} slower than old by more than "
        f"{100 * (args.flag - 1):.0f}%" + (": " + "; ".join(flagged) if flagged else "")
    )


if __name__ == "__main__":
    main()
