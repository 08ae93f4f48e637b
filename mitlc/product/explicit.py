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
from dataclasses import dataclass
from types import EllipsisType

import numpy as np

from mitlc.automata.digital import DigitalAutomaton
from mitlc.automata.ends import END_FAILS, END_HOLDS
from mitlc.errors import MitlcError
from mitlc.limits import DEFAULT_MAX_PRODUCT_STATES, DEFAULT_TIME_LIMIT, Deadline, LimitError
from mitlc.task import TaskAutomaton, TaskMonitor, rules
from mitlc.worlds.model import FloatArray, IntArray, Sparse, World

VIOLATED, SATISFIED = 0, 1
"""The ids of the two absorbing product states."""


@dataclass(frozen=True, slots=True)
class Product:
    """A product MDP in compressed rows of choices (see the module docstring).

    State ``x`` has the choices ``choice_ptr[x] .. choice_ptr[x+1]-1``; choice ``c`` leads to
    ``transitions.row(c)``, is world action ``action[c]`` (or, when negative, the epsilon jump
    to automaton state ``-1 - action[c]``) and is in the acceptance sets ``marks[c]``.

    As :func:`build_product` makes it, the arrays per choice and per transition hold 32-bit
    integers (``np.int32``) wherever the indices fit, and the probabilities 64-bit floats: about
    12 bytes a transition and 12 a choice. The solvers read them in place (scipy shares them).
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
    end: IntArray | None = None
    """Per state, the end code of an episode that stops there while pending (whether the
    finite trace it read is a success: :attr:`mitlc.automata.DigitalState.end` of its automaton
    state; ``None``: no state's). The absorbing states' fail and hold."""
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


def product_ends(product: Product) -> IntArray:
    """The end code (:mod:`mitlc.automata.ends`) of every product state (:attr:`Product.end`;
    all fails but the satisfied state's for a product made without them)."""
    if product.end is not None:
        return product.end
    end = np.zeros(product.num_states, dtype=np.int64)
    end[SATISFIED] = END_HOLDS
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


def within(states: int, transitions: int, max_product_states: int | None) -> bool:
    """Whether a product of ``states`` and ``transitions`` is within ``max_product_states``
    (and as many transitions as :data:`TRANSITIONS_PER_STATE` times it; ``None``: no limit)."""
    if max_product_states is None:
        return True
    return (
        states <= max_product_states and transitions <= TRANSITIONS_PER_STATE * max_product_states
    )


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

    ``automaton`` is the eager :class:`DigitalAutomaton` or a lazy one, whose states are made
    as the product reaches them; either way the build stops with :class:`ProductSizeError` once
    it has more than ``max_product_states`` states (``None``: no limit). The eager automaton's
    bound (:func:`estimate`: every world state with every automaton state) reserves the
    product's memory before anything is built where it is within the limit; past it, the
    reachable product is counted as it is built, as for a lazy automaton (a team's joint
    states meet few of the automaton's: the warehouse's bound is 30 times its product). It
    stops with
    :class:`mitlc.limits.LimitError` after ``time_limit`` seconds
    or past ``memory_limit`` GB held (``None``: no limit), or at
    ``deadline`` when one is given."""
    clock = Deadline.of(deadline, time_limit, "the product build", memory_limit).at(
        "the product build"
    )
    monitor = TaskMonitor(automaton, world.rewards)
    if isinstance(automaton, DigitalAutomaton):
        states, transitions = estimate(world, automaton)
        if within(states, transitions, max_product_states):  # else counted as built
            clock.reserve(product_bytes(states, transitions), "the product's arrays")
    return _build(world, monitor, clock, max_product_states)


def product_bytes(states: int, transitions: int) -> int:
    """About the bytes of a product of ``states`` and ``transitions`` as built (12 a transition,
    its choices and states besides; a grid world has about 2.5 transitions a choice)."""
    from mitlc.product.builder import BYTES_PER_CHOICE, BYTES_PER_STATE, BYTES_PER_TRANSITION

    per_transition = BYTES_PER_TRANSITION + BYTES_PER_CHOICE // 2
    return states * BYTES_PER_STATE + transitions * per_transition


def _build(world: World, monitor: TaskMonitor, clock: Deadline, limit: int | None) -> Product:
    """The product explored by :class:`mitlc.product.builder.Builder`, assembled."""
    from mitlc.product.builder import Builder

    builder = Builder(world, monitor, automaton_letters(world, monitor.propositions), clock, limit)
    starts = start_distribution(world)
    q0 = monitor.reset().q
    initial = builder.build(q0 * world.num_states + np.array([s for s, _ in starts]))
    codes = builder.codes.finish()
    num_s = world.num_states
    world_state = np.where(codes >= 0, codes % num_s, -1)
    automaton_state = np.where(codes >= 0, codes // num_s, -1)
    del codes
    end = monitor.ends(np.maximum(automaton_state, 0))
    end[VIOLATED], end[SATISFIED] = END_FAILS, END_HOLDS
    merged: dict[int, float] = {}
    for x, (_, p) in zip(initial.tolist(), starts, strict=True):
        merged[x] = merged.get(x, 0.0) + p
    indptr = builder.indptr.finish()
    targets = builder.targets.finish()
    if indptr.dtype != targets.dtype:  # scipy shares the arrays only when both agree
        indptr, targets = indptr.astype(np.int64), targets.astype(np.int64)
    return Product(
        world_state=world_state,
        automaton_state=automaton_state,
        initial=int(initial[0]),
        choice_ptr=builder.choice_ptr.finish(),
        action=builder.action.finish(),
        marks=builder.marks.finish(),
        transitions=Sparse(indptr, targets, builder.probs.finish()),
        num_sets=monitor.num_sets,
        initial_distribution=tuple(merged.items()),
        end=end,
    )
