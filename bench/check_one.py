"""One whole ``check`` (product, pmax, pmax_horizon) of an n x n benchmark world, for memory.

    .venv/bin/python bench/check_one.py 100

Prints n, product states, choices, transitions, seconds, pmax, pmax_horizon, this process's
peak resident memory in MB (``ru_maxrss``; run it as a child process so that nothing else
counts) and its CPU seconds (user and system, the loading of the world included: on a shared
machine the wall-clock seconds are noisy). The world is ``bench/check_bench.py``'s; no time
limit, no product-size limit.
"""

from __future__ import annotations

import resource
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from check_bench import world_yaml

from mitlc.automata import translate
from mitlc.check import check
from mitlc.syntax import parse
from mitlc.worlds import load_world


def main() -> None:
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 70
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / f"grid{n}.yaml"
        path.write_text(world_yaml(n), encoding="utf-8")
        world = load_world(path)
        start = time.perf_counter()
        report = check(
            world, translate(parse(world.spec)), max_product_states=None, time_limit=None
        )
        seconds = time.perf_counter() - start
    usage = resource.getrusage(resource.RUSAGE_SELF)
    peak, cpu = usage.ru_maxrss / 1024, usage.ru_utime + usage.ru_stime
    p = report.product
    print(
        n,
        p.num_states,
        p.num_choices,
        p.num_transitions,
        f"{seconds:.1f}",
        report.pmax,
        report.pmax_horizon,
        f"{peak:.0f}",
        f"{cpu:.1f}",
    )


if __name__ == "__main__":
    main()
