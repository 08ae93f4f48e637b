"""One whole ``check`` (product, pmax, pmax_horizon) of an n x n benchmark world, for memory.

    /usr/bin/time -v .venv/bin/python bench/check_one.py 70

Prints n, product states, seconds, pmax and pmax_horizon; ``time -v`` adds the peak memory.
The world is ``bench/check_bench.py``'s.
"""

from __future__ import annotations

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
        report = check(world, translate(parse(world.spec)))
        seconds = time.perf_counter() - start
    print(n, report.product_states, f"{seconds:.1f}", report.pmax, report.pmax_horizon)


if __name__ == "__main__":
    main()
