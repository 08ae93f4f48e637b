"""The tables of bench/envs_bench.py: per task and arm, rliable's IQM across tasks, and issue
24's targets (see envs_bench.py's docstring)."""

from __future__ import annotations

import argparse
import dataclasses
import json
from typing import Any

import numpy as np
from envs_plan import ARMS, TARGETS, Records, Run, Task


def per_arm(runs: list[Run]) -> Records:
    """The finished records by task and arm, in the order of the plan."""
    table: Records = {}
    for run in runs:
        arms = table.setdefault(run.task.name, {})
        records = arms.setdefault(run.arm.name, [])
        if run.result is not None:
            records.append(run.result)
    return table


def markdown(table: Records, seeds: int) -> list[str]:
    lines = [
        "| task | arm | algo | success (mean) | each seed: success [95%] | env steps | wall s |",
        "|---|---|---|---|---|---|---|",
    ]
    for task, arms in table.items():
        for arm, records in arms.items():
            if not records:
                lines.append(f"| {task} | {arm} | - | missing | - | - | - |")
                continue
            mean = np.mean([r["success_rate"] for r in records])
            each = "; ".join(
                f"s{r['seed']} {r['success_rate']:.3f} [{r['interval95'][0]:.3f}, "
                f"{r['interval95'][1]:.3f}]"
                for r in records
            )
            if len(records) < seeds:
                each += f" ({seeds - len(records)} missing)"
            steps = np.mean([r["steps"] for r in records])
            wall = np.mean([r["wall_s"] for r in records])
            algo = records[0]["algo"]
            lines.append(
                f"| {task} | {arm} | {algo} | {mean:.3f} | {each} | {steps:,.0f} | {wall:.1f} |"
            )
    return lines


def complete(table: Records) -> list[str]:
    """The tasks with a record of every arm of :data:`ARMS` for some seed they share: those
    the IQM is taken over (so a task still to run leaves it, rather than emptying it)."""
    found = []
    for task, arms in table.items():
        seeds = [{r["seed"] for r in arms.get(arm.name, [])} for arm in ARMS]
        if set.intersection(*seeds):
            found.append(task)
    return found


def aggregate(table: Records, reps: int) -> tuple[dict[str, Any], list[float] | None]:
    """Per arm of :data:`ARMS`: rliable's IQM of the success (seeds x tasks, over the
    :func:`complete` tasks and the seeds every arm has on all of them, so that the arms are
    paired) with its 95% stratified bootstrap interval, and the other statistics of
    :func:`mitlc.sweep.report.interval_estimates`; and P(mitlc > plain) with its interval."""
    from mitlc.sweep.report import improvement, interval_estimates

    tasks = complete(table)
    success = {(t, arm.name): {r["seed"]: r["success_rate"] for r in table[t].get(arm.name, [])}
               for t in tasks for arm in ARMS}  # fmt: skip
    seeds = sorted(set.intersection(*map(set, success.values()))) if tasks else []
    scores: dict[str, np.ndarray[Any, Any]] = {}
    for arm in ARMS if seeds else ():
        scores[arm.name] = np.array([[success[t, arm.name][s] for t in tasks] for s in seeds])
    estimates = interval_estimates(scores, reps=reps, seed=0) if scores else {}
    result = {
        name: {"seeds": int(scores[name].shape[0]), "tasks": tasks, **estimates[name]}
        for name in scores
    }
    both = [scores.get(arm.name) for arm in ARMS]
    pair = None
    if both[0] is not None and both[1] is not None and both[0].shape == both[1].shape:
        pair = improvement(both[1], both[0], reps=reps, seed=0)
    return result, pair


def targets(table: Records, seeds: int) -> list[dict[str, Any]]:
    """Each target of :data:`TARGETS` whose task ran: the figures and whether it is met (None:
    not measured, a run of it missing)."""
    found = []
    for target in TARGETS:
        records = table.get(target.task, {}).get(target.arm)
        if records is None:
            continue
        row: dict[str, Any] = {"target": target.text, "task": target.task, "arm": target.arm}
        if len(records) < seeds or not records:
            row.update(met=None, why=f"{seeds - len(records)} of {seeds} runs missing")
            found.append(row)
            continue
        success = float(np.mean([r["success_rate"] for r in records]))
        steps = max(r["steps"] for r in records)
        wall = float(np.mean([r["wall_s"] for r in records]))
        met = success >= target.success
        met &= target.steps is None or steps <= target.steps
        met &= target.seconds is None or wall <= target.seconds
        row.update(success=success, max_steps=steps, mean_wall_s=wall, met=bool(met))
        found.append(row)
    return found


def report(runs: list[Run], tasks: list[Task], seeds: list[int], args: argparse.Namespace) -> None:
    """Print the tables, the IQM and the targets; write them to ``--out/results.json``."""
    table = per_arm(runs)
    scale = "" if args.steps_scale == 1 else f", budgets x {args.steps_scale:g}"
    where = (f"the records in {args.record} (commits "
             f"{', '.join(sorted({str(r.result.get('commit')) for r in runs if r.result}))})"
             if args.report else f"jobs {args.jobs}")  # fmt: skip
    print(f"envs bench: seeds {','.join(map(str, seeds))}{scale}; greedy success from "
          f"mitlc eval --json; wall s is the train process's ({where})\n")  # fmt: skip
    for line in markdown(table, len(seeds)):
        print(line)
    for run in runs:
        for note in run.result["notes"] if run.result else []:
            print(f"note: {run.label}: {note}")
    iqm, pair = aggregate(table, args.reps)
    counted = complete(table)
    left = [t for t in table if t not in counted]
    print(
        f"\nIQM of the greedy success across {', '.join(counted) or 'no task'} "
        "(95% stratified bootstrap)" + (f"; not yet: {', '.join(left)}" if left else "") + ":"
    )
    for name, stats in iqm.items():
        point, low, high = stats["iqm"]
        print(f"  {name:6} {point:.3f} [{low:.3f}, {high:.3f}]  ({stats['seeds']} seeds)")
    if pair is not None:
        print(f"  P(mitlc > plain) {pair[0]:.3f} [{pair[1]:.3f}, {pair[2]:.3f}]")
    checked = targets(table, len(seeds))
    if checked:
        heading = "the issues' targets (24; 44's maze)"
        print("\n" + heading + (" (scaled budgets: not the issues')" if scale else ""))
    for row in checked:
        verdict = {True: "PASS", False: "FAIL", None: "NOT MEASURED"}[row["met"]]
        if "why" in row:
            print(f"  {verdict} {row['target']}: {row['why']}")
            continue
        print(
            f"  {verdict} {row['target']}: {row['arm']} {row['success']:.3f} mean success, "
            f"{row['max_steps']:,} steps at most, {row['mean_wall_s']:.1f} s mean wall"
        )
    results = {
        "seeds": seeds,
        "steps_scale": args.steps_scale,
        "jobs": args.jobs,
        "eval_episodes": args.episodes,
        "tasks": {t.name: dataclasses.asdict(t) for t in tasks},
        "runs": [run.result for run in runs if run.result is not None],
        "missing": [run.label for run in runs if run.result is None],
        "iqm": iqm,
        "p_mitlc_over_plain": pair,
        "targets": checked,
    }
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "results.json").write_text(json.dumps(results, indent=2), encoding="utf-8")
        print(f"\nwritten: {args.out / 'results.json'}")
