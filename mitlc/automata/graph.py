"""Graph analysis of an explored automaton: strongly connected components and liveness."""

from __future__ import annotations

from collections.abc import Sequence


def strongly_connected(successors: Sequence[Sequence[int]]) -> list[int]:
    """The SCC index of every node (iterative Tarjan; indices in reverse topological order)."""
    n = len(successors)
    index = [-1] * n
    low = [0] * n
    on_stack = [False] * n
    component = [-1] * n
    stack: list[int] = []
    counter = 0
    count = 0
    for root in range(n):
        if index[root] >= 0:
            continue
        work = [(root, 0)]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack[root] = True
        while work:
            node, child = work[-1]
            if child < len(successors[node]):
                work[-1] = (node, child + 1)
                nxt = successors[node][child]
                if index[nxt] < 0:
                    index[nxt] = low[nxt] = counter
                    counter += 1
                    stack.append(nxt)
                    on_stack[nxt] = True
                    work.append((nxt, 0))
                elif on_stack[nxt]:
                    low[node] = min(low[node], index[nxt])
                continue
            work.pop()
            if work:
                parent = work[-1][0]
                low[parent] = min(low[parent], low[node])
            if low[node] == index[node]:
                while True:
                    member = stack.pop()
                    on_stack[member] = False
                    component[member] = count
                    if member == node:
                        break
                count += 1
    return component


def live_states(
    delta: Sequence[Sequence[int]],
    marks: Sequence[Sequence[int]],
    epsilon: Sequence[tuple[int, int]],
    num_sets: int,
    rejecting: set[int],
    stops: set[int] | frozenset[int] = frozenset(),
) -> tuple[set[int], list[int]]:
    """The states from which an accepting run or a successful stop exists, and the SCC index of
    every state (:func:`strongly_connected`, over letters and jumps).

    An SCC is accepting when its internal letter transitions carry every acceptance set (with
    zero sets: when it has an internal transition and no rejecting state). A state is live when
    it reaches an accepting SCC or one of ``stops``, the states where a finite trace may stop
    with success (:mod:`mitlc.automata.ends`): a state is *violated* only when no continuation,
    infinite or finite, satisfies the task.
    """
    n = len(delta)
    successors: list[list[int]] = [sorted(set(row)) for row in delta]
    for s, t in epsilon:
        successors[s].append(t)
    component = strongly_connected(successors)
    all_sets = (1 << num_sets) - 1
    covered: dict[int, int] = {}
    cyclic: set[int] = set()
    for s in range(n):
        c = component[s]
        for letter, t in enumerate(delta[s]):
            if component[t] == c:
                cyclic.add(c)
                covered[c] = covered.get(c, 0) | marks[s][letter]
    bad = {component[s] for s in rejecting}
    accepting = {c for c in cyclic if covered.get(c, 0) == all_sets and c not in bad}
    predecessors: list[list[int]] = [[] for _ in range(n)]
    for s in range(n):
        for t in successors[s]:
            predecessors[t].append(s)
    live = {s for s in range(n) if component[s] in accepting} | set(stops)
    frontier = list(live)
    while frontier:
        t = frontier.pop()
        for s in predecessors[t]:
            if s not in live:
                live.add(s)
                frontier.append(s)
    return live, component
