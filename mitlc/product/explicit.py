"""The explicit product of a world and a digital automaton: ``build_product(world, automaton)``.

A product state ``(s, q)`` is the world in state ``s`` with the automaton in state ``q`` about
to read the letter of ``s`` (position 0 is the start cell, before the first action); ``L(s)``
is that letter over the automaton's propositions, mapped by name from the world's
(:func:`automaton_letters`). A world
action ``a`` moves to ``(s', delta[q][L(s)])`` with the world's probability, in the acceptance
sets ``marks[q][L(s)]``; an epsilon jump ``q -> t`` of the automaton is an extra choice that
moves to ``(s, t)`` with probability 1 and no marks. Every product state whose automaton state
is violated (satisfied) is merged into one absorbing ``violated`` (``satisfied``) state; the
satisfied state's self-loop is in every acceptance set. Only states reachable from
``(start, initial)`` are built, breadth first.

Before anything is built the product's size is bounded from above (:func:`estimate`): at most
``S * Q`` states for ``S`` world states and ``Q`` automaton states (the builder's table of ids
has exactly that many entries), and at most ``Q * T + S * J`` transitions for ``T`` world
transitions (every (state, action, successor) of the world) and ``J`` epsilon jumps. A product
whose bound passes ``max_product_states`` states, or twenty times as many transitions, is
refused with :class:`ProductSizeError`, as the world loader refuses a grid of more than a
million cells.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from mitlc.automata.digital import DigitalAutomaton
from mitlc.errors import MitlcError
from mitlc.limits import DEFAULT_MAX_PRODUCT_STATES, DEFAULT_TIME_LIMIT, Deadline, LimitError
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


TRANSITIONS_PER_STATE = 20
"""The bound on transitions may be this many times ``max_product_states`` (a grid world has at
most 5 actions of at most 3 successors each: 15 per state, jumps aside)."""


class ProductSizeError(LimitError):
    """The product would be larger than its limit (``max_product_states``)."""


class LabelError(MitlcError, ValueError):
    """The task names a proposition that the world does not label."""


def automaton_letters(world: World, propositions: Sequence[str]) -> IntArray:
    """Per world state, its letter over the automaton's ``propositions`` (bit ``j`` for
    ``propositions[j]``), read by name from the world's letters: the world may label more
    propositions, or list them in another order. A proposition the world does not have is a
    :class:`LabelError`."""
    index = {p: i for i, p in enumerate(world.propositions)}
    missing = [p for p in propositions if p not in index]
    if missing:
        raise LabelError(
            f"the task's propositions {missing} are not among the world's "
            f"{list(world.propositions)}"
        )
    letters = np.zeros(len(world.letters), dtype=np.int64)
    for j, p in enumerate(propositions):
        letters |= ((world.letters >> index[p]) & 1) << j
    return letters


def estimate(world: World, automaton: DigitalAutomaton) -> tuple[int, int]:
    """Upper bounds on the product's states and transitions, before it is built (see the
    module docstring): ``(S * Q + 2, Q * T + S * J)``."""
    q = len(automaton.states)
    states = world.num_states * q + 2
    transitions = q * len(world.transitions.targets) + world.num_states * len(automaton.epsilon)
    return states, transitions


def check_size(
    world: World, automaton: DigitalAutomaton, max_product_states: int | None
) -> tuple[int, int]:
    """:func:`estimate`, raising :class:`ProductSizeError` when it passes the limit
    (``None``: no limit)."""
    states, transitions = estimate(world, automaton)
    if max_product_states is None:
        return states, transitions
    if states > max_product_states or transitions > TRANSITIONS_PER_STATE * max_product_states:
        raise ProductSizeError(
            f"the product of {world.num_states:,} world states and {len(automaton.states):,} "
            f"automaton states may have {states:,} states and {transitions:,} transitions, past "
            f"the limit of {max_product_states:,} states ({TRANSITIONS_PER_STATE} times as many "
            "transitions); raise it with --max-product-states N (max_product_states from "
            "Python), or shrink the world or the formula's bounds"
        )
    return states, transitions


def build_product(
    world: World,
    automaton: DigitalAutomaton,
    *,
    max_product_states: int | None = DEFAULT_MAX_PRODUCT_STATES,
    time_limit: float | None = DEFAULT_TIME_LIMIT,
    deadline: Deadline | None = None,
) -> Product:
    """The reachable product of ``world`` and ``automaton`` (see the module docstring).

    Refuses a product whose size bound passes ``max_product_states`` (``None``: no limit) with
    :class:`ProductSizeError`; stops with :class:`mitlc.limits.LimitError` after
    ``time_limit`` seconds (``None``: no limit), or at ``deadline`` when one is given."""
    check_size(world, automaton, max_product_states)
    clock = Deadline.of(deadline, time_limit, "the product build").at("the product build")
    return _Builder(world, automaton, clock).build()


class _Builder:
    """Breadth-first exploration, one frontier (all states of a level) at a time in numpy."""

    def __init__(self, world: World, automaton: DigitalAutomaton, deadline: Deadline) -> None:
        self.world, self.deadline = world, deadline
        self.letters = automaton_letters(world, automaton.propositions)
        self.num_q = len(automaton.states)
        self.delta = np.asarray(automaton.delta, dtype=np.int64)
        self.marks = np.asarray(automaton.marks, dtype=np.int64)
        self.num_sets = automaton.num_sets
        kinds = {"pending": 0, "violated": 1, "satisfied": 2}
        self.verdict = np.array([kinds[s.verdict] for s in automaton.states], dtype=np.int64)
        jumps = sorted(automaton.epsilon)
        self.jump_ptr = np.searchsorted(
            np.array([j[0] for j in jumps], dtype=np.int64), np.arange(self.num_q + 1)
        )
        self.jump_target = np.array([j[1] for j in jumps], dtype=np.int64)
        self.ids = np.full(world.num_states * self.num_q, -1, dtype=np.int64)
        self.codes: list[IntArray] = [np.array([-1, -1], dtype=np.int64)]
        self.count = 2
        self.initial_code = world.start * self.num_q + automaton.initial

    def intern(self, codes: IntArray) -> tuple[IntArray, IntArray]:
        """Product ids of ``s * num_q + q`` codes (new ones numbered in order of first
        appearance), and the new states' ids."""
        kind = self.verdict[codes % self.num_q]
        out = np.where(kind == 1, VIOLATED, SATISFIED).astype(np.int64)
        pending = kind == 0
        fresh = codes[pending][self.ids[codes[pending]] < 0]
        unique, first = np.unique(fresh, return_index=True)
        new_codes = unique[np.argsort(first, kind="stable")]
        new_ids = np.arange(self.count, self.count + len(new_codes), dtype=np.int64)
        self.ids[new_codes] = new_ids
        self.codes.append(new_codes)
        self.count += len(new_codes)
        out[pending] = self.ids[codes[pending]]
        return out, new_ids

    def build(self) -> Product:
        world, num_q = self.world, self.num_q
        all_sets = (1 << self.num_sets) - 1
        # choices: (state, order key, action, marks); edges: (choice, target, probability)
        c_state = [np.array([VIOLATED, SATISFIED])]
        c_key = [np.zeros(2, dtype=np.int64)]
        c_action = [np.zeros(2, dtype=np.int64)]
        c_marks = [np.array([0, all_sets], dtype=np.int64)]
        e_choice = [np.array([0, 1])]
        e_target = [np.array([VIOLATED, SATISFIED])]
        e_prob = [np.ones(2)]
        num_choices = 2
        initial, frontier = self.intern(np.array([self.initial_code]))
        codes = self.codes[-1]
        while len(frontier):
            self.deadline.check_now()
            s, q = codes // num_q, codes % num_q
            letter = self.letters[s]
            q_next, marks = self.delta[q, letter], self.marks[q, letter]
            batches = []
            for a in range(world.num_actions):
                rows = s * world.num_actions + a
                lo, hi = world.transitions.indptr[rows], world.transitions.indptr[rows + 1]
                counts = hi - lo
                index = np.repeat(lo - np.cumsum(counts) + counts, counts) + np.arange(counts.sum())
                targets = world.transitions.targets[index] * num_q + np.repeat(q_next, counts)
                batches.append(
                    (
                        a,
                        np.arange(len(frontier)),
                        counts,
                        targets,
                        world.transitions.probs[index],
                        marks,
                    )
                )
            jump_counts = self.jump_ptr[q + 1] - self.jump_ptr[q]
            if jump_counts.any():
                owner = np.repeat(np.arange(len(frontier)), jump_counts)
                rank = np.arange(jump_counts.sum()) - np.repeat(
                    np.cumsum(jump_counts) - jump_counts, jump_counts
                )
                t = self.jump_target[self.jump_ptr[q[owner]] + rank]
                batches.append(
                    (
                        -1,
                        owner,
                        np.ones(len(owner), dtype=np.int64),
                        s[owner] * num_q + t,
                        np.ones(len(owner)),
                        np.zeros(len(owner), dtype=np.int64),
                    )
                )
            new_frontier, level_start = [], len(self.codes)
            for a, owner, counts, targets, probs, choice_marks in batches:
                ids, new = self.intern(targets)
                new_frontier.append(new)
                n = len(owner)
                choice_ids = np.arange(num_choices, num_choices + n)
                c_state.append(frontier[owner])
                c_marks.append(choice_marks[owner] if a >= 0 else choice_marks)
                if a >= 0:
                    c_key.append(np.full(n, a, dtype=np.int64))
                    c_action.append(np.full(n, a, dtype=np.int64))
                else:
                    jumped = targets % num_q
                    c_key.append(world.num_actions + jumped)
                    c_action.append(-1 - jumped)
                e_choice.append(np.repeat(choice_ids, counts))
                e_target.append(ids)
                e_prob.append(probs)
                num_choices += n
            frontier = np.concatenate(new_frontier)
            # The new states' ids are consecutive, in the order their codes were appended.
            codes = np.concatenate(self.codes[level_start:])
        return self._assemble(
            initial[0], c_state, c_key, c_action, c_marks, e_choice, e_target, e_prob
        )

    def _assemble(
        self,
        initial: np.int64,
        c_state: list[IntArray],
        c_key: list[IntArray],
        c_action: list[IntArray],
        c_marks: list[IntArray],
        e_choice: list[IntArray],
        e_target: list[IntArray],
        e_prob: list[FloatArray],
    ) -> Product:
        """Choices sorted by state, then action (jumps last, by target); duplicate targets of a
        choice summed; targets sorted within each choice."""
        state, key = np.concatenate(c_state), np.concatenate(c_key)
        order = np.lexsort((key, state))
        rank = np.empty_like(order)
        rank[order] = np.arange(len(order))
        choice = rank[np.concatenate(e_choice)]
        target = np.concatenate(e_target)
        n = self.count
        combined = choice * n + target
        unique, inverse = np.unique(combined, return_inverse=True)
        probs = np.zeros(len(unique))
        np.add.at(probs, inverse, np.concatenate(e_prob))
        edge_choice = unique // n
        indptr = np.searchsorted(edge_choice, np.arange(len(order) + 1))
        sorted_state = state[order]
        codes = np.concatenate(self.codes)
        world_state = np.where(codes >= 0, codes // self.num_q, -1)
        automaton_state = np.where(codes >= 0, codes % self.num_q, -1)
        return Product(
            world_state=world_state.astype(np.int64),
            automaton_state=automaton_state.astype(np.int64),
            initial=int(initial),
            choice_ptr=np.searchsorted(sorted_state, np.arange(n + 1)).astype(np.int64),
            action=np.concatenate(c_action)[order],
            marks=np.concatenate(c_marks)[order],
            transitions=Sparse(indptr.astype(np.int64), (unique % n).astype(np.int64), probs),
            num_sets=self.num_sets,
        )
