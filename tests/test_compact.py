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
