"""The product's compact layout (:mod:`mitlc.product.builder`): 32-bit arrays in compressed
rows, read in place by the solvers, and the memory reserved before they grow."""

from __future__ import annotations

import random

import numpy as np
import pytest

from mitlc.automata import translate
from mitlc.check.solve import _choice_matrix, pmax
from mitlc.limits import Deadline, LimitError
from mitlc.product.builder import Column
from mitlc.product.explicit import build_product
from mitlc.worlds import load_world
from tests.test_check_grids import random_spec, random_world_yaml


def _random_products(count: int, tmp_path):  # type: ignore[no-untyped-def]
    rng = random.Random(26)
    for i in range(count):
        formula = random_spec(rng)
        path = tmp_path / f"w{i}.yaml"
        path.write_text(random_world_yaml(rng, formula, f"w{i}"), encoding="utf-8")
        world = load_world(path)
        yield world, build_product(world, translate(formula))


def test_the_product_is_compressed_rows_of_32_bit_indices(tmp_path) -> None:  # type: ignore[no-untyped-def]
    for world, p in _random_products(12, tmp_path):
        t = p.transitions
        for array in (p.choice_ptr, p.action, p.marks, t.indptr, t.targets):
            assert array.dtype == np.int32
        assert t.probs.dtype == np.float64
        assert p.choice_ptr[0] == 0 and p.choice_ptr[-1] == p.num_choices
        assert t.indptr[0] == 0 and t.indptr[-1] == p.num_transitions
        assert (np.diff(p.choice_ptr) > 0).all() and (np.diff(t.indptr) > 0).all()
        # targets increase within each choice, and each world choice is a distribution
        rise = np.diff(t.targets) > 0
        starts = np.zeros(p.num_transitions, dtype=bool)
        starts[t.indptr[:-1]] = True
        assert (rise | starts[1:]).all()
        sums = np.add.reduceat(t.probs, t.indptr[:-1])
        assert np.allclose(sums, 1.0)
        # actions in order within each state, jumps last
        key = np.where(p.action >= 0, p.action, world.num_actions)
        first = np.zeros(p.num_choices, dtype=bool)
        first[p.choice_ptr[:-1]] = True
        assert ((np.diff(key) >= 0) | first[1:]).all()


def test_the_solvers_read_the_arrays_in_place(tmp_path) -> None:  # type: ignore[no-untyped-def]
    _, p = next(_random_products(1, tmp_path))
    matrix = _choice_matrix(p)
    assert np.shares_memory(matrix.indices, p.transitions.targets)
    assert np.shares_memory(matrix.data, p.transitions.probs)
    assert 0.0 <= pmax(p).values[p.initial] <= 1.0


def test_a_column_grows_in_place_and_widens_past_32_bits() -> None:
    column = Column(np.int32)
    for k in range(100):
        column.append(np.arange(k * 50, (k + 1) * 50))
    assert np.array_equal(column.finish(), np.arange(5000))
    wide = Column(np.int32)
    wide.append([1, 2**40])
    assert wide.finish().dtype == np.int64


def test_the_arrays_are_reserved_before_they_grow() -> None:
    column = Column(np.float64, Deadline(None, "the product build", memory=0.001))
    with pytest.raises(LimitError, match="the product's arrays"):
        column.append(np.zeros(1_000_000))


def _grid_product(n: int, tmp_path):  # type: ignore[no-untyped-def]
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))
    from check_bench import world_yaml

    from mitlc.syntax import parse

    path = tmp_path / f"grid{n}.yaml"
    path.write_text(world_yaml(n), encoding="utf-8")
    world = load_world(path)
    return world, build_product(world, translate(parse(world.spec)))


def test_the_state_graph_holds_no_weights(tmp_path) -> None:  # type: ignore[no-untyped-def]
    from mitlc.check.topo import state_graph

    _, p = _grid_product(4, tmp_path)
    graph = state_graph(p)
    assert graph.data.strides == (0,) and (graph.data == 1.0).all()
    assert graph.indices.dtype == np.int32
    rows = np.repeat(np.arange(p.num_states), np.diff(graph.indptr))
    edges = set(zip(rows.tolist(), graph.indices.tolist(), strict=True))
    assert len(edges) == graph.nnz  # each edge once
    sources = np.repeat(np.arange(p.num_states), np.diff(p.choice_ptr))
    made = np.repeat(sources, np.diff(p.transitions.indptr))
    assert edges == set(zip(made.tolist(), p.transitions.targets.tolist(), strict=True))


def test_the_acyclic_horizon_is_the_steps_table(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """One pass over the layers gives the steps' last table bit for bit, from the first
    horizon that covers the layers; below it the steps run."""
    from mitlc.check.solve import _ends, mask_matrices, pmax_horizon
    from mitlc.check.topo import acyclic_horizon, layers, state_graph

    _, p = _grid_product(5, tmp_path)
    count = len(layers(state_graph(p))[1]) - 1
    _, history = pmax_horizon(p, count + 2)
    fast = []
    for horizon in range(count - 3, count + 3):
        table = acyclic_horizon(p, mask_matrices(p), _ends(p), horizon, Deadline.none())
        fast.append(table is not None)
        within, last = pmax_horizon(p, horizon, keep_history=False)
        assert last[0].tobytes() == history[horizon].tobytes()
        assert within == pmax_horizon(p, horizon)[0]
    assert fast == [False, False, True, True, True, True]


def test_the_blocks_give_the_whole_pass(tmp_path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """The passes over the transitions a block of states (choices) at a time give what one
    pass over all of them gives."""
    import mitlc.check.mec as mec
    import mitlc.check.topo as topo

    _, p = _grid_product(6, tmp_path)
    whole = pmax(p)
    monkeypatch.setattr(topo, "CHUNK", 7)
    monkeypatch.setattr(mec, "CHUNK", 11)
    blocks = pmax(p)
    assert whole.values.tobytes() == blocks.values.tobytes()
    assert np.array_equal(whole.policy, blocks.policy)
    stays, leaving = topo._self_loops(p)
    sources = np.repeat(np.arange(p.num_states), np.diff(p.choice_ptr))
    t = p.transitions
    for c in range(p.num_choices):
        row = slice(int(t.indptr[c]), int(t.indptr[c + 1]))
        here = t.targets[row] == sources[c]
        assert stays[c] == (t.probs[row][here].sum() if here.any() else 0.0)
    assert np.array_equal(leaving, stays < 1.0 - 1e-15)
