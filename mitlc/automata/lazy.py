"""The digital LDGBA built lazily: states and successors made on first request.

:class:`LazyAutomaton` is the automaton of :func:`mitlc.automata.ldba.translate` (the
construction of Esparza, Křetínský and Sickert, EKS20: "A unified translation of linear temporal
logic to ω-automata", JACM 67(6), 2020), with the same states, marks, jumps and verdicts, but
built on demand: the eager translation tabulates ``delta[s][letter]`` for all ``2^n`` letters
of every reachable state before anything can use it, while this one computes a transition
when a caller asks for it, or when deciding a state's verdict needs it, and memoises it.

Two facts make that possible and exact.

* **Letter classes.** The successor (and the marks) of a state depend on a letter only through
  its class: the terminal of the state's decision diagram (:meth:`Rules.transitions`, over
  the propositions its obligations read now, :meth:`mitlc.automata.keys.Rules.reads`), so a
  state has one transition per class; a task over twelve rooms typically has two or three.
* **Liveness on the class graph.** The eager translation merges every state with no accepting
  run (over all letters) into the rejecting sink, with the rule of
  :func:`mitlc.automata.graph.live_states`: a state is live iff it reaches an SCC whose internal
  letter transitions carry every acceptance set (with zero sets: that has an internal
  transition) and that is not the sink, or a state where a finite trace may stop with success
  (:mod:`mitlc.automata.ends`). The class graph has the same states, the same
  (source, target, marks) triples and the same jumps as the full letter graph, so it has the
  same SCCs, the same accepting SCCs and the same live states. Liveness is decided by
  Couvreur's on-the-fly search (Tarjan's SCC search keeping the marks of each partial SCC;
  Couvreur, FM 1999) from the state in question, which stops at the first proof of liveness:
  an edge into a state known live, or a cycle whose edges carry every set (it lies in an
  accepting SCC). Every state then on Tarjan's stack reaches the current one, hence is live;
  every SCC completed before that had all its successors decided and no such cycle, so it is
  dead. Each state is searched once; decided states stay decided. A dead state costs its
  whole forward closure (as in the eager translation); a live one often a handful of states.

Both automata read one definition of their states, :class:`mitlc.automata.keys.Rules`, whose
keys hold the store's normal forms, which do not depend on the order in which they were made
(the order of discovery: breadth-first in the eager translation, by need here), so both reach
the same keys. Jumps are
listed in the order of :meth:`mitlc.automata.keys.Rules.jumps` (that of the guesses) in both,
so a product or a gym wrapper built on either numbers a state's jump actions alike.

A successor that is dead is the one sink (verdict ``violated``, marks 0, a self-loop), as in the
eager automaton; the transition into it keeps the marks of the original step, as eager does.
State ids count the live states and the sink handed out so far, in order of first creation.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from mitlc.automata.digital import Component, DigitalState, Verdict
from mitlc.automata.ends import END_FAILS
from mitlc.automata.keys import SINK, Key, Rules, Transitions
from mitlc.automata.ldba import state_limit_error
from mitlc.automata.terms import TermStore
from mitlc.limits import Deadline, collector_paused
from mitlc.syntax import ast, to_text

_SINK_STATE = DigitalState("false", "initial", "violated")
_NO_NODE = -1
"""The node of the public sink state: it stands for every dead state."""


@dataclass(slots=True)
class _Frame:
    """A node of the search's depth-first path and its next edge: its transition ``sub``
    (counting down from its last one; -1 when done), then the jump ``jump``."""

    node: int
    sub: int
    jump: int = 0


@dataclass(slots=True)
class _Graph:
    """The class graph explored so far: one node per key, in order of creation."""

    rules: Rules
    max_states: int
    deadline: Deadline
    keys: list[Key] = field(default_factory=list)
    index: dict[Key, int] = field(default_factory=dict)
    live: list[bool | None] = field(default_factory=list)
    """``True``: an accepting run exists; ``False``: none; ``None``: not decided yet."""
    masks: list[int] = field(default_factory=list)
    """``masks[n]``: the propositions node ``n`` reads (:meth:`Rules.reads`)."""
    rows: list[dict[int, tuple[int, int]]] = field(default_factory=list)
    """``rows[n][sub]``: the target node and marks on every letter ``l`` with
    ``l & masks[n] == sub``, for the classes asked about so far."""
    jumps: list[tuple[int, ...] | None] = field(default_factory=list)
    """The jump targets of a node, once asked about."""
    diagrams: list[Transitions | None] = field(default_factory=list)
    """A node's transitions (:meth:`Rules.transitions`), once needed."""
    outs: list[list[tuple[int, int]] | None] = field(default_factory=list)
    """A node's distinct transitions (target node, marks), by least letter, once needed."""

    def node(self, key: Key) -> int:
        """The node of ``key``, made on first sight (the sink and ``true``-like states decided
        at once)."""
        found = self.index.get(key)
        if found is None:
            if len(self.keys) >= self.max_states:
                raise state_limit_error(self.max_states)
            found = len(self.keys)
            self.keys.append(key)
            self.index[key] = found
            self.live.append(False if key == SINK else self.rules.surely_live(key) or None)
            self.masks.append(self.rules.reads(key))
            self.rows.append({})
            self.jumps.append(None)
            self.diagrams.append(None)
            self.outs.append(None)
        return found

    def transitions(self, node: int) -> Transitions:
        """The transitions of ``node`` (a decision diagram and its terminals' meaning)."""
        found = self.diagrams[node]
        if found is None:
            found = self.diagrams[node] = self.rules.transitions(self.keys[node])
        return found

    def out_edges(self, node: int) -> list[tuple[int, int]]:
        """The distinct transitions of ``node`` (target node, marks): one per class of
        letters it tells apart, by least letter."""
        found = self.outs[node]
        if found is None:
            self.deadline.check()
            transitions = self.transitions(node)
            classes = self.rules.progression.diagrams.classes(transitions.diagram)
            found = self.outs[node] = []
            for value, _ in classes:
                key, marks = transitions.outcome(value)
                found.append((self.node(key), marks))
        return found

    def edge(self, node: int, sub: int) -> tuple[int, int]:
        """The target node and marks of ``node`` on the letter class ``sub``."""
        row = self.rows[node]
        found = row.get(sub)
        if found is None:
            self.deadline.check()
            diagrams = self.rules.progression.diagrams
            transitions = self.transitions(node)
            target, marks = transitions.outcome(diagrams.evaluate(transitions.diagram, sub))
            found = row[sub] = (self.node(target), marks)
        return found

    def jump_targets(self, node: int) -> tuple[int, ...]:
        """The nodes the epsilon jumps of ``node`` lead to, in the order of the guesses."""
        found = self.jumps[node]
        if found is None:
            jumps = self.rules.jumps(self.keys[node], self.deadline)
            found = self.jumps[node] = tuple(self.node(jump) for jump in jumps)
        return found

    def decide(self, start: int) -> bool:
        """Whether ``start`` is live, searching (see the module docstring) if not known."""
        known = self.live[start]
        if known is None:
            with collector_paused():
                self._search(start)
            known = self.live[start]
            assert known is not None
        return known

    def _search(self, start: int) -> None:
        """Couvreur's on-the-fly SCC search (Tarjan's, with the acceptance marks of each
        partial SCC on a stack of roots) from ``start`` over undecided nodes, stopping at the
        first proof of liveness; every node it visits is decided when it returns.

        Transitions are tried from the last class down (by least letter: the class with the
        most read propositions true first, which meets pending obligations soonest), then the
        jumps. A cycle closed by an
        edge back into the depth-first path merges the partial SCCs it spans; when their
        internal edges carry every set (zero sets: any cycle), that SCC is accepting. Jumps
        lead from the initial to the accepting component and never back, so every cycle
        holds a letter transition, as :func:`mitlc.automata.graph.live_states` requires."""
        live, number, all_sets = self.live, {start: 0}, (1 << self.rules.num_sets) - 1
        if self._stops(start):
            live[start] = True
            return
        stack, work = [start], [_Frame(start, len(self.out_edges(start)) - 1)]
        # [number, marks, entry marks] of each partial SCC, by depth: its root's number, the
        # marks of its internal edges, and those of the tree edge into its root
        roots = [[0, 0, 0]]
        while work:
            frame = work[-1]
            step = self._next_edge(frame)
            if step is None:
                work.pop()
                if roots[-1][0] == number[frame.node]:  # a whole SCC, and not accepting
                    roots.pop()
                    for member in _pop_component(stack, frame.node):
                        live[member] = False
                continue
            target, marks = step
            known = live[target]
            if known is not None:
                if known:  # every node on the stack reaches the path, which reaches target
                    self._mark_live(stack)
                    return
                continue
            if target not in number:
                self.deadline.check_now()
                if self._stops(target):  # a successful stop: live, and so is the path
                    live[target] = True
                    self._mark_live(stack)
                    return
                number[target] = len(number)
                stack.append(target)
                roots.append([number[target], 0, marks])
                work.append(_Frame(target, len(self.out_edges(target)) - 1))
                continue
            merged = marks  # target is on the stack: a cycle
            while roots[-1][0] > number[target]:
                _, inside, entry = roots.pop()
                merged |= inside | entry
            roots[-1][1] |= merged
            if roots[-1][1] == all_sets:
                self._mark_live(stack)
                return

    def _next_edge(self, frame: _Frame) -> tuple[int, int] | None:
        """The next edge of ``frame`` (target, marks), or ``None`` when it has no more."""
        if frame.sub >= 0:
            frame.sub -= 1
            return self.out_edges(frame.node)[frame.sub + 1]
        jumps = self.jump_targets(frame.node)
        if frame.jump < len(jumps):
            frame.jump += 1
            return jumps[frame.jump - 1], 0
        return None

    def _stops(self, node: int) -> bool:
        """Whether a finite trace may stop in ``node`` with success (:mod:`mitlc.automata.ends`):
        such a node is live whatever follows."""
        key = self.keys[node]
        return key != SINK and self.rules.end(key) != END_FAILS

    def _mark_live(self, nodes: list[int]) -> None:
        for node in nodes:
            self.live[node] = True


def _pop_component(stack: list[int], root: int) -> list[int]:
    members = []
    while True:
        member = stack.pop()
        members.append(member)
        if member == root:
            return members


class LazyAutomaton:
    """The digital LDGBA of a formula (EKS20, as :func:`mitlc.automata.ldba.translate`), made
    lazily: a state and its successors exist once something asks for them (module docstring).

    Same language, marks, jumps, obligations and verdicts as the eager automaton, state by
    state; any number of propositions (letters are Python ints, ``sum(1 << i)`` over the true
    ``propositions[i]``). Stops with :class:`~mitlc.automata.ldba.StateLimitError` past
    ``max_states`` explored states and with :class:`mitlc.limits.LimitError` at ``deadline``.
    """

    def __init__(
        self,
        formula: ast.Formula,
        *,
        max_states: int = 1_000_000,
        deadline: Deadline | None = None,
    ) -> None:
        clock = Deadline.none() if deadline is None else deadline
        rules = Rules.of(formula)
        rules.progression.diagrams.deadline = clock
        self.propositions: tuple[str, ...] = rules.store.propositions
        self.num_sets: int = rules.num_sets
        self.formula: str = to_text(formula)
        self._graph = _Graph(rules, max_states, clock)
        self._nodes: list[int] = []
        """``_nodes[state]``: the graph node of a public state (:data:`_NO_NODE`: the sink)."""
        self._ids: dict[int, int] = {}
        self._sink: int | None = None
        self._out: list[dict[int, tuple[int, int]]] = []
        self._states: dict[int, DigitalState] = {}
        self._jumps: dict[int, tuple[int, ...]] = {}
        self.initial: int = self._publish(self._graph.node(rules.start()))

    @property
    def num_states(self) -> int:
        """The states handed out so far (live states and the sink)."""
        return len(self._nodes)

    @property
    def num_explored(self) -> int:
        """The states explored so far, dead ones included (what ``max_states`` bounds)."""
        return len(self._graph.keys)

    def successor(self, state: int, letter: int) -> tuple[int, int]:
        """The successor of ``state`` on ``letter`` and the acceptance marks of that step."""
        node = self._nodes[state]
        if node == _NO_NODE:
            return state, 0
        graph = self._graph
        sub = letter & graph.masks[node]
        out = self._out[state]
        found = out.get(sub)
        if found is None:
            target, marks = graph.edge(node, sub)
            found = out[sub] = (self._publish(target), marks)
        return found

    def jumps(self, state: int) -> tuple[int, ...]:
        """The targets of the epsilon jumps from ``state`` into live states, in the order of
        :meth:`mitlc.automata.keys.Rules.jumps` (the guesses'), as
        :meth:`mitlc.automata.digital.DigitalAutomaton.jumps` of a translation lists them."""
        found = self._jumps.get(state)
        if found is None:
            node, graph = self._nodes[state], self._graph
            found = ()
            if node != _NO_NODE:
                targets = graph.jump_targets(node)
                found = tuple(self._publish(t) for t in targets if graph.decide(t))
            self._jumps[state] = found
        return found

    def verdict(self, state: int) -> Verdict:
        """``satisfied``, ``violated`` (the sink) or ``pending``, as the eager automaton says."""
        return self._state(state).verdict

    def obligation(self, state: int) -> str:
        """The formula still owed in ``state`` (as :attr:`DigitalState.obligation`)."""
        return self._state(state).obligation

    def end(self, state: int) -> int:
        """What a trace that stops in ``state`` is worth: its end code
        (:attr:`DigitalState.end`)."""
        return self._state(state).end

    def component(self, state: int) -> Component:
        """``initial`` or ``accepting``: the component of ``state``."""
        return self._state(state).component

    @property
    def store(self) -> TermStore:
        """The term store of the keys (:meth:`key`)."""
        return self._graph.rules.store

    def key(self, state: int) -> Key:
        """The normal forms behind ``state`` (:data:`mitlc.automata.keys.SINK` for the sink)."""
        node = self._nodes[state]
        return SINK if node == _NO_NODE else self._graph.keys[node]

    def _state(self, state: int) -> DigitalState:
        found = self._states.get(state)
        if found is None:
            node = self._nodes[state]
            found = _SINK_STATE
            if node != _NO_NODE:
                found = self._graph.rules.state(self._graph.keys[node])
            self._states[state] = found
        return found

    def _publish(self, node: int) -> int:
        """The state id of ``node``: its own when live, else the sink's (made on first use)."""
        found = self._ids.get(node)
        if found is not None:
            return found
        if not self._graph.decide(node):
            if self._sink is None:
                self._sink = self._new(_NO_NODE)
            return self._sink
        found = self._ids[node] = self._new(node)
        return found

    def _new(self, node: int) -> int:
        self._nodes.append(node)
        self._out.append({})
        return len(self._nodes) - 1
