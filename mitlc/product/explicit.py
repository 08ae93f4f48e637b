"""The explicit product of a world and a digital automaton: ``build_product(world, automaton)``.

A product state ``(s, q)`` is the world in state ``s`` with the automaton in state ``q`` about
to read the letter of ``s`` (position 0 is the start cell, before the first action). A world
action ``a`` moves to ``(s', delta[q][L(s)])`` with the world's probability, in the acceptance
sets ``marks[q][L(s)]``; an epsilon jump ``q -> t`` of the automaton is an extra choice that
moves to ``(s, t)`` with probability 1 and no marks. Every product state whose automaton state
is violated (satisfied) is merged into one absorbing ``violated`` (``satisfied``) state; the
satisfied state's self-loop is in every acceptance set. Only states reachable from
``(start, initial)`` are built, breadth first.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mitlc.automata.digital import DigitalAutomaton
from mitlc.worlds.model import FloatArray, IntArray, Sparse, World

VIOLATED, SATISFIED = 0, 1
"""The ids of the two absorbing product states."""


@dataclass(frozen=True, slots=True)
class Product:
    """A product MDP in compressed rows of choices (see the module docstring).

    State ``x`` has the choices ``choice_ptr[x] .. choice_ptr[x+1]-1``; choice ``c`` leads to
    ``transitions.row(c)``, is world action ``action[c]`` (or, when negative, the epsilon jump
    to automaton state ``-1 - action[c]``) and is in the acceptance sets ``marks[c]``.
    """

    world_state: IntArray
    """``-1`` for the two absorbing states."""
    automaton_state: IntArray
    initial: int
    choice_ptr: IntArray
    action: IntArray
    marks: IntArray
    transitions: Sparse
    num_sets: int

    @property
    def num_states(self) -> int:
        """Product states, the two absorbing ones included."""
        return len(self.world_state)

    @property
    def num_choices(self) -> int:
        """Choices over all states."""
        return len(self.action)

    @property
    def num_transitions(self) -> int:
        """Non-zero transition probabilities."""
        return len(self.transitions.targets)


def build_product(world: World, automaton: DigitalAutomaton) -> Product:
    """The reachable product of ``world`` and ``automaton`` (see the module docstring)."""
    delta = np.asarray(automaton.delta, dtype=np.int64)
    marks = np.asarray(automaton.marks, dtype=np.int64)
    verdict = np.array([s.verdict for s in automaton.states])
    jumps: dict[int, list[int]] = {}
    for source, target in automaton.epsilon:
        jumps.setdefault(source, []).append(target)
    num_q = len(automaton.states)
    ids = np.full(world.num_states * num_q, -1, dtype=np.int64)
    states_w: list[int] = [-1, -1]
    states_q: list[int] = [-1, -1]

    def intern(codes: IntArray) -> IntArray:
        """Product ids of (s * num_q + q) codes, numbering new ones in order of first use."""
        out = np.empty(len(codes), dtype=np.int64)
        for i, code in enumerate(codes.tolist()):
            q = code % num_q
            if verdict[q] == "violated":
                out[i] = VIOLATED
            elif verdict[q] == "satisfied":
                out[i] = SATISFIED
            else:
                if ids[code] < 0:
                    ids[code] = len(states_w)
                    states_w.append(code // num_q)
                    states_q.append(q)
                out[i] = ids[code]
        return out

    initial = int(intern(np.array([world.start * num_q + automaton.initial]))[0])
    all_sets = (1 << automaton.num_sets) - 1
    rows: list[tuple[int, FloatArray, IntArray]] = []  # per choice: (action, probs, targets)
    choice_ptr, choice_marks = [0], []
    x = 0
    while x < len(states_w):
        if x in (VIOLATED, SATISFIED):
            rows.append((0, np.ones(1), np.array([x])))
            choice_marks.append(all_sets if x == SATISFIED else 0)
        else:
            s, q = states_w[x], states_q[x]
            letter = int(world.letters[s])
            q_next = int(delta[q, letter])
            for a in range(world.num_actions):
                targets, probs = world.transitions.row(s * world.num_actions + a)
                rows.append((a, probs, intern(targets * num_q + q_next)))
                choice_marks.append(int(marks[q, letter]))
            for t in jumps.get(q, ()):
                rows.append((-1 - t, np.ones(1), intern(np.array([s * num_q + t]))))
                choice_marks.append(0)
        choice_ptr.append(len(rows))
        x += 1
    return Product(
        world_state=np.array(states_w, dtype=np.int64),
        automaton_state=np.array(states_q, dtype=np.int64),
        initial=initial,
        choice_ptr=np.array(choice_ptr, dtype=np.int64),
        action=np.array([r[0] for r in rows], dtype=np.int64),
        marks=np.array(choice_marks, dtype=np.int64),
        transitions=_sparse([(r[2], r[1]) for r in rows]),
        num_sets=automaton.num_sets,
    )


def _sparse(rows: list[tuple[IntArray, FloatArray]]) -> Sparse:
    """Compressed rows with targets sorted and duplicate targets summed."""
    indptr = [0]
    targets: list[IntArray] = []
    probs: list[FloatArray] = []
    for row_targets, row_probs in rows:
        unique, inverse = np.unique(row_targets, return_inverse=True)
        summed = np.zeros(len(unique))
        np.add.at(summed, inverse, row_probs)
        targets.append(unique)
        probs.append(summed)
        indptr.append(indptr[-1] + len(unique))
    return Sparse(
        np.array(indptr, dtype=np.int64),
        np.concatenate(targets).astype(np.int64),
        np.concatenate(probs).astype(np.float64),
    )
