"""Storm on the product of ``bench/check_one.py``'s n x n world, for memory beside mitlc's.

    .venv/bin/python bench/storm_one.py write 100 product.drn
    .venv/bin/python bench/storm_one.py check product.drn

The first run writes the product (mitlc's, in its own order: breadth-first from the start, the
absorbing states first) to DRN, a block of states at a time formatted by numpy, and prints its
states, choices, transitions and the seconds of the writing; a second one loads it into Storm
and checks
``Pmax=? [G !"violated"]`` (the task has no acceptance sets). Prints Storm's states,
transitions, seconds (build from DRN, check), pmax, its process's peak memory in MB
(``ru_maxrss``: Storm's model and stormpy's interpreter, nothing of mitlc's product) and its CPU
seconds (user and system).
"""

from __future__ import annotations

import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from mitlc.product.explicit import Product

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))


def write_drn(n: int, path: Path) -> None:
    """Build the product of the n x n world and write it as DRN, a block of states at a time."""
    from check_bench import world_yaml

    from mitlc.automata import translate
    from mitlc.product.explicit import build_product
    from mitlc.syntax import parse
    from mitlc.worlds import load_world

    with tempfile.TemporaryDirectory() as folder:
        world_path = Path(folder) / "grid.yaml"
        world_path.write_text(world_yaml(n), encoding="utf-8")
        world = load_world(world_path)
    p = build_product(world, translate(parse(world.spec)), max_product_states=None, time_limit=None)
    start = time.perf_counter()
    with path.open("w", encoding="utf-8") as out:
        out.write("@type: MDP\n@parameters\n\n@reward_models\n\n")
        out.write(f"@nr_states\n{p.num_states}\n@nr_choices\n{p.num_choices}\n@model\n")
        for lo in range(0, p.num_states, BLOCK):
            out.write(_block(p, lo, min(lo + BLOCK, p.num_states)))
    print(p.num_states, p.num_choices, p.num_transitions, f"{time.perf_counter() - start:.1f}")


BLOCK = 200_000
"""States written per block (its lines are formatted by numpy, a column at a time)."""


def _block(p: Product, lo: int, hi: int) -> str:
    """The DRN lines of states ``lo .. hi-1``: each state's line, then per choice its action
    line and its transitions' lines, placed by their positions in the block's text."""
    from mitlc.product.explicit import SATISFIED, VIOLATED

    t = p.transitions
    ptr = p.choice_ptr.astype(np.int64)
    indptr = t.indptr.astype(np.int64)
    c0, c1 = int(ptr[lo]), int(ptr[hi])
    e0, e1 = int(indptr[c0]), int(indptr[c1])
    per_state = np.diff(ptr[lo : hi + 1])
    per_choice = np.diff(indptr[c0 : c1 + 1])
    state_of = np.repeat(np.arange(hi - lo), per_state)  # each choice's state, in the block
    choice_of = np.repeat(np.arange(c1 - c0), per_choice)  # each edge's choice, in the block
    lines = np.empty((hi - lo) + (c1 - c0) + (e1 - e0), dtype=np.dtypes.StringDType())
    state_at = np.arange(hi - lo) + (ptr[lo:hi] - c0) + (indptr[ptr[lo:hi]] - e0)
    choice_at = state_at[state_of] + 1 + (np.arange(c1 - c0) - (ptr[lo:hi] - c0)[state_of])
    choice_at += indptr[c0:c1] - indptr[ptr[lo:hi]][state_of]
    edge_at = choice_at[choice_of] + 1 + (np.arange(e1 - e0) - (indptr[c0:c1] - e0)[choice_of])
    labels = np.full(hi - lo, "", dtype=np.dtypes.StringDType())
    for x, name in ((p.initial, " init"), (VIOLATED, " violated"), (SATISFIED, " satisfied")):
        if lo <= x < hi:
            labels[x - lo] = name
    lines[state_at] = np.strings.add(
        np.strings.add("state ", np.arange(lo, hi).astype(np.dtypes.StringDType())), labels
    )
    rank = np.arange(c1 - c0) - (ptr[lo:hi] - c0)[state_of]  # the choice's index in its state
    lines[choice_at] = np.strings.add("\taction ", rank.astype(np.dtypes.StringDType()))
    values, inverse = np.unique(t.probs[e0:e1], return_inverse=True)
    names = np.array([repr(float(v)) for v in values], dtype=np.dtypes.StringDType())
    targets = t.targets[e0:e1].astype(np.dtypes.StringDType())
    lines[edge_at] = np.strings.add(np.strings.add("\t\t", targets), " : ")
    lines[edge_at] = np.strings.add(lines[edge_at], names[inverse])
    return "\n".join(lines.tolist()) + "\n"


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
    usage = resource.getrusage(resource.RUSAGE_SELF)
    peak, cpu = usage.ru_maxrss / 1024, usage.ru_utime + usage.ru_stime
    print(
        model.nr_states,
        model.nr_transitions,
        f"{built - start:.3f}",
        f"{done - built:.3f}",
        value,
        f"{peak:.0f}",
        f"{cpu:.1f}",
    )


if __name__ == "__main__":
    if sys.argv[1] == "write":
        write_drn(int(sys.argv[2]), Path(sys.argv[3]))
    else:
        check_drn(Path(sys.argv[2]))
