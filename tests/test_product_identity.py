"""The product builder against a reference: the previous builder, kept here verbatim but for
names (one ``np.unique`` over a level's transitions, ``np.unique`` to number new states). Every
array of the product must be the same (state numbering, choice order, targets and the
floating-point probabilities, bit for bit), for an eager and a lazy automaton (which numbers
its states as the builder asks for them), and so must ``pmax`` and ``pmax_horizon``."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from mitlc.automata import translate
from mitlc.automata.lazy import LazyAutomaton
from mitlc.check import solve
from mitlc.check.solve import pmax, pmax_horizon
from mitlc.product import builder
from mitlc.product.builder import INDEX_LIMIT, Builder, merge_rows
from mitlc.product.explicit import Product, build_product
from mitlc.syntax import parse
from mitlc.task import rules
from mitlc.worlds import World, load_world
from mitlc.worlds.model import FloatArray, IntArray

ROOT = Path(__file__).resolve().parent.parent


class ReferenceBuilder(Builder):
    """The builder before level layouts and sort-free numbering (its methods but
    :meth:`Builder.jumps`; the states of a level are read back from the new codes of the
    level before)."""

    fresh: list[IntArray]

    def build(self, start_codes: IntArray) -> IntArray:
        self.fresh = []
        initial, frontier = self.intern(start_codes)
        while len(frontier):
            codes, self.fresh = np.concatenate(self.fresh), []
            frontier = self._reference_level(frontier, codes)
        return initial

    def intern(self, codes: IntArray, kind: IntArray | None = None) -> tuple[IntArray, IntArray]:
        kind = self.monitor.verdicts(codes // self.num_s)
        out = np.where(kind == rules.VIOLATED, 0, 1).astype(np.int64)
        pending = kind == rules.PENDING
        if len(codes) and int(codes.max()) >= len(self.ids):
            grown = np.full(max(int(codes.max()) + 1, 2 * len(self.ids)), -1, dtype=np.int32)
            grown[: len(self.ids)] = self.ids
            self.ids = grown
        fresh = codes[pending][self.ids[codes[pending]] < 0]
        unique, first = np.unique(fresh, return_index=True)
        new_codes = unique[np.argsort(first, kind="stable")]
        assert self.count + len(new_codes) <= INDEX_LIMIT
        new_ids = np.arange(self.count, self.count + len(new_codes), dtype=np.int64)
        self.ids[new_codes] = new_ids
        self.codes.append(new_codes)
        self.fresh.append(new_codes)
        self.count += len(new_codes)
        out[pending] = self.ids[codes[pending]]
        return out, new_ids

    def _reference_level(self, frontier: IntArray, codes: IntArray) -> IntArray:
        world, num_s, monitor = self.world, self.num_s, self.monitor
        s, q = codes % num_s, codes // num_s
        q_next, marks = monitor.successors(q, self.letters[s])
        c_owner, c_key, c_action, c_marks, e_choice, e_target, e_prob = [], [], [], [], [], [], []
        new_frontier, made = [], 0
        for a in range(world.num_actions):
            rows = s * world.num_actions + a
            lo, hi = world.transitions.indptr[rows], world.transitions.indptr[rows + 1]
            counts = hi - lo
            index = np.repeat(lo - np.cumsum(counts) + counts, counts) + np.arange(counts.sum())
            ids, new = self.intern(
                np.repeat(q_next, counts) * num_s + world.transitions.targets[index]
            )
            new_frontier.append(new)
            c_owner.append(np.arange(len(frontier)))
            c_key.append(np.full(len(frontier), a, dtype=np.int64))
            c_action.append(np.full(len(frontier), a, dtype=np.int64))
            c_marks.append(marks)
            e_choice.append(np.repeat(np.arange(made, made + len(frontier)), counts))
            e_target.append(ids)
            e_prob.append(world.transitions.probs[index])
            made += len(frontier)
        jump_counts, jump_targets, jump_ranks = self.jumps(q)
        if jump_counts.any():
            owner = np.repeat(np.arange(len(frontier)), jump_counts)
            ids, new = self.intern(jump_targets * num_s + s[owner])
            new_frontier.append(new)
            c_owner.append(owner)
            c_key.append(world.num_actions + jump_ranks)
            c_action.append(-1 - jump_targets)
            c_marks.append(np.zeros(len(owner), dtype=np.int64))
            e_choice.append(np.arange(made, made + len(owner)))
            e_target.append(ids)
            e_prob.append(np.ones(len(owner)))
        self._append_level_reference(
            len(frontier),
            np.concatenate(c_owner),
            np.concatenate(c_key),
            np.concatenate(c_action),
            np.concatenate(c_marks),
            (np.concatenate(e_choice), np.concatenate(e_target), np.concatenate(e_prob)),
        )
        return np.concatenate(new_frontier)

    def _append_level_reference(
        self,
        states: int,
        owner: IntArray,
        key: IntArray,
        action: IntArray,
        marks: IntArray,
        edges: tuple[IntArray, IntArray, FloatArray],
    ) -> None:
        e_choice, e_target, e_prob = edges
        order = np.lexsort((key, owner))
        rank = np.empty_like(order)
        rank[order] = np.arange(len(order))
        combined = rank[e_choice] * self.count + e_target
        unique, inverse = np.unique(combined, return_inverse=True)
        probs = np.bincount(inverse, weights=e_prob, minlength=len(unique))
        edge_choice = unique // self.count
        base_choice, base_edge = self.action.size, self.targets.size
        per_state = np.bincount(owner, minlength=states)
        self.choice_ptr.append(base_choice + np.cumsum(per_state))
        self.action.append(action[order])
        self.marks.append(marks[order])
        per_choice = np.bincount(edge_choice, minlength=len(order))
        self.indptr.append(base_edge + np.cumsum(per_choice))
        self.targets.append(unique % self.count)
        self.probs.append(probs)


def reference_product(
    world: World, make: Callable[[], object], monkeypatch: pytest.MonkeyPatch
) -> Product:
    """The product as the reference builder makes it."""
    with monkeypatch.context() as patch:
        patch.setattr(builder, "Builder", ReferenceBuilder)
        return build_product(world, make())  # type: ignore[arg-type]


def assert_same(new: Product, old: Product) -> None:
    """Every field equal; arrays of the same values, dtypes and bits."""
    for name in ("world_state", "automaton_state", "choice_ptr", "action", "marks", "end"):
        a, b = getattr(new, name), getattr(old, name)
        assert a.dtype == b.dtype and np.array_equal(a, b), name
    for name in ("indptr", "targets"):
        a, b = getattr(new.transitions, name), getattr(old.transitions, name)
        assert a.dtype == b.dtype and np.array_equal(a, b), name
    assert new.transitions.probs.tobytes() == old.transitions.probs.tobytes()
    assert (new.initial, new.initial_distribution, new.num_sets) == (
        old.initial,
        old.initial_distribution,
        old.num_sets,
    )


CASES = {
    "case1": ("paper/case1.yaml", None),
    "case2-pomdp": ("paper/case2.yaml", None),
    "office": ("paper/case3-office.yaml", None),
    "frozenlake": ("gym/frozenlake8x8.yaml", None),
    "jumps": ("paper/case1.yaml", "F G b"),
    "sets": ("paper/case1.yaml", "G F a & G F b"),
    "jumps-and-sets": ("paper/case1.yaml", "G F a | F G b"),
    "two-robots": ("teams/two-robots.yaml", None),
}


@pytest.mark.parametrize("lazy", [False, True], ids=["eager", "lazy"])
@pytest.mark.parametrize("case", list(CASES))
def test_product_is_the_reference(case: str, lazy: bool, monkeypatch: pytest.MonkeyPatch) -> None:
    path, spec = CASES[case]
    world = load_world(ROOT / "specs" / path, spec)

    def make() -> object:
        formula = parse(world.spec)
        return LazyAutomaton(formula) if lazy else translate(formula)

    new = build_product(world, make())  # type: ignore[arg-type]
    old = reference_product(world, make, monkeypatch)
    assert_same(new, old)
    if case == "two-robots" and lazy:
        return  # the eager run checks its values
    value, history = pmax_horizon(new, min(world.horizon, 40))
    with monkeypatch.context() as patch:
        patch.setattr(solve, "_distinct", reference_distinct)
        reference_value, reference_history = pmax_horizon(old, min(world.horizon, 40))
    assert value == reference_value
    assert all(np.array_equal(a, b) for a, b in zip(history, reference_history, strict=True))
    if case != "two-robots":
        assert np.array_equal(pmax(new).values, pmax(old).values)


def reference_distinct(keys: IntArray, seen: IntArray) -> IntArray:
    """``solve._distinct`` as it was (the last occurrence of each key, in order)."""
    slot = np.zeros(len(seen), dtype=np.int64)
    index = np.arange(len(keys))
    slot[keys] = index
    distinct: IntArray = keys[slot[keys] == index]
    return distinct


def test_merge_rows_sorts_and_sums_in_order() -> None:
    starts = np.array([0, 3, 3, 4, 8])
    targets = np.array([5, 1, 5, 2, 7, 0, 7, 7], dtype=np.int32)
    probs = np.array([0.1, 0.2, 0.3, 1.0, 0.1, 0.2, 0.3, 0.4])
    merged, summed, sizes = merge_rows(starts, targets, probs, 8)
    assert merged.tolist() == [1, 5, 2, 0, 7]
    assert sizes.tolist() == [2, 0, 1, 2]
    assert summed.tolist() == [0.2, 0.1 + 0.3, 1.0, 0.2, (0.1 + 0.3) + 0.4]


def test_merge_rows_leaves_increasing_rows_alone() -> None:
    starts = np.array([0, 2, 4])
    targets = np.array([1, 4, 0, 9], dtype=np.int32)
    probs = np.array([0.5, 0.5, 0.25, 0.75])
    merged, summed, sizes = merge_rows(starts, targets, probs, 10)
    assert merged is targets and summed is probs and sizes.tolist() == [2, 2]
