"""The explicit product of a world and a digital automaton: ``build_product(world, automaton)``.

A product state ``(s, q)`` is the world in state ``s`` with the automaton in state ``q`` about
to read the letter of ``s`` (position 0 is the start cell, before the first action); ``L(s)``
is that letter over the automaton's propositions, mapped by name from the world's
(:func:`automaton_letters`). A world
action ``a`` moves to ``(s', delta[q][L(s)])`` with the world's probability, in the acceptance
sets ``marks[q][L(s)]``; an epsilon jump ``q -> t`` of the automaton is an extra choice that
moves to ``(s, t)`` with probability 1 and no marks (a state's jumps come after its world
actions, in the order of the automaton's ``jumps(q)``, so jump ``j`` is the task wrapper's action
``num_actions + j``). Every product state whose automaton state
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
from dataclasses import dataclass, replace
from types import EllipsisType
from typing import Any

import numpy as np

from mitlc.automata.digital import DigitalAutomaton
from mitlc.errors import MitlcError
from mitlc.limits import DEFAULT_MAX_PRODUCT_STATES, DEFAULT_TIME_LIMIT, Deadline, LimitError
from mitlc.task import TaskAutomaton, TaskMonitor, rules
from mitlc.worlds.model import BoolArray, FloatArray, IntArray, Sparse, World

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
    initial_distribution: tuple[tuple[int, float], ...] = ()
    end: BoolArray | None = None
    """Per state, whether an episode that stops there while pending is a success by the
    finite trace it read (:attr:`mitlc.automata.DigitalState.end` of its automaton state;
    ``None``: no state's). The absorbing states' are ``False`` and ``True``."""
    """The product states the episode may start in, each once, with their probabilities (the
    world's start distribution; one state with probability 1 for a certain start). ``initial``
    is the one of the world's ``start``."""

    @property
    def starts(self) -> tuple[tuple[int, float], ...]:
        """:attr:`initial_distribution`, or the certain ``initial`` for a product made
        without one."""
        return self.initial_distribution or ((self.initial, 1.0),)

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


def product_verdicts(product: Product) -> IntArray:
    """The verdict code (:mod:`mitlc.task.rules`) of every product state: the two absorbing
    states are violated and satisfied, every other one pending."""
    verdict = np.full(product.num_states, rules.PENDING, dtype=np.int64)
    verdict[VIOLATED], verdict[SATISFIED] = rules.VIOLATED, rules.SATISFIED
    return verdict


def product_ends(product: Product) -> BoolArray:
    """The end value of every product state (:attr:`Product.end`; all ``False`` but the
    satisfied state's for a product made without them)."""
    if product.end is not None:
        return product.end
    end = np.zeros(product.num_states, dtype=np.bool_)
    end[SATISFIED] = True
    return end


def recursion_ends(product: Product) -> FloatArray:
    """The finite-horizon recursions' values when the horizon ends, ``values[mask, x]``
    (:func:`mitlc.task.rules.recursion_ends` of the product's verdicts and end values)."""
    return rules.recursion_ends(product_verdicts(product), product_ends(product), product.num_sets)


def start_distribution(world: World) -> tuple[tuple[int, float], ...]:
    """The world's start states with their probabilities, the most probable first (the
    world's ``start``); a certain start is ``((start, 1.0),)``."""
    given = world.start_distribution
    if not given:
        return ((world.start, 1.0),)
    rest = [(int(s), float(p)) for s, p in given if s != world.start]
    first = [(int(s), float(p)) for s, p in given if s == world.start]
    return tuple(first + rest)


def start_average(product: Product, values: FloatArray) -> float:
    """``values`` (one per product state) averaged over the start distribution."""
    return float(sum(p * float(values[x]) for x, p in product.starts))


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
    module docstring): ``(S * Q + 2, Q * T + S * J + 2 A)``, the two absorbing states with a
    loop per action."""
    q = len(automaton.states)
    states = world.num_states * q + 2
    transitions = q * len(world.transitions.targets) + world.num_states * len(automaton.epsilon)
    transitions += 2 * world.num_actions
    return states, transitions


def _too_large(what: str, max_product_states: int) -> ProductSizeError:
    return ProductSizeError(
        f"{what}, past the limit of {max_product_states:,} states ({TRANSITIONS_PER_STATE} "
        "times as many transitions); raise it with --max-product-states N (max_product_states "
        "from Python), or shrink the world or the formula's bounds"
    )


def check_size(
    world: World, automaton: DigitalAutomaton, max_product_states: int | None
) -> tuple[int, int]:
    """:func:`estimate`, raising :class:`ProductSizeError` when it passes the limit
    (``None``: no limit)."""
    states, transitions = estimate(world, automaton)
    if max_product_states is None:
        return states, transitions
    if states > max_product_states or transitions > TRANSITIONS_PER_STATE * max_product_states:
        raise _too_large(
            f"the product of {world.num_states:,} world states and {len(automaton.states):,} "
            f"automaton states may have {states:,} states and {transitions:,} transitions",
            max_product_states,
        )
    return states, transitions


def build_product(
    world: World,
    automaton: TaskAutomaton,
    *,
    max_product_states: int | None = DEFAULT_MAX_PRODUCT_STATES,
    time_limit: float | None = DEFAULT_TIME_LIMIT,
    memory_limit: float | EllipsisType | None = ...,
    deadline: Deadline | None = None,
) -> Product:
    """The reachable product of ``world`` and ``automaton`` (see the module docstring).

    ``automaton`` is the eager :class:`DigitalAutomaton`, whose size bound is checked before
    anything is built, or a lazy one, whose states are made as the product reaches them; either
    way the build stops with :class:`ProductSizeError` once it has more than
    ``max_product_states`` states (``None``: no limit). It stops with
    :class:`mitlc.limits.LimitError` after ``time_limit`` seconds
    or past ``memory_limit`` GB held (``None``: no limit), or at
    ``deadline`` when one is given."""
    if isinstance(automaton, DigitalAutomaton):
        check_size(world, automaton, max_product_states)
    clock = Deadline.of(deadline, time_limit, "the product build", memory_limit).at(
        "the product build"
    )
    monitor = TaskMonitor(automaton, world.rewards)
    return _Builder(world, monitor, clock, max_product_states).build()


class _Builder:
    """Breadth-first exploration, one frontier (all states of a level) at a time in numpy.

    A pair ``(s, q)`` is coded ``q * S + s``, so the table of ids grows with the automaton
    states the monitor makes; the automaton's steps, verdicts and jumps are the monitor's."""

    def __init__(
        self, world: World, monitor: TaskMonitor, deadline: Deadline, limit: int | None
    ) -> None:
        self.world, self.monitor, self.deadline, self.limit = world, monitor, deadline, limit
        self.letters = automaton_letters(world, monitor.propositions)
        self.num_s = world.num_states
        self.ids = np.full(0, -1, dtype=np.int64)
        self.codes: list[IntArray] = [np.array([-1, -1], dtype=np.int64)]
        self.count = 2

    def intern(self, codes: IntArray) -> tuple[IntArray, IntArray]:
        """Product ids of ``q * S + s`` codes (new ones numbered in order of first
        appearance), and the new states' ids."""
        kind = self.monitor.verdicts(codes // self.num_s)
        out = np.where(kind == rules.VIOLATED, VIOLATED, SATISFIED).astype(np.int64)
        pending = kind == rules.PENDING
        if len(codes) and int(codes.max()) >= len(self.ids):
            grown = np.full(max(int(codes.max()) + 1, 2 * len(self.ids)), -1, dtype=np.int64)
            grown[: len(self.ids)] = self.ids
            self.ids = grown
        fresh = codes[pending][self.ids[codes[pending]] < 0]
        unique, first = np.unique(fresh, return_index=True)
        new_codes = unique[np.argsort(first, kind="stable")]
        if self.limit is not None and self.count + len(new_codes) > self.limit:
            raise _too_large(
                f"the product of {self.num_s:,} world states and its task grows past "
                f"{self.limit:,} states",
                self.limit,
            )
        new_ids = np.arange(self.count, self.count + len(new_codes), dtype=np.int64)
        self.ids[new_codes] = new_ids
        self.codes.append(new_codes)
        self.count += len(new_codes)
        out[pending] = self.ids[codes[pending]]
        return out, new_ids

    def jumps(self, q: IntArray) -> tuple[IntArray, IntArray, IntArray]:
        """For each entry of ``q``: how many epsilon jumps it has, their targets and their
        ranks in the monitor's order of the state's jumps (all of them, entry after entry);
        the monitor is asked once per distinct state."""
        counts = self.monitor.jump_counts(q)
        none = np.zeros(0, dtype=np.int64)
        if not counts.any():
            return counts, none, none
        distinct, inverse = np.unique(q, return_inverse=True)
        lists = [self.monitor.jumps(state) for state in distinct.tolist()]
        sizes = np.array([len(targets) for targets in lists], dtype=np.int64)
        counts = sizes[inverse]
        if not sizes.any():
            return counts, none, none
        flat = np.array([t for targets in lists for t in targets], dtype=np.int64)
        start = np.cumsum(sizes) - sizes
        owner = np.repeat(np.arange(len(q)), counts)
        rank = np.arange(len(owner)) - np.repeat(np.cumsum(counts) - counts, counts)
        targets: IntArray = flat[start[inverse[owner]] + rank]
        return counts, targets, rank

    def build(self) -> Product:
        world, num_s, monitor = self.world, self.num_s, self.monitor
        all_sets = monitor.all_sets
        # choices: (state, order key, action, marks); edges: (choice, target, probability)
        c_state = [np.array([VIOLATED, SATISFIED])]
        c_key = [np.zeros(2, dtype=np.int64)]
        c_action = [np.zeros(2, dtype=np.int64)]
        c_marks = [np.array([0, all_sets], dtype=np.int64)]
        e_choice = [np.array([0, 1])]
        e_target = [np.array([VIOLATED, SATISFIED])]
        e_prob = [np.ones(2)]
        num_choices = 2
        starts = start_distribution(world)
        q0 = monitor.reset().q
        initial, frontier = self.intern(q0 * num_s + np.array([s for s, _ in starts]))
        codes = self.codes[-1]
        while len(frontier):
            self.deadline.check_now()
            s, q = codes % num_s, codes // num_s
            q_next, marks = monitor.successors(q, self.letters[s])
            batches: list[tuple[int, Any, Any, Any, Any, Any, IntArray | None]] = []
            for a in range(world.num_actions):
                rows = s * world.num_actions + a
                lo, hi = world.transitions.indptr[rows], world.transitions.indptr[rows + 1]
                counts = hi - lo
                index = np.repeat(lo - np.cumsum(counts) + counts, counts) + np.arange(counts.sum())
                targets = np.repeat(q_next, counts) * num_s + world.transitions.targets[index]
                batches.append(
                    (
                        a,
                        np.arange(len(frontier)),
                        counts,
                        targets,
                        world.transitions.probs[index],
                        marks,
                        None,
                    )
                )
            jump_counts, jump_targets, jump_ranks = self.jumps(q)
            if jump_counts.any():
                owner = np.repeat(np.arange(len(frontier)), jump_counts)
                batches.append(
                    (
                        -1,
                        owner,
                        np.ones(len(owner), dtype=np.int64),
                        jump_targets * num_s + s[owner],
                        np.ones(len(owner)),
                        np.zeros(len(owner), dtype=np.int64),
                        jump_ranks,
                    )
                )
            new_frontier, level_start = [], len(self.codes)
            for a, owner, counts, targets, probs, choice_marks, ranks in batches:
                ids, new = self.intern(targets)
                new_frontier.append(new)
                n = len(owner)
                choice_ids = np.arange(num_choices, num_choices + n)
                c_state.append(frontier[owner])
                c_marks.append(choice_marks[owner] if a >= 0 else choice_marks)
                if a >= 0:
                    c_key.append(np.full(n, a, dtype=np.int64))
                    c_action.append(np.full(n, a, dtype=np.int64))
                else:  # jumps after the world actions, in the monitor's order
                    assert ranks is not None
                    c_key.append(world.num_actions + ranks)
                    c_action.append(-1 - targets // num_s)
                e_choice.append(np.repeat(choice_ids, counts))
                e_target.append(ids)
                e_prob.append(probs)
                num_choices += n
            frontier = np.concatenate(new_frontier)
            # The new states' ids are consecutive, in the order their codes were appended.
            codes = np.concatenate(self.codes[level_start:])
        product = self._assemble(
            initial[0], c_state, c_key, c_action, c_marks, e_choice, e_target, e_prob
        )
        merged: dict[int, float] = {}
        for x, (_, p) in zip(initial.tolist(), starts, strict=True):
            merged[x] = merged.get(x, 0.0) + p
        distribution = tuple(merged.items())
        return replace(product, initial_distribution=distribution)

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
        """Choices sorted by state, then action (jumps last, in the order of the automaton
        state's jumps: the wrapper's jump actions); duplicate targets of a choice summed;
        targets sorted within each choice."""
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
        world_state = np.where(codes >= 0, codes % self.num_s, -1)
        automaton_state = np.where(codes >= 0, codes // self.num_s, -1)
        end = self.monitor.ends(np.maximum(automaton_state, 0))
        end[VIOLATED], end[SATISFIED] = False, True
        return Product(
            world_state=world_state.astype(np.int64),
            automaton_state=automaton_state.astype(np.int64),
            initial=int(initial),
            choice_ptr=np.searchsorted(sorted_state, np.arange(n + 1)).astype(np.int64),
            action=np.concatenate(c_action)[order],
            marks=np.concatenate(c_marks)[order],
            transitions=Sparse(indptr.astype(np.int64), (unique % n).astype(np.int64), probs),
            num_sets=self.monitor.num_sets,
            end=end,
        )
