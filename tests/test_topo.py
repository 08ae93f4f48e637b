"""Graph helpers of the topological solver against networkx on random graphs."""

from __future__ import annotations

import networkx as nx
import numpy as np
import pytest
from scipy.sparse import csr_matrix

from mitlc.check.topo import backward_reachable, layers


def random_graph(seed: int, n: int, edges: int) -> tuple[csr_matrix, nx.DiGraph]:
    rng = np.random.default_rng(seed)
    tails, heads = rng.integers(0, n, edges), rng.integers(0, n, edges)
    matrix = csr_matrix((np.ones(edges), (tails, heads)), shape=(n, n))
    matrix.sum_duplicates()
    graph = nx.DiGraph()
    graph.add_nodes_from(range(n))
    graph.add_edges_from(zip(tails.tolist(), heads.tolist(), strict=True))
    return matrix, graph


@pytest.mark.parametrize("seed", range(40))
def test_backward_reachable_is_the_ancestors_of_the_target(seed: int) -> None:
    n = 5 + seed * 3
    matrix, graph = random_graph(seed, n, edges=int(1.3 * n))
    target = np.random.default_rng(seed + 1000).random(n) < 0.1
    expected = set(np.flatnonzero(target).tolist())
    for t in np.flatnonzero(target).tolist():
        expected |= nx.ancestors(graph, t)
    found = backward_reachable(matrix, target)
    assert set(np.flatnonzero(found).tolist()) == expected


def test_backward_reachable_of_no_target_is_empty() -> None:
    matrix, _ = random_graph(0, 10, 20)
    assert not backward_reachable(matrix, np.zeros(10, dtype=bool)).any()


@pytest.mark.parametrize("seed", range(20))
def test_layers_put_every_successor_in_an_earlier_layer(seed: int) -> None:
    n = 10 + seed * 5
    rng = np.random.default_rng(seed)
    tails, heads = rng.integers(0, n, 2 * n), rng.integers(0, n, 2 * n)
    low, high = np.minimum(tails, heads), np.maximum(tails, heads)  # acyclic: edges go down
    matrix = csr_matrix((np.ones(len(low)), (high, low)), shape=(n, n))
    matrix.sum_duplicates()
    order, ptr = layers(matrix)
    assert sorted(order.tolist()) == list(range(n))
    depth = np.empty(n, dtype=np.int64)
    depth[order] = np.repeat(np.arange(len(ptr) - 1), np.diff(ptr))
    for x, y in zip(high.tolist(), low.tolist(), strict=True):
        if x != y:
            assert depth[y] < depth[x]
