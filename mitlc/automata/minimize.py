"""Merging the equivalent states of a digital automaton: ``bisimulation(automaton)`` finds
them, ``quotient(automaton, keys, block)`` merges them.

Two states are merged when they are *bisimilar*: the same component, verdict and value at the
end of a trace, and, for every letter, transitions with the same acceptance marks into merged
states, and epsilon jumps (in their order) into merged states. Bisimilar states accept the same
words with the same marks on the way and the same finite-trace verdicts, so the quotient keeps
the language, the limit-deterministic structure (jumps still go from the initial to the
accepting component) and everything a product reads (verdicts, ends, marks, jump actions). It
is computed component by component in reverse topological order: hash-consing for the states
alone in their strongly connected component (as a reduced decision diagram's nodes are made),
and, inside a larger component, signature refinement (Moore's algorithm, "Gedanken-experiments
on sequential machines", 1956, for transition-marked automata as in the bisimulation-based
reductions of Spot and Owl), where only the predecessors of the states that moved to a new
block are looked at again, as in Hopcroft's algorithm ("An n log n algorithm for minimizing
states in a finite automaton", 1971).

A state's transitions are compared through the reduced decision diagram of its row with each
target replaced by its block, a canonical form of the function from letters to (block, marks).
Progression already merges states with the same normal form; this merges those whose forms
differ but mean the same (``G[0,2] a | G[0,3] a`` with ``G[0,3] a`` as a point ``F[0,0] G[0,3]
a``, which the store does not compare with ``G[0,2] a``), which brings ``F[0,k] G[0,k] a`` to
Spot's minimal automaton.

The quotient keeps, for each block, its least state (its obligation and its key, which the
folding reads) and the breadth-first numbering of the translation.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable, Sequence

from mitlc.automata.bdd import Diagrams
from mitlc.automata.digital import DigitalAutomaton, Row
from mitlc.automata.graph import strongly_connected
from mitlc.automata.keys import Key
from mitlc.limits import Deadline

EXPLICIT_LETTERS = 16
"""Up to this many letters, the refinement compares states letter by letter (cheaper than
reducing a decision diagram again)."""
SMALL = 16
"""Up to this many states to refine, the refinement runs at once: its rounds cost less than
finding where each letter leads (which spares the rounds of long counters)."""


def bisimulation(
    automaton: DigitalAutomaton,
    deadline: Deadline | None = None,
    components: Sequence[int] = (),
) -> list[int]:
    """``block[s]``: the class of state ``s`` in a bisimulation that respects the acceptance
    marks, components, verdicts and ends (see the module docstring), numbered by least state.

    The strongly connected components are taken in reverse topological order. A state that
    leads to no component of several states (the whole of most bounded automata) gets the
    class of its signature at once, its successors' classes being known and a self-loop
    written as such (hash-consing, as a reduced decision diagram's nodes are made: no rounds,
    however long the chains of deadlines). The others, together, are split by signature
    refinement (:func:`_refine`) and never merged with the first (a cycle of states each
    bisimilar to a self-looping one: rare; sound). ``components``: the strongly connected
    component of each state, numbered in reverse topological order, where the caller has them
    (the translation's liveness analysis does); else they are found here."""
    n = len(automaton.states)
    jumps = [automaton.jumps(s) for s in range(n)] if automaton.epsilon else [()] * n
    rows = automaton.rows
    successors = (
        [rows[s].targets + jumps[s] for s in range(n)]
        if automaton.epsilon
        else [row.targets for row in rows]
    )
    component = list(components) if components else strongly_connected(successors)
    heads = _heads(automaton)
    order = sorted(range(n), key=component.__getitem__)  # successors first
    size = [0] * (max(component, default=0) + 1)
    for c in component:
        size[c] += 1
    cyclic = [False] * n  # in a component of several states, or leads to one
    classes = [-1] * n
    interned: dict[Hashable, int] = {}
    reduced: dict[Hashable, Hashable] = {}
    for s in order:
        if size[component[s]] > 1 or any(cyclic[t] for t in successors[s] if t != s):
            cyclic[s] = True
            continue
        row = rows[s]
        key = (
            heads[s],
            _row_key(row, [-1 if t == s else classes[t] for t in row.targets], reduced),
            tuple([-1 if t == s else classes[t] for t in jumps[s]]),
        )
        found = interned.get(key)
        if found is not None:
            classes[s] = found
            continue
        c = classes[s] = interned[key] = len(interned)  # fresh: above every class so far
        if s in row.targets:
            # A self-looping class: a state that goes where it does, and into it where it
            # loops, is bisimilar to it (``b R c`` beside a first step that becomes it).
            unfolded = (
                heads[s],
                _row_key(row, [c if t == s else classes[t] for t in row.targets], reduced),
                tuple([c if t == s else classes[t] for t in jumps[s]]),
            )
            interned.setdefault(unfolded, c)
    rest = [s for s in range(n) if cyclic[s]]
    if rest:
        if deadline is not None:
            deadline.check()
        blocks = _refine(automaton, jumps, heads, rest, classes, reduced)
        for s, block in zip(rest, blocks, strict=True):
            classes[s] = interned.setdefault(("cyclic", block), len(interned))
    return _renumbered(classes)


def _heads(automaton: DigitalAutomaton) -> list[int]:
    """Per state, a number for what its class must agree on besides its transitions: its
    component, verdict and end."""
    found: dict[Hashable, int] = {}
    return [
        found.setdefault((state.component, state.verdict, state.end), len(found))
        for state in automaton.states
    ]


def _row_key(row: Row, targets: list[int], memo: dict[Hashable, Hashable]) -> Hashable:
    """The function ``letter -> (targets[k], marks[k])`` of ``row`` (its targets renamed),
    canonically: the reduced ordered decision diagram of it, as :meth:`Row.export` writes it.
    The row's own diagram is that one when the renamed transitions stay distinct; when two
    come to agree it is reduced again (``G (a -> F b)``: two states alike but for a test of
    ``a`` whose branches lead to merged states), once for each row shape and renaming
    (``memo``)."""
    structural = (row.root, row.tests, tuple(targets), row.marks)
    if len(targets) == 1 or len(set(targets)) == len(targets):
        return structural
    if len(set(zip(targets, row.marks, strict=True))) == len(targets):
        return structural
    found = memo.get(structural)
    if found is None:
        diagrams = Diagrams()
        node = row.into(diagrams, lambda k: (targets[k], row.marks[k]))
        reduced = Row.export(diagrams, node, lambda outcome: outcome)
        found = memo[structural] = (reduced.root, reduced.tests, reduced.targets, reduced.marks)
    return found


def _refine(
    automaton: DigitalAutomaton,
    jumps: Sequence[Sequence[int]],
    heads: Sequence[int],
    states: list[int],
    classes: list[int],
    reduced: dict[Hashable, Hashable],
) -> list[int]:
    """The blocks of ``states`` (closed under successors but for those classed in
    ``classes``) in their coarsest bisimulation: Moore's refinement from a first partition
    coarser than it, looking again only at the predecessors of the states that moved, as
    Hopcroft does."""
    inside = {s: i for i, s in enumerate(states)}
    rows = automaton.rows

    def outside(t: int) -> int:
        return -1 if t in inside else classes[t]

    # The first partition: what bisimilar states share whatever the blocks inside (the set of
    # (successor, marks) outcomes, the successors inside not told apart; then the fewest steps
    # to leave these states, and to a marked transition): coarser than the bisimulation, cheap
    # (no diagram, no rounds), and most states are alone in it, final at once (the counters
    # of ``G (a -> F[0,k] b)`` leave after 0, 1, ..., k steps).
    outcomes = [
        (
            heads[s],
            frozenset(zip(map(outside, rows[s].targets), rows[s].marks, strict=True)),
            frozenset(map(outside, jumps[s])),
        )
        for s in states
    ]
    if len(set(outcomes)) == len(states):
        return list(range(len(states)))
    predecessors: list[list[int]] = [[] for _ in states]
    for i, s in enumerate(states):
        for t in {*rows[s].targets, *jumps[s]}:
            if t in inside:
                predecessors[inside[t]].append(i)
    leaves = _distances(
        predecessors,
        [i for i, s in enumerate(states) if any(t not in inside for t in rows[s].targets)],
    )
    marked = _distances(predecessors, [i for i, s in enumerate(states) if any(rows[s].marks)])
    first: dict[Hashable, int] = {}
    block = [
        first.setdefault((outcomes[i], leaves[i], marked[i]), len(first))
        for i in range(len(states))
    ]
    if len(first) == len(states):
        return block
    explicit = automaton.num_letters <= EXPLICIT_LETTERS
    if explicit and len(states) <= SMALL:
        return _moore(automaton, jumps, states, inside, classes, block)
    # Where reading one letter over and over leaves, and after how many steps, letter by
    # letter from the empty one (no proposition holds: a robot waiting) while states remain
    # together: the counters of a pending window (``!a U[5,10] a``).
    for x in range(automaton.num_letters if explicit else 1):
        ways = [rows[s].successor(x)[0] for s in states]
        waits = _exits([inside.get(t, ~outside(t)) for t in ways])
        first = {}
        block = [first.setdefault((block[i], waits[i]), len(first)) for i in range(len(states))]
        if len(first) == len(states):
            return block
    letters = range(automaton.num_letters)
    taken = [[rows[s].transition(x) for x in letters] for s in states] if explicit else []
    members: list[set[int]] = [set() for _ in first]
    for i, b in enumerate(block):
        members[b].add(i)

    def name(t: int) -> int:
        found = inside.get(t)
        return classes[t] if found is None else -1 - block[found]

    if explicit:
        # A few letters: each state's transition on every letter, found once; its signature is
        # the tuple of (block, marks) by letter, canonical without a diagram.

        def signature(i: int) -> Hashable:
            s = states[i]
            row = rows[s]
            targets, marks = row.targets, row.marks
            return (
                heads[s],
                tuple([(name(targets[k]), marks[k]) for k in taken[i]]),
                tuple(map(name, jumps[s])),
            )
    else:

        def signature(i: int) -> Hashable:
            s = states[i]
            row = rows[s]
            named = list(map(name, row.targets))
            return (heads[s], _row_key(row, named, reduced), tuple(map(name, jumps[s])))

    touched = {i for i in range(len(states)) if len(members[block[i]]) > 1}
    while touched:
        by_block: dict[int, list[int]] = {}
        for i in touched:
            by_block.setdefault(block[i], []).append(i)
        moved: list[int] = []
        for b, group in by_block.items():
            moved += _split(b, group, members, block, signature)
        touched = {p for i in moved for p in predecessors[i]}
    return block


def _moore(
    automaton: DigitalAutomaton,
    jumps: Sequence[Sequence[int]],
    states: list[int],
    inside: dict[int, int],
    classes: list[int],
    first: list[int],
) -> list[int]:
    """:func:`_refine` for a few states and letters: Moore's rounds over every state, each
    state's signature its (block, marks) on every letter, until no block splits (cheaper, for
    so few, than the bookkeeping of which states to look at again)."""
    rows = automaton.rows
    letters = range(automaton.num_letters)

    def code(t: int) -> int:  # an inside state's index, or below -1 an outside class
        found = inside.get(t)
        return -2 - classes[t] if found is None else found

    taken = []
    for s in states:
        row = rows[s]
        coded = [(code(t), m) for t, m in zip(row.targets, row.marks, strict=True)]
        taken.append(([coded[row.transition(x)] for x in letters], [code(t) for t in jumps[s]]))
    block = first
    while True:
        names: dict[Hashable, int] = {}
        split = [
            names.setdefault(
                (
                    block[i],
                    tuple([(block[j] if j >= 0 else j, m) for j, m in moves]),
                    tuple([block[j] if j >= 0 else j for j in jumped]),
                ),
                len(names),
            )
            for i, (moves, jumped) in enumerate(taken)
        ]
        if len(names) == len(set(block)):
            return split
        block = split


def _exits(ways: Sequence[int]) -> list[tuple[int, int]]:
    """For each state, reading one letter over and over: ``(steps, class)`` of the first step
    that leaves the states (``ways[i]``: the state the letter leads to, or ``~class`` of the one
    outside), ``(-1, -1)`` when it never leaves."""
    found: list[tuple[int, int] | None] = [None] * len(ways)
    for start in range(len(ways)):
        path, i = [], start
        on_path = set()
        while i >= 0 and found[i] is None and i not in on_path:
            path.append(i)
            on_path.add(i)
            i = ways[i]
        if i < 0:
            exit_ = (1, ~i)
        elif found[i] is not None:
            steps, cls = found[i]  # type: ignore[misc]
            exit_ = (steps + 1, cls) if steps >= 0 else (-1, -1)
        else:
            exit_ = (-1, -1)  # a cycle: the path never leaves
        for j in reversed(path):
            found[j] = exit_
            steps, cls = exit_
            exit_ = (steps + 1, cls) if steps >= 0 else (-1, -1)
    return [f if f is not None else (-1, -1) for f in found]


def _distances(predecessors: Sequence[Sequence[int]], sources: list[int]) -> list[int]:
    """The fewest steps from each state to one of ``sources`` (-1: none), by a breadth-first
    search backwards."""
    distance = [-1] * len(predecessors)
    for i in sources:
        distance[i] = 0
    frontier = sources
    while frontier:
        reached = []
        for i in frontier:
            for p in predecessors[i]:
                if distance[p] < 0:
                    distance[p] = distance[i] + 1
                    reached.append(p)
        frontier = reached
    return distance


def _split(
    b: int,
    touched: list[int],
    members: list[set[int]],
    block: list[int],
    signature: Callable[[int], Hashable],
) -> list[int]:
    """Split block ``b`` by the signatures of its ``touched`` states (the others keep theirs,
    which their successors' blocks have not changed); return the states moved out of it."""
    groups: dict[Hashable, list[int]] = {}
    for s in touched:
        groups.setdefault(signature(s), []).append(s)
    untouched = _untouched(members[b], touched)
    if untouched is not None:
        stay = signature(untouched)
    elif len(groups) == 1:
        return []
    else:
        stay = max(groups, key=lambda key: len(groups[key]))
    moved: list[int] = []
    for key, group in groups.items():
        if key == stay:
            continue
        new = len(members)
        members.append(set(group))
        members[b].difference_update(group)
        for s in group:
            block[s] = new
        moved += group
    return moved


def _untouched(block: set[int], touched: list[int]) -> int | None:
    """A state of ``block`` not in ``touched`` (``None``: all are), found without walking the
    whole block when it is much larger than ``touched`` (a long chain splits one state a
    round)."""
    if len(block) == len(touched):
        return None
    seen = set(touched)
    return next(s for s in block if s not in seen)


def _renumbered(block: Sequence[int]) -> list[int]:
    """The blocks renumbered in the order of their least state."""
    names: dict[int, int] = {}
    return [names.setdefault(b, len(names)) for b in block]


def quotient(
    automaton: DigitalAutomaton, keys: Sequence[Key], block: Sequence[int]
) -> tuple[DigitalAutomaton, tuple[Key, ...]]:
    """The automaton of the blocks (``block`` as :func:`bisimulation` numbers them), each the
    copy of its least state, with the keys of those states."""
    first: dict[int, int] = {}
    for s, b in enumerate(block):
        first.setdefault(b, s)
    representatives = [first[b] for b in range(len(first))]
    rows = tuple(automaton.rows[s].renumbered(block) for s in representatives)
    order = tuple(
        tuple(dict.fromkeys(block[t] for t in automaton.jumps(s))) for s in representatives
    )
    epsilon = tuple(sorted({(b, t) for b, targets in enumerate(order) for t in targets}))
    merged = DigitalAutomaton(
        source=automaton.source,
        formula=automaton.formula,
        propositions=automaton.propositions,
        states=tuple(automaton.states[s] for s in representatives),
        initial=block[automaton.initial],
        rows=rows,
        num_sets=automaton.num_sets,
        epsilon=epsilon,
        jump_order=order if epsilon else (),
    )
    return merged, tuple(keys[s] for s in representatives)


def is_minimal(block: Sequence[int]) -> bool:
    """Whether no two states share a block."""
    return len(set(block)) == len(block)
