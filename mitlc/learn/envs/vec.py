"""A batch of product episodes stepped together in numpy: ``VecProduct(tables, n, rng)``.

The learners' simulator. It reads the transition tables of the explicit product
(:func:`mitlc.product.explicit.build_product`), so learning and checking see one model, and
follows the conventions of :class:`mitlc.product.env.ProductEnv` (the gymnasium environment):

* actions ``0 .. A-1`` are the world's, ``A + j`` the ``j``-th epsilon jump of the automaton
  state (in the order of its ``jumps``, as the task wrapper's); a jump takes no time.
  :attr:`Tables.valid` masks the jumps a state lacks (learners never choose them);
* rewards: ``accept`` for each acceptance set new in the current round (a generalized Büchi
  frontier, emptied when every set has been seen), ``satisfied`` / ``violated`` on entering those
  states, ``move`` for each world action other than ``stay``;
* an episode ends when it enters *satisfied* or *violated* (terminated) or after ``horizon``
  world actions (truncated); whether it is a **success** is :func:`mitlc.task.rules.success`
  of the state it stops in (its verdict, its completed rounds, its end value).

Sampling is inverse-CDF over one global cumulative array (``row + cumulative probability``), so
a step of ``n`` episodes is a handful of vectorised operations whatever ``n``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from mitlc.check.shield import Shield
from mitlc.check.shield_observed import ObservedShield
from mitlc.product.explicit import Product, product_ends, product_verdicts
from mitlc.task import rules
from mitlc.worlds.model import BoolArray, FloatArray, IntArray, Rewards, Sparse, World


@dataclass(frozen=True, slots=True)
class Tables:
    """The product as flat arrays for simulation (see the module docstring)."""

    num_world_actions: int
    num_actions: int
    """World actions plus the most epsilon jumps any state has."""
    initial: int
    choice: IntArray
    """``choice[x, a]``: the product choice of action ``a`` in state ``x`` (-1: not valid)."""
    valid: BoolArray
    """``choice >= 0``."""
    cumulative: FloatArray
    """Per transition ``c + P(first transitions of choice c up to this one)``."""
    indptr: IntArray
    targets: IntArray
    marks: IntArray
    moves: BoolArray
    """Per choice: a world action other than ``stay``."""
    world_state: IntArray
    automaton_state: IntArray
    num_sets: int
    horizon: int
    reward_accept: float
    reward_satisfied: float
    reward_violated: float
    reward_move: float
    observation: Sparse | None
    """For a POMDP, the observation distribution of each world state."""
    observation_cumulative: FloatArray | None
    num_observations: int
    """Observation ids (cells for an MDP)."""
    verdict: IntArray
    """The verdict code of each product state (:func:`mitlc.product.explicit.product_verdicts`)."""
    end: IntArray
    """The end code of each product state (:func:`mitlc.product.explicit.product_ends`)."""
    popcount: IntArray
    """:func:`mitlc.task.rules.popcounts` as an array."""
    starts: IntArray
    """The product states an episode may start in (``[initial]`` for a certain start)."""
    start_cumulative: FloatArray
    """Their cumulative probabilities."""
    shield: Shield | ObservedShield | None = None
    """The actions allowed per step (:mod:`mitlc.check.shield`; over a POMDP's observations,
    :mod:`mitlc.check.shield_observed`), or none."""
    cost: FloatArray | None = None
    """Per product transition, what it costs (:func:`mitlc.product.costs.product_costs`, the
    world's ``costs:``), taken from the step's reward; ``None``: no costs."""
    shield_enforced: bool = True
    """Whether :meth:`VecProduct.valid_actions` keeps to :attr:`shield` (else it only records
    the blocked actions taken: an audit)."""

    @property
    def rewards(self) -> Rewards:
        """The reward terms."""
        return Rewards(
            self.reward_accept, self.reward_satisfied, self.reward_violated, self.reward_move
        )

    @property
    def num_states(self) -> int:
        """Product states, the absorbing ones included."""
        return len(self.world_state)

    @property
    def num_automaton_states(self) -> int:
        """One more than the largest automaton state in the product."""
        return int(self.automaton_state.max()) + 1

    @property
    def all_sets(self) -> int:
        """The mask of all acceptance sets."""
        return (1 << self.num_sets) - 1


def _cumulative(sparse: Sparse) -> FloatArray:
    rows = np.repeat(np.arange(sparse.num_rows), np.diff(sparse.indptr))
    within = np.cumsum(sparse.probs)
    before = np.concatenate([[0.0], within])[sparse.indptr[:-1]]
    cumulative: FloatArray = rows + (within - np.repeat(before, np.diff(sparse.indptr)))
    return cumulative


def tables(product: Product, world: World) -> Tables:
    """The simulation tables of ``product``, the product of ``world`` with its task."""
    n, num_a = product.num_states, world.num_actions
    counts = np.diff(product.choice_ptr)
    width = max(num_a, int(counts.max()))
    choice = np.full((n, width), -1, dtype=np.int64)
    pending = product.world_state >= 0
    rank = np.arange(product.num_choices) - np.repeat(product.choice_ptr[:-1], counts)
    owner = np.repeat(np.arange(n), counts)
    keep = pending[owner]
    choice[owner[keep], rank[keep]] = np.flatnonzero(keep)
    pairs = product.starts
    for x, _ in pairs:  # a task decided at the start: one step on the absorbing state's loop
        if not pending[x]:
            choice[x, :num_a] = product.choice_ptr[x]
    stay = world.actions.index("stay") if "stay" in world.actions else -1
    observations = world.observations
    return Tables(
        num_world_actions=num_a,
        num_actions=width,
        initial=product.initial,
        choice=choice,
        valid=choice >= 0,
        cumulative=_cumulative(product.transitions),
        # the product keeps 32-bit indices; the episodes' states are 64-bit (checkpoints)
        indptr=product.transitions.indptr.astype(np.int64),
        targets=product.transitions.targets.astype(np.int64),
        marks=product.marks.astype(np.int64),
        moves=(product.action >= 0) & (product.action != stay),
        world_state=product.world_state,
        automaton_state=product.automaton_state,
        num_sets=product.num_sets,
        horizon=world.horizon,
        reward_accept=world.rewards.accept,
        reward_satisfied=world.rewards.satisfied,
        reward_violated=world.rewards.violated,
        reward_move=world.rewards.move,
        observation=None if observations is None else observations.model,
        observation_cumulative=None if observations is None else _cumulative(observations.model),
        num_observations=world.num_states if observations is None else len(observations.names),
        verdict=product_verdicts(product),
        end=product_ends(product),
        popcount=np.asarray(rules.popcounts(product.num_sets), dtype=np.int64),
        starts=np.array([x for x, _ in pairs], dtype=np.int64),
        start_cumulative=np.cumsum([p for _, p in pairs]),
    )


def draw(
    cumulative: FloatArray, indptr: IntArray, targets: IntArray, rows: IntArray, uniform: FloatArray
) -> IntArray:
    """For each ``rows[i]``, the target that ``uniform[i]`` in [0, 1) selects."""
    drawn: IntArray = targets[draw_index(cumulative, indptr, rows, uniform)]
    return drawn


def draw_index(
    cumulative: FloatArray, indptr: IntArray, rows: IntArray, uniform: FloatArray
) -> IntArray:
    """For each ``rows[i]``, the index of the entry that ``uniform[i]`` in [0, 1) selects."""
    index: IntArray = np.searchsorted(cumulative, rows + uniform, side="right")
    return np.clip(index, indptr[rows], indptr[rows + 1] - 1)


@dataclass(frozen=True, slots=True)
class Step:
    """What one step of the batch did. ``next_*`` describe the state each episode reached
    *before* ended episodes were restarted (what a learner bootstraps from)."""

    reward: FloatArray
    """The world file's reward terms."""
    accepting: BoolArray
    """The step added a set to the frontier (for the accepting-step discount)."""
    terminated: BoolArray
    truncated: BoolArray
    next_state: IntArray
    next_mask: IntArray
    next_observation: IntArray
    success: BoolArray
    """For ended episodes: whether they succeeded."""
    episode_return: FloatArray
    """The return so far of each episode, this step included (complete for ended ones)."""
    episode_steps: IntArray
    """World actions taken so far in each episode, this step included."""
    next_automaton: IntArray
    """The automaton state reached (0 at the product's absorbing states)."""
    next_valid: BoolArray
    """The actions valid in the state reached."""
    next_potential: FloatArray | None = None
    """The task's potential of the position reached (``info["potential"]`` of wrapped envs
    that report it; 0 where an episode ended decided)."""
    letter: IntArray | None = None
    """The letter the task read on the step (``info["letter"]`` of wrapped envs: that of the
    position left; -1 for an epsilon jump), for counterfactual experience
    (:mod:`mitlc.learn.learners.crm_env`)."""
    env_reward: FloatArray | None = None
    """The env's own reward of the step (``info["env_reward"]`` of wrapped envs)."""
    env_ended: BoolArray | None = None
    """Whether the env had ended by the end of the step (``info["env_ended"]``)."""
    distances: FloatArray | None = None
    """How far the position reached is from each proposition (``info["distances"]`` of wrapped
    envs made with a potential; rows are episodes)."""
    distances_left: FloatArray | None = None
    """The same of the position the step left (``info["distances_left"]``)."""
    blocked: BoolArray | None = None
    """With a shield: whether the step's action was one the shield blocks (only ever under
    an audit: an enforced shield refuses them)."""
    strayed: BoolArray | None = None
    """With a shield: whether the episode has taken a blocked action so far, this step
    included."""
    episode_cost: FloatArray | None = None
    episode_rounds: IntArray | None = None
    """The rounds of the acceptance sets each episode has completed so far, this step
    included (complete for ended ones; docs/episodes.md)."""
    """With costs: what each episode has cost so far, this step included (complete for
    ended ones); the reward already has it taken off."""

    @property
    def done(self) -> BoolArray:
        """Episodes that ended on this step."""
        ended: BoolArray = self.terminated | self.truncated
        return ended


class VecProduct:
    """``num_envs`` product episodes stepped together; ended episodes restart at once.

    The state of episode ``i`` is ``state[i]`` (a product state), ``mask[i]`` (the frontier of
    acceptance sets seen in this round), ``steps[i]`` (world actions taken), ``observation[i]``
    (what the agent sees: the cell for an MDP, an observation id for a POMDP) and
    ``returns[i]`` / ``rounds[i]``. All randomness comes from ``rng``.
    """

    def __init__(self, tables: Tables, num_envs: int, rng: np.random.Generator) -> None:
        self.tables, self.num_envs, self.rng = tables, num_envs, rng
        self.state = self._starts(num_envs)
        self.mask = np.zeros(num_envs, dtype=np.int64)
        self.steps = np.zeros(num_envs, dtype=np.int64)
        self.actions_taken = np.zeros(num_envs, dtype=np.int64)
        self.rounds = np.zeros(num_envs, dtype=np.int64)
        self.returns = np.zeros(num_envs)
        self.strayed = np.zeros(num_envs, dtype=np.bool_)
        self.costs = np.zeros(num_envs)
        self._shield_now: BoolArray | None = None
        self.observation = self._observe(self.state)

    # -- checkpoints ---------------------------------------------------------------------------

    def state_dict(self) -> dict[str, Any]:
        """Everything needed to continue exactly (the rng's state included)."""
        return {
            "state": self.state.copy(),
            "mask": self.mask.copy(),
            "steps": self.steps.copy(),
            "actions_taken": self.actions_taken.copy(),
            "rounds": self.rounds.copy(),
            "returns": self.returns.copy(),
            "observation": self.observation.copy(),
            "strayed": self.strayed.copy(),
            "costs": self.costs.copy(),
            "rng": self.rng.bit_generator.state,
        }

    def load_state_dict(self, saved: dict[str, Any]) -> None:
        """Restore :meth:`state_dict` (``ValueError`` for states outside this product)."""
        t = self.tables
        state = np.asarray(saved["state"])
        if len(state) and (state.min() < 0 or state.max() >= t.num_states):
            raise ValueError(f"state: values outside 0..{t.num_states - 1}")
        if (t.world_state[state] < 0).any():
            raise ValueError("state: an absorbing product state (episodes restart at once)")
        bounds = {"mask": t.all_sets + 1, "observation": t.num_observations}
        for name, top in bounds.items():
            values = np.asarray(saved[name])
            if len(values) and (values.min() < 0 or values.max() >= top):
                raise ValueError(f"{name}: values outside 0..{top - 1}")
        for name in ("steps", "actions_taken", "rounds"):
            if (np.asarray(saved[name]) < 0).any():
                raise ValueError(f"{name}: negative counts")
        for name in ("state", "mask", "steps", "actions_taken", "rounds", "returns", "observation"):
            setattr(self, name, np.array(saved[name]))
        self._shield_now = None
        costs = saved.get("costs")  # runs saved before costs: none paid
        self.costs = np.zeros(len(state)) if costs is None else np.array(costs, dtype=np.float64)
        strayed = saved.get("strayed")  # runs saved before shields: none strayed
        self.strayed = (
            np.zeros(len(state), dtype=np.bool_)
            if strayed is None
            else np.array(strayed, dtype=np.bool_)
        )
        self.rng.bit_generator.state = saved["rng"]

    # -- stepping ------------------------------------------------------------------------------

    @property
    def automaton(self) -> IntArray:
        """The automaton state of each episode (0 at the absorbing product states)."""
        automaton: IntArray = np.maximum(self.tables.automaton_state[self.state], 0)
        return automaton

    def valid_actions(self) -> BoolArray:
        """``valid[i, a]``: action ``a`` is available to episode ``i`` (and, under an enforced
        shield, allowed by it)."""
        t = self.tables
        valid: BoolArray = t.valid[self.state]
        if t.shield is None or not t.shield_enforced:
            return valid
        return valid & self._shielded()

    def _shielded(self) -> BoolArray:
        """``allowed[i, a]``: the shield allows action ``a`` to episode ``i`` now, with its
        steps left and its frontier (the mask of all sets once a round completed, as the
        shield's values have it), and in a POMDP its observation and automaton state."""
        if self._shield_now is not None:  # asked again before the episodes moved
            return self._shield_now
        t = self.tables
        assert t.shield is not None
        remaining = t.horizon - self.steps
        mask = rules.seen_sets(self.mask, self.rounds, t.all_sets)
        if isinstance(t.shield, ObservedShield):
            seen = t.shield.actions(remaining, mask, self.observation, self.automaton)
            allowed = np.ones((self.num_envs, t.num_actions), dtype=np.bool_)
            allowed[:, : seen.shape[1]] = seen
        else:
            allowed = t.shield.allowed(remaining[:, None], mask[:, None], t.choice[self.state])
        self._shield_now = allowed
        return allowed

    def step(self, actions: IntArray) -> Step:
        """Take ``actions[i]`` in episode ``i`` (each must be valid); restart ended episodes."""
        t = self.tables
        inside = (actions >= 0) & (actions < t.num_actions)
        choice = np.where(inside, t.choice[self.state, np.where(inside, actions, 0)], -1)
        if (choice < 0).any():
            bad = int(np.flatnonzero(choice < 0)[0])
            raise ValueError(f"action {int(actions[bad])} is not valid in episode {bad}")
        blocked = None
        if t.shield is not None:
            rows = np.arange(self.num_envs)
            blocked = ~self._shielded()[rows, np.where(inside, actions, 0)] & inside
        if blocked is not None and t.shield_enforced and blocked.any():
            bad = int(np.flatnonzero(blocked)[0])
            raise ValueError(
                f"action {int(actions[bad])} is blocked by the shield in episode {bad}"
            )
        if blocked is not None:
            self.strayed |= blocked
        uniform = self.rng.random(self.num_envs)
        index = draw_index(t.cumulative, t.indptr, choice, uniform)
        nxt = t.targets[index]
        jump = actions >= t.num_world_actions
        mask, new_count, complete = rules.account(
            self.mask, t.marks[choice], t.all_sets, t.popcount
        )
        self.rounds += complete
        verdict = t.verdict[nxt]
        reward = rules.reward(new_count, verdict, t.rewards) + t.reward_move * t.moves[choice]
        self.steps += ~jump
        self.actions_taken += 1
        terminated = rules.terminated(verdict)
        # jumps take no time; a bound on all actions stops a policy that only jumps
        truncated = ~terminated & (
            (self.steps >= t.horizon) | (self.actions_taken >= 4 * t.horizon + 4)
        )
        observation = np.where(jump, self.observation, self._observe(nxt))
        seen = rules.seen_sets(mask, self.rounds, t.all_sets)
        success = rules.success(verdict, seen, t.end[nxt])
        if t.cost is not None:
            paid = t.cost[index]
            reward = reward - paid
            self.costs += paid
        self.returns += reward
        result = Step(
            reward=reward,
            accepting=new_count > 0,
            terminated=terminated,
            truncated=truncated,
            next_state=nxt,
            next_mask=mask,
            next_observation=observation,
            success=success,
            episode_return=self.returns.copy(),
            episode_steps=self.steps.copy(),
            next_automaton=np.maximum(t.automaton_state[nxt], 0),
            next_valid=t.valid[nxt],
            blocked=blocked,
            strayed=None if blocked is None else self.strayed.copy(),
            episode_cost=None if t.cost is None else self.costs.copy(),
            episode_rounds=self.rounds.copy(),
        )
        self.state, self.mask, self.observation = nxt, mask, observation
        self._shield_now = None
        self._restart(result.done)
        return result

    def _restart(self, done: BoolArray) -> None:
        if not done.any():
            return
        self.state = np.where(done, self._starts(self.num_envs), self.state)
        self.mask = np.where(done, 0, self.mask)
        for counter in (self.steps, self.actions_taken, self.rounds):
            counter[done] = 0
        self.returns[done] = 0.0
        self.costs[done] = 0.0
        self.strayed[done] = False
        self.observation = np.where(done, self._observe(self.state), self.observation)

    def _starts(self, n: int) -> IntArray:
        """``n`` start states: the initial one, or drawn from the start distribution (only
        then is the random generator read)."""
        t = self.tables
        if len(t.starts) == 1:
            return np.full(n, t.initial, dtype=np.int64)
        drawn: IntArray = t.starts[
            np.minimum(
                np.searchsorted(
                    t.start_cumulative, self.rng.random(n) * t.start_cumulative[-1], side="right"
                ),
                len(t.starts) - 1,
            )
        ]
        return drawn

    def _observe(self, states: IntArray) -> IntArray:
        """What the agent sees in product states ``states`` (absorbing ones: 0)."""
        t = self.tables
        cells = np.maximum(t.world_state[states], 0)
        if t.observation is None or t.observation_cumulative is None:
            return cells
        uniform = self.rng.random(len(states))
        seen: IntArray = draw(
            t.observation_cumulative, t.observation.indptr, t.observation.targets, cells, uniform
        )
        return seen
