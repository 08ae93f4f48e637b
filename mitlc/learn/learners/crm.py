"""Counterfactual experience for automaton tasks (Toro Icarte, Klassen, Valenzano and McIlraith,
"Reward Machines: Exploiting Reward Function Structure in Reinforcement Learning", JAIR 73,
2022: CRM).

The world's transition does not depend on the task's automaton: a world step ``(s, a, s')``
that an episode experienced in one automaton state is a sample of what the same step does in
every other automaton state and frontier. From each experienced world step,
:meth:`Counterfactuals.of` makes the transition of every product state ``(s, q)`` and frontier
``mask`` that the product has: the automaton reads the letter of ``s`` from ``q`` (the task
monitor's successor), the frontier, reward, verdict and termination follow the rules of
:mod:`mitlc.task.rules`, and the next product state is ``(s', q')`` (or the absorbing state of
the verdict). A learner trains on all of them instead of the one it experienced.

Only world actions give counterfactuals (an epsilon jump moves the automaton alone). A step
whose episode entered an absorbing state does not tell ``s'`` (the product merges it away):
its counterfactuals are skipped, which does not bias the others, since whether the real
automaton step decides the task depends on ``s`` and ``q`` alone, not on ``s'``. A
counterfactual whose next pair ``(s', q')`` the product never reached is skipped too.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mitlc.product.explicit import SATISFIED, VIOLATED, Product, automaton_letters
from mitlc.task import TaskAutomaton, TaskMonitor, rules
from mitlc.task.costs import StepTable, TransitionCosts, world_cost
from mitlc.worlds.model import BoolArray, FloatArray, IntArray, World


@dataclass(frozen=True, slots=True)
class Batch:
    """Transitions to learn from, as arrays: ``(mask, state) --action--> (next_mask,
    next_state)`` with its reward, whether it added a set to the frontier and whether it ended
    the episode."""

    mask: IntArray
    state: IntArray
    action: IntArray
    reward: FloatArray
    accepting: BoolArray
    terminated: BoolArray
    next_mask: IntArray
    next_state: IntArray


@dataclass(frozen=True, slots=True)
class Counterfactuals:
    """The product's pairs and the automaton's steps over the world's letters, as tables."""

    pair: IntArray
    """``pair[q, s]``: the product state of world state ``s`` with automaton state ``q`` (-1
    where the product has none; the absorbing state where ``q`` is decided)."""
    column: IntArray
    """``column[s]``: the index of the letter of ``s`` among the world's distinct letters."""
    next_q: IntArray
    """``next_q[q, column]``: the automaton's successor on that letter."""
    marks: IntArray
    verdict: IntArray
    """The verdict code of every automaton state."""
    world_state: IntArray
    """Of every product state (-1 at the absorbing ones)."""
    automaton_state: IntArray
    members_ptr: IntArray
    members: IntArray
    """``members[members_ptr[s]:members_ptr[s + 1]]``: the live product states of world state
    ``s``."""
    moves: FloatArray
    """The world's reward of each world action (``move`` for all but ``stay``)."""
    all_sets: int
    popcount: IntArray
    rewards: rules.TaskRewards
    costs: _Costs | None = None
    """The world's costs (``costs:``), taken off each counterfactual's reward."""

    @staticmethod
    def build(product: Product, world: World, automaton: TaskAutomaton) -> Counterfactuals:
        """The tables of ``product``, the product of ``world`` and ``automaton``."""
        live = product.world_state >= 0
        num_q = int(product.automaton_state.max()) + 1
        letters = automaton_letters(world, automaton.propositions)
        distinct, column = np.unique(letters, return_inverse=True)
        monitor = TaskMonitor(automaton, world.rewards)
        q = np.repeat(np.arange(num_q), len(distinct))
        next_q, marks = monitor.successors(q, np.tile(distinct, num_q))
        top = max(num_q, int(next_q.max()) + 1)
        verdict = monitor.verdicts(np.arange(top))
        pair = np.full((top, world.num_states), -1, dtype=np.int64)
        pair[product.automaton_state[live], product.world_state[live]] = np.flatnonzero(live)
        pair[verdict == rules.VIOLATED] = VIOLATED
        pair[verdict == rules.SATISFIED] = SATISFIED
        moves = np.array([0.0 if a == "stay" else world.rewards.move for a in world.actions])
        members = np.flatnonzero(live)
        members = members[np.argsort(product.world_state[members], kind="stable")]
        members_ptr = np.searchsorted(
            product.world_state[members], np.arange(world.num_states + 1)
        ).astype(np.int64)
        return Counterfactuals(
            pair=pair,
            column=column.astype(np.int64),
            next_q=next_q.reshape(num_q, len(distinct)),
            marks=marks.reshape(num_q, len(distinct)),
            verdict=verdict,
            world_state=product.world_state,
            automaton_state=product.automaton_state,
            members_ptr=members_ptr,
            members=members,
            moves=moves,
            all_sets=(1 << product.num_sets) - 1,
            popcount=np.asarray(rules.popcounts(product.num_sets), dtype=np.int64),
            rewards=world.rewards,
            costs=None if world.costs is None else _Costs.build(world, automaton, top),
        )

    def of(self, state: IntArray, action: IntArray, next_state: IntArray) -> Batch:
        """Every counterfactual of the experienced world steps ``state --action-->
        next_state`` (product states; steps that jumped or ended in an absorbing state give
        none): one per automaton state the product pairs with ``s`` and per frontier."""
        s, s_next = self.world_state[state], self.world_state[next_state]
        num_world = len(self.moves)
        keep = (s >= 0) & (s_next >= 0) & (action < num_world)
        s, s_next, action = s[keep], s_next[keep], action[keep]
        masks = max(self.all_sets, 1)  # the frontiers a round can have
        counts = self.members_ptr[s + 1] - self.members_ptr[s]
        owner = np.repeat(np.arange(len(s)), counts)
        rank = np.arange(len(owner)) - np.repeat(np.cumsum(counts) - counts, counts)
        source = self.members[self.members_ptr[s[owner]] + rank]
        step, source = np.repeat(owner, masks), np.repeat(source, masks)
        mask = np.tile(np.arange(masks), len(owner))
        q = self.automaton_state[source]
        column = self.column[s[step]]
        q_next, marks = self.next_q[q, column], self.marks[q, column]
        target = self.pair[q_next, s_next[step]]
        reached = target >= 0
        step, mask, source, q_next, marks, target = (
            step[reached],
            mask[reached],
            source[reached],
            q_next[reached],
            marks[reached],
            target[reached],
        )
        next_mask, new, _ = rules.account(mask, marks, self.all_sets, self.popcount)
        verdict = self.verdict[q_next]
        reward = rules.reward(new, verdict, self.rewards) + self.moves[action[step]]
        if self.costs is not None:
            reward = reward - self.costs.paid(action[step], s[step], s_next[step], q)
        return Batch(
            mask=mask,
            state=source,
            action=action[step],
            reward=np.asarray(reward, dtype=np.float64),
            accepting=new > 0,
            terminated=np.asarray(rules.terminated(verdict), dtype=np.bool_),
            next_mask=next_mask,
            next_state=target,
        )


@dataclass(frozen=True, slots=True)
class _Costs:
    """What a counterfactual step costs, by the one definition (:mod:`mitlc.task.costs`):
    :func:`~mitlc.task.costs.world_cost` of the world step, and the transition rules' cost
    per (automaton state, world letter), tabled once."""

    table: StepTable
    letters: IntArray
    """Per world state, its index among the distinct world letters."""
    world_letters: IntArray
    """Per world state, its world letter."""
    rules_cost: FloatArray
    """``rules_cost[q, k]``: the rules' cost of automaton state ``q`` on letter ``k``."""

    @staticmethod
    def build(world: World, automaton: TaskAutomaton, num_q: int) -> _Costs:
        """The tables of ``world``'s costs over ``automaton``'s first ``num_q`` states."""
        distinct, index = np.unique(world.letters, return_inverse=True)
        rules_of = TransitionCosts(world, automaton)
        table = np.zeros((num_q, len(distinct)))
        if rules_of.rules:
            for q in range(num_q):
                for k, letter in enumerate(distinct.tolist()):
                    table[q, k] = rules_of.cost(q, int(letter))
        return _Costs(StepTable.of(world), index.astype(np.int64), world.letters, table)

    def paid(self, action: IntArray, s: IntArray, s_next: IntArray, q: IntArray) -> FloatArray:
        """The cost of world steps ``s --action--> s_next`` read by automaton states ``q``."""
        left, arrived = self.world_letters[s], self.world_letters[s_next]
        world = np.asarray(world_cost(self.table, action, left, arrived), dtype=np.float64)
        cost: FloatArray = world + self.rules_cost[q, self.letters[s]]
        return cost


def select(batch: Batch, keep: BoolArray) -> Batch:
    """The transitions of ``batch`` where ``keep``."""
    return Batch(*(getattr(batch, f)[keep] for f in Batch.__slots__))


def concatenate(first: Batch, second: Batch) -> Batch:
    """Both batches' transitions."""
    return Batch(
        *(np.concatenate([getattr(first, f), getattr(second, f)]) for f in Batch.__slots__)
    )
