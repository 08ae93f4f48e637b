"""The lazy automaton beside the eager translation, on a twelve-room deadline sequence.

    .venv/bin/python bench/lazy_bench.py [--rooms 12] [--window 20] [--eager-limit 60]

A 10x10 grid world (written as YAML into a temporary directory and loaded with
:func:`mitlc.worlds.load_world`) has twelve labelled cells ``p1 .. p12`` and the task
``!p1 U[0,w] (p1 & X (!p2 U[0,w] (p2 & X (... (!p12 U[0,w] p12)))))``: visit the rooms in
order, each within ``w`` steps of the last. The eager translation (``translate``) tabulates
``2^12`` letters per state; it runs in a child process under a ``--eager-limit`` second time
limit (its peak memory is the child's). The lazy automaton (:class:`LazyAutomaton`) is walked
breadth-first over the world's distinct letters (13: one per room, and the empty one) and its
epsilon jumps, which is what a product with the world asks of it. Prints one table.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from mitlc.automata import LazyAutomaton, TranslationError, compile_formula, translate
from mitlc.limits import LimitError
from mitlc.syntax import parse
from mitlc.worlds import load_world


def sequence_task(rooms: int, window: int) -> str:
    """``!p1 U[0,w] (p1 & X (... (!pn U[0,w] pn)...))``, built from the innermost room out."""
    text = f"!p{rooms} U[0,{window}] p{rooms}"
    for i in range(rooms - 1, 0, -1):
        text = f"!p{i} U[0,{window}] (p{i} & X ({text}))"
    return text


def world_yaml(rooms: int, task: str) -> str:
    """A 10x10 grid world with ``rooms`` labelled cells spread over it."""
    cells = [(r, c) for r in range(0, 10, 3) for c in range(0, 10, 3)][1:]
    cells += [(1, 5), (5, 1), (8, 5), (5, 8)]
    labels = "\n".join(f"  p{i + 1}: [[{r}, {c}]]" for i, (r, c) in enumerate(cells[:rooms]))
    return (
        "name: lazy-bench\n"
        "grid: {rows: 10, cols: 10}\n"
        f"labels:\n{labels}\n"
        "start: [0, 0]\n"
        "motion: {intended: 0.8, sideways: 0.1}\n"
        f"spec: {{formula: {json.dumps(task)}}}\n"
        "horizon: 300\n"
    )


def walk(lazy: LazyAutomaton, letters: list[int]) -> tuple[int, int]:
    """Breadth-first over every (state, letter) and jump: the states and transitions seen."""
    seen, frontier, transitions = {lazy.initial}, [lazy.initial], 0
    while frontier:
        state = frontier.pop()
        targets = [lazy.successor(state, letter)[0] for letter in letters]
        targets += lazy.jumps(state)
        transitions += len(targets)
        for target in targets:
            if target not in seen:
                seen.add(target)
                frontier.append(target)
    return len(seen), transitions


def world_letters(world_file: Path) -> tuple[list[int], list[str]]:
    """The distinct letters of the world, over the world's propositions, and those."""
    world = load_world(world_file)
    return sorted({int(x) for x in world.letters}), list(world.propositions)


def relabel(letters: list[int], source: list[str], target: tuple[str, ...]) -> list[int]:
    """Letters over ``source`` propositions, as letters over ``target``."""
    where = {p: target.index(p) for p in source}
    return [sum(1 << where[p] for i, p in enumerate(source) if x >> i & 1) for x in letters]


def run_lazy(task: str, world_file: Path) -> dict[str, float]:
    """Load the world, build the lazy automaton, walk it; times in seconds."""
    t0 = time.perf_counter()
    letters, props = world_letters(world_file)
    t1 = time.perf_counter()
    lazy = LazyAutomaton(parse(task))
    t2 = time.perf_counter()
    states, transitions = walk(lazy, relabel(letters, props, lazy.propositions))
    t3 = time.perf_counter()
    return {
        "load": t1 - t0,
        "build": t2 - t1,
        "walk": t3 - t2,
        "states": states,
        "created": lazy.num_states,
        "explored": lazy.num_explored,
        "transitions": transitions,
        "letters": len(letters),
    }


def run_eager(task: str, limit: float, stage: str) -> dict[str, object]:
    """The eager ``translate`` or ``compile`` (translate and fold) in this process (the
    child's work)."""
    start = time.perf_counter()
    try:
        if stage == "compile":
            states = len(compile_formula(parse(task), time_limit=limit).digital.states)
        else:
            states = len(translate(parse(task), time_limit=limit).states)
    except (LimitError, TranslationError) as error:
        return {"error": str(error), "time": time.perf_counter() - start}
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return {"time": time.perf_counter() - start, "states": states, "peak_mb": peak}


def check_process(world_file: Path) -> dict[str, float]:
    """``mitlc check WORLD --json`` as a whole process: wall time, CPU time (user + system of
    the child) and its pmax."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    command = [sys.executable, "-m", "mitlc", "check", str(world_file), "--json"]
    done = subprocess.run(command, capture_output=True, text=True, check=True)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    summary = json.loads(done.stdout)
    return {"wall": wall, "cpu": cpu, "pmax": summary["pmax"], "states": summary["product_states"]}


def eager_in_child(task: str, limit: float, stage: str) -> dict[str, object]:
    """:func:`run_eager` in a child process, with the child's peak resident memory (MB)."""
    command = [sys.executable, __file__, "--eager-child", task, "--eager-limit", str(limit)]
    done = subprocess.run([*command, "--stage", stage], capture_output=True, text=True, check=True)
    result: dict[str, object] = json.loads(done.stdout)
    return result


def lazy_peak_mb(task: str) -> float:
    """The Python heap the lazy automaton and its walk allocate at most (tracemalloc, MB)."""
    tracemalloc.start()
    lazy = LazyAutomaton(parse(task))
    walk(lazy, [0, *(1 << i for i in range(len(lazy.propositions)))])
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return peak / 2**20


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rooms", type=int, default=12)
    parser.add_argument("--window", type=int, default=20)
    parser.add_argument("--eager-limit", type=float, default=60.0)
    parser.add_argument("--eager-child", help=argparse.SUPPRESS)
    parser.add_argument("--stage", default="translate", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.eager_child:
        print(json.dumps(run_eager(args.eager_child, args.eager_limit, args.stage)))
        return
    task = sequence_task(args.rooms, args.window)
    with tempfile.TemporaryDirectory() as folder:
        world_file = Path(folder) / "world.yaml"
        world_file.write_text(world_yaml(args.rooms, task))
        lazy = run_lazy(task, world_file)
        checked = check_process(world_file)
    peak = lazy_peak_mb(task)
    eager = {stage: eager_in_child(task, args.eager_limit, stage) for stage in STAGES}
    report(task, lazy, peak, eager)
    print(
        f"\nmitlc check WORLD (a whole process, lazy automaton): {checked['wall']:.2f} s wall, "
        f"{checked['cpu']:.2f} s CPU; {checked['states']:.0f} product states, "
        f"pmax {checked['pmax']:.6f} (target: under 2 s)"
    )


STAGES = ("translate", "compile")


def report(
    task: str, lazy: dict[str, float], peak: float, eager: dict[str, dict[str, object]]
) -> None:
    """Print the table."""
    lazy_time = lazy["build"] + lazy["walk"]
    print(f"task: {task[:90]}{'...' if len(task) > 90 else ''}")
    print(f"world letters: {lazy['letters']:.0f}; world load {lazy['load']:.3f} s\n")
    print(f"{'':28}{'time (s)':>10}{'states':>10}{'memory (MB)':>14}")
    for stage in STAGES:
        row = eager[stage]
        name = f"eager {stage}" + (" (+fold)" if stage == "compile" else "")
        if "error" in row:
            print(f"{name:28}{row['time']:>10.2f}{'refused':>10}{'':>14}   {row['error']}")
        else:
            print(
                f"{name:28}{row['time']:>10.2f}{row['states']:>10}"
                f"{row['peak_mb']:>14.0f}   (peak RSS of a child process)"
            )
    print(f"{'lazy: build (initial)':28}{lazy['build']:>10.4f}{'':>10}")
    print(
        f"{'lazy: walk world letters':28}{lazy['walk']:>10.4f}{lazy['states']:>10.0f}"
        f"{peak:>14.2f}   (Python heap peak)"
    )
    print(
        f"{'lazy: total':28}{lazy_time:>10.4f}{lazy['created']:>10.0f}"
        f"{'':>14}   ({lazy['explored']:.0f} explored, {lazy['transitions']:.0f} transitions)"
    )
    for stage in STAGES:
        seconds = eager[stage]["time"]
        assert isinstance(seconds, float)
        print(f"eager {stage} / lazy total time: {seconds / lazy_time:,.0f}x")


if __name__ == "__main__":
    main()
