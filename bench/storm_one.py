"""Storm on the product of ``bench/check_one.py``'s n x n world, for memory beside mitlc's.

    .venv/bin/python bench/storm_one.py 100 [product.drn]

The first run writes the product (mitlc's, in its own order: breadth-first from the start, the
absorbing states first) to DRN in a child process; a second child loads it into Storm and checks
``Pmax=? [G !"violated"]`` (the task has no acceptance sets). Prints Storm's states,
transitions, seconds (build from DRN, check), pmax and its process's peak memory in MB
(``ru_maxrss``: Storm's model and stormpy's interpreter, nothing of mitlc's product).
"""

from __future__ import annotations

import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))


def write_drn(n: int, path: Path) -> None:
    """Build the product of the n x n world and write it as DRN, a block of states at a time."""
    from check_bench import world_yaml

    from mitlc.automata import translate
    from mitlc.product.explicit import SATISFIED, VIOLATED, build_product
    from mitlc.syntax import parse
    from mitlc.worlds import load_world

    with tempfile.TemporaryDirectory() as folder:
        world_path = Path(folder) / "grid.yaml"
        world_path.write_text(world_yaml(n), encoding="utf-8")
        world = load_world(world_path)
    p = build_product(world, translate(parse(world.spec)), max_product_states=None, time_limit=None)
    t = p.transitions
    names = {float(v): repr(float(v)) for v in np.unique(t.probs)}
    with path.open("w", encoding="utf-8") as out:
        out.write("@type: MDP\n@parameters\n\n@reward_models\n\n")
        out.write(f"@nr_states\n{p.num_states}\n@nr_choices\n{p.num_choices}\n@model\n")
        for lo in range(0, p.num_states, 100_000):
            lines = []
            for x in range(lo, min(lo + 100_000, p.num_states)):
                label = (
                    " init"
                    if x == p.initial
                    else " violated"
                    if x == VIOLATED
                    else " satisfied"
                    if x == SATISFIED
                    else ""
                )
                lines.append(f"state {x}{label}")
                first = int(p.choice_ptr[x])
                for c in range(first, int(p.choice_ptr[x + 1])):
                    lines.append(f"\taction {c - first}")
                    a, b = int(t.indptr[c]), int(t.indptr[c + 1])
                    for y, q in zip(t.targets[a:b].tolist(), t.probs[a:b].tolist(), strict=True):
                        lines.append(f"\t\t{y} : {names[q]}")
            out.write("\n".join(lines) + "\n")


def check_drn(path: Path) -> None:
    """Storm: build the model from ``path`` and check it; print the measurements."""
    import stormpy

    start = time.perf_counter()
    model = stormpy.build_model_from_drn(str(path))
    built = time.perf_counter()
    prop = stormpy.parse_properties('Pmax=? [G !"violated"]')[0]
    result = stormpy.model_checking(model, prop)
    value = float(result.get_value_vector()[model.initial_states[0]])
    done = time.perf_counter()
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(
        model.nr_states,
        model.nr_transitions,
        f"{built - start:.1f}",
        f"{done - built:.1f}",
        value,
        f"{peak:.0f}",
    )


if __name__ == "__main__":
    if sys.argv[1] == "write":
        write_drn(int(sys.argv[2]), Path(sys.argv[3]))
    else:
        check_drn(Path(sys.argv[2]))
