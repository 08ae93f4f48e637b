"""Plain SB3 beside mitlc's observation and shaping on env worlds (issue 24), over several seeds.

    .venv/bin/python bench/envs_bench.py [--tasks doorkey,empty,pointmaze,case1c,case2c,case2]
        [--arms plain,mitlc,...] [--seeds 0,1,2] [--steps-scale 1] [--episodes N] [--out DIR]
        [--jobs 1] [--device D] [--record DIR | --no-record] [--report] [--progress-every S]

Each task (:data:`TASKS`: a world file, an SB3 algorithm and its budget in env steps) is
learned by two arms (:data:`ARMS`) at the same budget and seeds:

* ``plain``: SB3 on the wrapper's flat digital observation with the pass/fail reward
  (``--set task_obs=state --set shaping=0``, counterfactual experience off);
* ``mitlc``: mitlc's observation and shaping (``--set task_obs=clocks --set shaping=1``),
  counterfactual experience off, as the world files train.

Two tasks have a third arm. PointMaze (SAC, the one off-policy learner here) has
``mitlc-crm``: the ``mitlc`` arm with counterfactual experience in SAC's replay
(``sb3.crm=true``, half of each batch: ``sb3.crm_share=0.5``); it is not in the ``mitlc`` arm
because it held PointMaze's first success back (``docs/deadlines.md``). A run whose ``crm``
the learner refuses (e.g. a lazy automaton's task) is run again without it, and the table
says so. The paper's case 2 has ``mitlc-q``:
mitlc's tabular Q-learning on what the agent sees (``--algo q --episodes 200000 --set
shaping=1``: the observation, the automaton state and the frontier), timed against issue 24's
120 s.

Every run goes through the command line into its own run directory under ``--out`` (``mitlc
train --no-eval``, timed: the wall time is the ``train`` process's, start-up included; then
``mitlc eval RUN --json --episodes N``, greedy success with its 95% interval); every
``--progress-every`` seconds (300) a line per run in training says its steps and its training
success (the last line of its ``metrics.jsonl``). A run whose
directory already has ``run/summary.json`` and ``result.json`` is not run again, and one
interrupted in training (SIGINT or SIGTERM: every ``mitlc train`` saves a checkpoint and the
bench starts nothing new) goes on from its latest checkpoint (``mitlc train --resume``), so a
bench run over several sittings loses at most the steps since each run's last checkpoint. A
resumed SB3 off-policy run goes on with its replay memory (in the checkpoint), and its wall
time is the sum of its train processes that ended, signalled ones included (``DIR/wall.json``;
a process killed outright is not counted).

A sitting's machine may not be the next one's, so a finished run at the full budgets also
keeps its record in git, ``bench/results/envs/TASK-ARM-sSEED.json`` (:data:`RECORDS`,
``--record``): its figures, its command and the commit that ran it. A later sitting, anywhere,
counts a record made by the command it would run now and does not run it again; a record of
another command (a budget or setting changed since) is stale and the run is made again. The
tables are of records and runs together; what is lost with a machine is the runs not yet
finished. ``--report`` runs nothing and prints the tables of the records alone (a target with
a run missing is NOT MEASURED). Runs with a wall-time target (:data:`TARGETS`) run
first and alone, whatever ``--jobs`` says. Printed: a Markdown table per task and arm (mean
greedy success over the seeds, each seed's with its interval, env steps from ``summary.json``,
mean wall time), rliable's IQM of the success across the tasks per arm with its 95%
stratified bootstrap interval (:func:`mitlc.sweep.report.interval_estimates`), the
probability that ``mitlc`` beats ``plain``, and the issue's targets (:data:`TARGETS`) with
PASS/FAIL; all of it also in ``--out/results.json``.

``--steps-scale`` multiplies every budget (env steps and the tabular Q's episodes) for a quick
look; the targets are then printed but say nothing about the issue. The full bench takes many
hours on a CPU: measured on 2 cores at ``--jobs 2`` (a run a core), a run of DoorKey's PPO takes
8 to 12 minutes (about 500 env steps/s), of PointMaze's SAC about 20 (125 steps/s), of the
recurrent PPO on case 2 about half an hour. ``--jobs`` runs several at once (torch's threads
shared out). The tasks, arms and targets are in ``envs_plan.py``, the tables in
``envs_report.py``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))  # its sibling modules

from envs_plan import (
    ARMS,
    ENV_EVAL,
    MITLC,
    RECORDS,
    ROOT,
    TASKS,
    Run,
    Task,
    command,
    crm_on,
    plan,
    timed,
)
from envs_report import report


def stop_on_signals() -> None:
    """SIGINT and SIGTERM set :data:`STOP` (the ``mitlc train`` processes, in this process
    group, get the same signal and save their checkpoints)."""

    def handler(signum: int, frame: Any) -> None:
        if not STOP.is_set():
            say(f"envs bench: {signal.Signals(signum).name}: the runs going on save their "
                "checkpoints; nothing new starts (run it again to go on)")  # fmt: skip
        STOP.set()

    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)


CRM_REFUSAL = re.compile(r"^(?:[a-z0-9_]+\.)?crm\b")


def crm_refusal(returncode: int, stderr: str) -> str | None:
    """mitlc's one-line refusal of a counterfactual setting (``sb3.crm: ...``, ``crm: ...``,
    ``q.crm on a POMDP: ...``: exit 1, the message on stderr's last line), else None. An
    interrupted run (exit 130, its last line the resume command, which may name a ``-crm``
    directory) or a crash (a traceback) is no refusal."""
    lines = stderr.strip().splitlines()
    if returncode != 1 or not lines or "Traceback" in stderr:
        return None
    return lines[-1] if CRM_REFUSAL.match(lines[-1]) else None


def train(run: Run, scale: float, device: str | None) -> tuple[float, list[str]]:
    """Train ``run``: from its latest checkpoint where an earlier sitting left one (see the
    module docstring), else afresh; the seconds of all its train processes and its command. A
    ``crm`` the learner refuses is dropped (the run starts again without it)."""
    import shutil

    crm = crm_on(run)
    walls = run.directory / "wall.json"
    while True:
        resume = (run.directory / "run" / "checkpoint.json").is_file()
        if not resume:
            shutil.rmtree(run.directory / "run", ignore_errors=True)
            walls.unlink(missing_ok=True)
        run.directory.mkdir(parents=True, exist_ok=True)
        line = command(run, scale, device, crm)
        before = json.loads(walls.read_text(encoding="utf-8")) if walls.is_file() else []
        start = time.perf_counter()
        with _say:
            TRAINING[run.label] = run
        try:
            done = subprocess.run([*line, *(["--resume"] if resume else [])], cwd=ROOT,
                                  capture_output=True, text=True)  # fmt: skip
        finally:
            with _say:
                TRAINING.pop(run.label, None)
        seconds = time.perf_counter() - start
        walls.write_text(json.dumps([*before, round(seconds, 3)]), encoding="utf-8")
        log = f"$ {' '.join(line)}{' --resume' if resume else ''}\n{done.stdout}{done.stderr}"
        with (run.directory / "train.log").open("a", encoding="utf-8") as out:
            out.write(log)
        if done.returncode == 130 or (STOP.is_set() and done.returncode != 0):
            raise Interrupted(f"stopped after {seconds:.0f} s; it goes on from its checkpoint")
        refusal = crm_refusal(done.returncode, done.stderr)
        if refusal is not None and crm:
            run.notes.append(f"crm refused, run without it ({refusal})")
            (run.directory / "notes.json").write_text(json.dumps(run.notes), encoding="utf-8")
            crm = False
            shutil.rmtree(run.directory / "run", ignore_errors=True)
            continue
        if done.returncode != 0:
            tail = "\n".join(done.stderr.strip().splitlines()[-5:])
            raise RuntimeError(f"mitlc train failed (exit {done.returncode}):\n{tail}")
        if len(before) > 0:
            run.notes.append(f"resumed {len(before)} time(s); wall s summed over the processes")
        return sum(before) + seconds, line


def evaluate(run: Run, episodes: int) -> dict[str, Any]:
    """``mitlc eval RUN --json --episodes N``."""
    line = [*MITLC, "eval", str(run.directory / "run"), "--json", "--episodes", str(episodes)]
    done = subprocess.run(line, cwd=ROOT, capture_output=True, text=True)
    if done.returncode != 0 and STOP.is_set():
        raise Interrupted("stopped in its evaluation; it is evaluated again next time")
    if done.returncode != 0:
        tail = "\n".join(done.stderr.strip().splitlines()[-5:])
        raise RuntimeError(f"mitlc eval failed (exit {done.returncode}):\n{tail}")
    report: dict[str, Any] = json.loads(done.stdout)
    return report


def finished(run: Run) -> dict[str, Any] | None:
    """The record of a run already done (``run/summary.json`` and ``result.json``), else None."""
    summary, result = run.directory / "run" / "summary.json", run.directory / "result.json"
    if summary.is_file() and result.is_file():
        record: dict[str, Any] = json.loads(result.read_text(encoding="utf-8"))
        return record
    return None


def signature(line: list[str]) -> list[str]:
    """A ``mitlc train`` command less what differs between machines and sittings: the
    interpreter and the run directory."""
    words = line[len(MITLC) :]
    return ["RUN" if i > 0 and words[i - 1] == "--out" else w for i, w in enumerate(words)]


def record_file(run: Run, records: Path) -> Path:
    return records / f"{run.task.name}-{run.arm.name}-s{run.seed}.json"


def recorded(run: Run, args: argparse.Namespace) -> dict[str, Any] | None:
    """``run``'s record in ``--record``, where one was made by the command this bench would run
    now (same settings, budget, seed and evaluation); None otherwise (a record of another
    command is stale: the run is made again and its record replaced)."""
    if args.record is None or not record_file(run, args.record).is_file():
        return None
    path = record_file(run, args.record)
    record: dict[str, Any] = json.loads(path.read_text(encoding="utf-8"))
    then = dataclasses.replace(run, notes=list(record.get("notes", [])))
    now = signature(command(then, args.steps_scale, args.device, crm_on(then)))
    episodes = args.episodes if args.episodes is not None else run.task.eval_episodes
    if signature(record.get("command", [])) != now or record.get("eval_episodes") != episodes:
        say(f"{run.label}: {path.name} was made by another command; the run is made again")
        return None
    return record


def keep(run: Run, record: dict[str, Any], args: argparse.Namespace) -> None:
    """Write ``run``'s record to ``--record`` (atomically), with the commit that made it: the
    record's own where it names one (a run finished in an earlier sitting), else this bench's."""
    if args.record is None:
        return
    args.record.mkdir(parents=True, exist_ok=True)
    path = record_file(run, args.record)
    text = json.dumps({**args.provenance, **record}, indent=2, sort_keys=True) + "\n"
    with tempfile.NamedTemporaryFile("w", dir=args.record, delete=False, encoding="utf-8",
                                     suffix=".tmp") as out:  # fmt: skip
        out.write(text)
    os.replace(out.name, path)


def provenance() -> dict[str, Any]:
    """The commit the bench runs (``+changes`` where mitlc, specs or bench differ from it) and
    the machine's cores: what a record carries."""

    def git(*words: str) -> str:
        done = subprocess.run(["git", *words], cwd=ROOT, capture_output=True, text=True)
        return done.stdout.strip() if done.returncode == 0 else ""

    commit = git("rev-parse", "--short=12", "HEAD") or "unknown"
    if git("status", "--porcelain", "--", "mitlc", "specs", "bench/envs_bench.py"):
        commit += "+changes"
    return {"commit": commit, "cpus": os.cpu_count()}


_say = threading.Lock()

TRAINING: dict[str, Run] = {}
"""The runs in training now, by label (under ``_say``)."""


def progress(run: Run, scale: float) -> str:
    """Where ``run``'s training is: the last line of its ``metrics.jsonl``."""
    metrics = run.directory / "run" / "metrics.jsonl"
    lines = metrics.read_text(encoding="utf-8").splitlines() if metrics.is_file() else []
    if not lines:
        return f"{run.label}: starting"
    last = json.loads(lines[-1])
    if run.arm.episodes is not None:
        budget, done, unit = round(run.arm.episodes * scale), last["episodes"], "episodes"
    else:
        budget, done, unit = round(run.task.steps * scale), last["steps"], "steps"
    return (f"{run.label}: {done:,} of {budget:,} {unit}, training success "
            f"{last['success_rate']:.2f}")  # fmt: skip


def watch(every: float, scale: float, ended: threading.Event) -> None:
    """Every ``every`` seconds until ``ended``, one line per run in training."""
    while not ended.wait(every):
        with _say:
            running = list(TRAINING.values())
        for run in running:
            try:
                say(f"  {progress(run, scale)}")
            except (OSError, ValueError, KeyError):  # a line being written
                continue


STOP = threading.Event()
"""Set on SIGINT or SIGTERM: runs not yet started are left for the next sitting."""


class Interrupted(Exception):
    """A ``mitlc train`` stopped by a signal (its checkpoint saved): the run goes on next time."""


def say(text: str) -> None:
    with _say:
        print(text, file=sys.stderr, flush=True)


def execute(run: Run, index: int, total: int, args: argparse.Namespace) -> None:
    """Train and evaluate ``run`` unless it is done; its record in ``run.result``."""
    where = f"[{index}/{total}] {run.label}"
    if STOP.is_set():
        return
    done = finished(run)
    if done is not None:
        run.result = done
        say(f"{where}: done before, kept ({done['success_rate']:.3f})")
        if args.record is not None and not record_file(run, args.record).is_file():
            keep(run, done, args)
        return
    done = recorded(run, args)
    if done is not None:
        run.result = done
        say(f"{where}: recorded ({done['success_rate']:.3f}, commit {done.get('commit')})")
        return
    episodes = args.episodes if args.episodes is not None else run.task.eval_episodes
    say(f"{where}: start ({run.arm.algo or run.task.algo})")
    try:
        timed, notes = run.directory / "train.json", run.directory / "notes.json"
        if notes.is_file():
            run.notes = list(json.loads(notes.read_text(encoding="utf-8")))
        if (run.directory / "run" / "summary.json").is_file() and timed.is_file():
            trained = json.loads(timed.read_text(encoding="utf-8"))  # trained, not evaluated
            run.notes = list(trained["notes"])
        else:
            ended = run.directory / "run" / "summary.json"
            if ended.is_file():  # trained, but the bench stopped before it wrote train.json
                line = command(run, args.steps_scale, args.device, crm_on(run))
                seconds = float(json.loads(ended.read_text(encoding="utf-8"))["seconds"])
                run.notes.append("wall s: the run's own training seconds (its end not timed)")
            else:
                seconds, line = train(run, args.steps_scale, args.device)
            trained = {"wall_s": seconds, "command": line, "notes": run.notes}
            timed.write_text(json.dumps(trained, indent=2), encoding="utf-8")
        summary = json.loads((run.directory / "run" / "summary.json").read_text())
        report = evaluate(run, episodes)
    except Interrupted as err:
        say(f"{where}: {err}")
        return
    except RuntimeError as err:
        say(f"{where}: FAILED ({err}); log in {run.directory / 'train.log'}")
        return
    run.result = {
        "task": run.task.name,
        "arm": run.arm.name,
        "algo": run.arm.algo or run.task.algo,
        "seed": run.seed,
        "success_rate": float(report["success_rate"]),
        "interval95": [float(x) for x in report["interval95"]],
        "eval_episodes": int(report["episodes"]),
        "steps": int(summary["steps"]),
        "episodes": int(summary["episodes"]),
        "wall_s": float(trained["wall_s"]),
        "train_s": float(summary["seconds"]),
        "command": trained["command"],
        "notes": trained["notes"],
        "lower": report.get("lower"),
        **args.provenance,  # the commit that made it, kept with it
    }
    (run.directory / "result.json").write_text(json.dumps(run.result, indent=2), encoding="utf-8")
    keep(run, run.result, args)
    low, high = run.result["interval95"]
    say(
        f"{where}: end, success {run.result['success_rate']:.3f} [{low:.3f}, {high:.3f}], "
        f"{run.result['steps']:,} steps, {run.result['wall_s']:.1f} s"
    )


def parse() -> tuple[argparse.Namespace, list[Task], list[int], list[Run]]:
    """The options, the chosen tasks, the seeds and the plan of runs (an error for bad ones)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    names = [task.name for task in TASKS]
    parser.add_argument("--tasks", default=",".join(names), help=f"of {', '.join(names)}")
    parser.add_argument("--seeds", default="0,1,2")
    parser.add_argument("--steps-scale", type=float, default=1.0, help="times every budget")
    parser.add_argument("--episodes", type=int, default=None,
                        help=f"greedy eval episodes (default: {ENV_EVAL} on env worlds, "
                             "10,000 on the others)")  # fmt: skip
    parser.add_argument("--out", type=Path, default=None, help="default: a new temp dir")
    parser.add_argument("--jobs", type=int, default=1, help="runs at once")
    parser.add_argument("--device", default=None, help="mitlc train --device (default: auto)")
    parser.add_argument("--reps", type=int, default=2000, help="bootstrap resamples")
    parser.add_argument("--arms", default=None,
                        help="of the arms (plain, mitlc, a task's own), in this order "
                             "(default: all)")  # fmt: skip
    parser.add_argument("--record", type=Path, default=None,
                        help=f"where finished runs keep their records (default: {RECORDS} "
                             "at full budgets, none otherwise)")  # fmt: skip
    parser.add_argument("--no-record", action="store_true", help="keep no records")
    parser.add_argument("--progress-every", type=float, default=300.0,
                        help="seconds between the lines on the runs in training")  # fmt: skip
    parser.add_argument("--report", action="store_true",
                        help="run nothing: the tables of the records in --record")  # fmt: skip
    args = parser.parse_args()
    full = args.steps_scale == 1 and args.episodes is None
    if args.no_record or (args.record is None and not full):
        args.record = None
    elif args.record is None:
        args.record = RECORDS
    if args.report and args.record is None:
        parser.error("--report reads the records: at full budgets, or give --record")
    args.provenance = provenance()
    chosen = [name.strip() for name in args.tasks.split(",") if name.strip()]
    unknown = [name for name in chosen if name not in names]
    if unknown or not chosen:
        parser.error(f"--tasks: unknown {', '.join(unknown)} (of {', '.join(names)})")
    seeds = [int(seed) for seed in args.seeds.split(",") if seed.strip()]
    if args.steps_scale <= 0 or args.jobs < 1 or not seeds or args.progress_every <= 0:
        parser.error("--steps-scale, --jobs and --progress-every must be positive, --seeds "
                     "not empty")  # fmt: skip
    if args.out is None and not args.report:
        args.out = Path(tempfile.mkdtemp(prefix="envs-bench-"))
    tasks = [next(task for task in TASKS if task.name == name) for name in chosen]
    arms = None if args.arms is None else [a.strip() for a in args.arms.split(",") if a.strip()]
    known = {arm.name for task in TASKS for arm in (*ARMS, *task.extra_arms)}
    if arms is not None and (not arms or set(arms) - known):
        parser.error(f"--arms: unknown {', '.join(sorted(set(arms) - known))} (of "
                     f"{', '.join(sorted(known))})")  # fmt: skip
    runs = plan(tasks, seeds, args.out or Path("build/bench-envs"), arms)
    if not runs:
        parser.error(f"--arms: no run of {args.arms} on {', '.join(chosen)}")
    return args, tasks, seeds, runs


def run_all(runs: list[Run], args: argparse.Namespace) -> None:
    """Every run not done (see the module docstring); exit 130 where a signal stopped them."""
    args.out.mkdir(parents=True, exist_ok=True)
    if args.jobs > 1 and "OMP_NUM_THREADS" not in os.environ:  # torch's threads, shared out
        os.environ["OMP_NUM_THREADS"] = str(max(1, (os.cpu_count() or 1) // args.jobs))
    say(f"envs bench: {len(runs)} runs under {args.out}")
    stop_on_signals()
    alone = [run for run in runs if timed(run)]  # their wall time is a target
    rest = [run for run in runs if not timed(run)]
    number = {id(run): i + 1 for i, run in enumerate([*alone, *rest])}
    ended = threading.Event()
    watcher = threading.Thread(target=watch, args=(args.progress_every, args.steps_scale, ended),
                               daemon=True)  # fmt: skip
    watcher.start()
    for run in alone:
        execute(run, number[id(run)], len(runs), args)
    with ThreadPoolExecutor(max_workers=args.jobs) as pool:
        futures = [pool.submit(execute, run, number[id(run)], len(runs), args) for run in rest]
        for future in futures:
            future.result()
    ended.set()
    if STOP.is_set():
        say("envs bench: stopped; run the same command again to go on")
        sys.exit(130)


def main() -> None:
    args, tasks, seeds, runs = parse()
    if args.report:
        for run in runs:
            run.result = recorded(run, args)
    else:
        run_all(runs, args)
    report(runs, tasks, seeds, args)


if __name__ == "__main__":
    main()
