"""mitlc's DQN beside Stable-Baselines3's DQN and PPO, one run each, on the same wrapped env and
the same number of environment steps: greedy success with its 95% interval, and wall time.

mitlc's DQN trains first for ``--episodes`` episodes; its step count (from ``summary.json``)
is the budget the SB3 runs get (``sb3.steps``). Each run goes through the command line into
its own run directory (``mitlc train``, then ``mitlc eval --json``), as a user would run them.
Wall time is the ``train`` process's. The figures to compare (issue 13): mitlc's DQN should
reach at least SB3's best greedy success at the same number of env steps in at most a third of
SB3's wall time.

``--set KEY=VALUE`` (repeatable, as ``mitlc train --set``) goes to mitlc's DQN run only, e.g.
``--set dqn.crm=true``; the SB3 runs keep their defaults.

    .venv/bin/python bench/sb3_bench.py [--world specs/paper/case1.yaml] [--episodes 40000]
        [--set dqn.KEY=VALUE ...]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MITLC = [sys.executable, "-m", "mitlc"]


def train(world: str, out: Path, algo: str, settings: list[str]) -> float:
    """Seconds of one ``mitlc train`` process."""
    command = [*MITLC, "train", world, "--algo", algo, "--out", str(out), "--quiet", *settings]
    start = time.perf_counter()
    subprocess.run(command, check=True, cwd=ROOT, capture_output=True)
    return time.perf_counter() - start


def evaluate(out: Path, episodes: int) -> dict[str, object]:
    """``mitlc eval --json`` of a run."""
    command = [*MITLC, "eval", str(out), "--json", "--episodes", str(episodes)]
    done = subprocess.run(command, check=True, cwd=ROOT, capture_output=True, text=True)
    result: dict[str, object] = json.loads(done.stdout)
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--world", default="specs/paper/case1.yaml")
    parser.add_argument("--episodes", type=int, default=40_000)
    parser.add_argument("--eval-episodes", type=int, default=10_000)
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a setting of mitlc's DQN run (repeatable), passed on as mitlc train --set",
    )
    args = parser.parse_args()
    dqn_settings = ["--episodes", str(args.episodes)]
    for setting in args.set:
        dqn_settings += ["--set", setting]
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        base = Path(folder)
        seconds = train(args.world, base / "dqn", "dqn", dqn_settings)
        steps = json.loads((base / "dqn" / "summary.json").read_text())["steps"]
        rows.append(("mitlc dqn", steps, seconds, evaluate(base / "dqn", args.eval_episodes)))
        for algo in ("sb3-dqn", "sb3-ppo"):
            out = base / algo
            seconds = train(args.world, out, algo, ["--set", f"sb3.steps={steps}"])
            rows.append((algo, steps, seconds, evaluate(out, args.eval_episodes)))
    print(f"world {args.world}; {args.eval_episodes:,} greedy evaluation episodes each")
    shown_settings = " ".join(f"--set {setting}" for setting in args.set) or "(world file's)"
    print(f"mitlc dqn: --episodes {args.episodes:,} {shown_settings}")
    print("sb3-dqn, sb3-ppo: default settings, sb3.steps = mitlc dqn's env steps\n")
    print(f"{'learner':12} {'env steps':>10} {'greedy success [95%]':>28} {'optimum':>8} "
          f"{'train s':>8} {'s / mitlc s':>11}")  # fmt: skip
    mitlc_seconds = rows[0][2]
    for name, steps, seconds, result in rows:
        low, high = result["interval95"]  # type: ignore[misc]
        shown = f"{result['success_rate']:.4f} [{low:.4f}, {high:.4f}]"
        optimum = result.get("optimum")
        optimum_shown = f"{optimum:.4f}" if isinstance(optimum, float) else "-"
        ratio = seconds / mitlc_seconds
        print(f"{name:12} {steps:>10,} {shown:>28} {optimum_shown:>8} {seconds:8.1f} {ratio:11.2f}")
    ours = float(rows[0][3]["success_rate"])  # type: ignore[arg-type]
    best = max(rows[1:], key=lambda row: float(row[3]["success_rate"]))  # type: ignore[arg-type]
    best_rate = float(best[3]["success_rate"])  # type: ignore[arg-type]
    fastest = min(row[2] for row in rows[1:])
    print(
        f"\nissue 13: mitlc dqn {ours:.4f} vs SB3's best {best_rate:.4f} ({best[0]}): "
        f"{'met' if ours >= best_rate else 'NOT met'}; time {mitlc_seconds:.1f} s vs a third "
        f"of SB3's fastest {fastest / 3:.1f} s: "
        f"{'met' if mitlc_seconds <= fastest / 3 else 'NOT met'}"
    )


if __name__ == "__main__":
    main()
