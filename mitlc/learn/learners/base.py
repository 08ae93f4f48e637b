"""What every learner shares: the interfaces, the learning signal (discount and shaping) and
action choice under a validity mask."""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any, Protocol

import numpy as np

from mitlc.automata.digital import DigitalAutomaton
from mitlc.learn.config import Discount, TrainConfig
from mitlc.learn.envs.vec import Step, Tables
from mitlc.worlds.model import BoolArray, FloatArray, IntArray


class Episodes(Protocol):
    """A batch of episodes as the learners read it: :class:`mitlc.learn.envs.envvec.VectorTask`
    over any vector env of wrapped envs (mitlc's simulator of a finite product included).
    ``state`` is the product state (-1 without a finite product)."""

    num_envs: int

    @property
    def observation(self) -> Any: ...

    @property
    def automaton(self) -> IntArray: ...

    @property
    def mask(self) -> IntArray: ...

    @property
    def state(self) -> IntArray: ...

    def valid_actions(self) -> BoolArray: ...

    def step(self, actions: IntArray) -> Step: ...


class Policy(ABC):
    """A greedy policy acting in a batch of :class:`Episodes`; it may remember each episode's
    past."""

    def reset(self, num_envs: int) -> None:  # noqa: B027 - stateless policies need nothing
        """Forget everything: ``num_envs`` fresh episodes begin."""

    @abstractmethod
    def act(self, env: Episodes) -> IntArray:
        """The action of each episode of ``env`` (valid ones only)."""

    def observe(self, step: Step) -> None:  # noqa: B027 - stateless policies need nothing
        """Take note of ``step`` (restart the memory of the episodes it ended)."""


class Learner(ABC):
    """A learning algorithm: it steps a batch of episodes and learns from what it sees."""

    num_envs: int

    @abstractmethod
    def train_step(self, env: Episodes, fraction: float) -> Step:
        """Choose actions (exploring), step ``env`` once and learn; ``fraction`` is the share
        of the run's episodes done so far (for schedules)."""

    @property
    @abstractmethod
    def epsilon(self) -> float:
        """The exploration rate of the last step."""

    @abstractmethod
    def state_dict(self) -> dict[str, Any]:
        """Everything needed to continue exactly (random states included)."""

    @abstractmethod
    def load_state_dict(self, saved: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`."""

    @abstractmethod
    def policy(self) -> Policy:
        """The greedy policy learned so far."""


def epsilon_at(fraction: float, start: float, end: float, decay: float) -> float:
    """Linear decay from ``start`` to ``end`` over the first ``decay`` share of the run."""
    if decay <= 0.0:
        return end
    return end + (start - end) * max(0.0, 1.0 - fraction / decay)


def step_discounts(accepting: BoolArray, discount: Discount) -> FloatArray:
    """Each transition's discount: ``gamma``, or ``gamma_accept`` on accepting steps."""
    if discount.mode == "accepting":
        return np.where(accepting, discount.gamma_accept, discount.gamma)
    return np.full(len(accepting), discount.gamma)


def automaton_distance(automaton: DigitalAutomaton) -> FloatArray:
    """Per automaton state, the fewest letters to a transition that marks an acceptance set or
    enters a satisfied state (0 when satisfied; violated and hopeless states get one more than
    the largest finite distance)."""
    num_q = len(automaton.states)
    inf = float(num_q + 1)
    distance = np.full(num_q, inf)
    for q, state in enumerate(automaton.states):
        if state.verdict == "satisfied":
            distance[q] = 0.0
    rows = automaton.rows
    sources = np.repeat(np.arange(num_q), [len(row.targets) for row in rows])
    targets = np.asarray([t for row in rows for t in row.targets], dtype=np.int64)
    direct = np.where([any(row.marks) for row in rows], 1.0, inf)
    for _ in range(num_q):
        nearest = np.full(num_q, np.inf)
        np.minimum.at(nearest, sources, distance[targets])
        updated = np.minimum(distance, np.minimum(direct, 1.0 + nearest))
        updated[distance == 0.0] = 0.0
        if np.array_equal(updated, distance):
            break
        distance = updated
    finite = distance[distance < inf]
    result: FloatArray = np.where(
        distance < inf, distance, (finite.max() if len(finite) else 0) + 1
    )
    return result


def automaton_potential(automaton: DigitalAutomaton, scale: float) -> FloatArray:
    """The shaping potential of each automaton state, ``-scale`` times its distance to
    acceptance, and one more entry, 0, for an episode's end (Ng, Harada and Russell, ICML
    1999: potential-based shaping keeps the optimal policies)."""
    phi: FloatArray = np.append(-scale * automaton_distance(automaton), 0.0)
    return phi


def potential(tables: Tables, automaton: DigitalAutomaton, scale: float) -> FloatArray:
    """The shaping potential of each product state: its automaton state's
    (:func:`automaton_potential`); 0 at the absorbing states (an episode's end)."""
    by_state = automaton_potential(automaton, scale)
    phi: FloatArray = by_state[np.maximum(tables.automaton_state, 0)]
    phi[tables.world_state < 0] = 0.0
    return phi


def learning_signal(
    step: Step, before: IntArray, config: TrainConfig, phi: FloatArray | None
) -> tuple[FloatArray, FloatArray]:
    """The reward a learner maximises and the discount of each transition of ``step``
    (:func:`transition_signal`): the shaping reads the automaton state of the observation,
    ``before`` the step and ``step.next_automaton`` after it (an ended episode's end where the
    task was decided); ``phi`` is :func:`automaton_potential`."""
    return transition_signal(
        step.reward, step.accepting, before, after_automaton(step, phi), config, phi
    )


def after_automaton(step: Step | None, phi: FloatArray | None, *,
                    automaton: IntArray | None = None,
                    terminated: BoolArray | None = None) -> IntArray:  # fmt: skip
    """The index into :func:`automaton_potential` of the state each transition reached: its
    automaton state, or the last entry (an episode's end) where the task was decided."""
    if step is not None:
        automaton, terminated = step.next_automaton, step.terminated
    assert automaton is not None and terminated is not None
    end = len(phi) - 1 if phi is not None else 0
    after: IntArray = np.where(terminated, end, automaton)
    return after


def transition_signal(
    reward: FloatArray,
    accepting: BoolArray,
    before: IntArray,
    after: IntArray,
    config: TrainConfig,
    phi: FloatArray | None,
) -> tuple[FloatArray, FloatArray]:
    """The reward a learner maximises and the discount of each transition ``before -> after``
    (product states): the world's reward, plus ``gamma * phi(after) - phi(before)`` with
    shaping on."""
    gammas = step_discounts(accepting, config.discount)
    if phi is not None:
        reward = reward + gammas * phi[after] - phi[before]
    return reward, gammas


def masked_argmax(values: FloatArray, valid: BoolArray) -> IntArray:
    """The best valid action of each row."""
    best: IntArray = np.where(valid, values, -np.inf).argmax(axis=1)
    return best


def random_valid(rng: np.random.Generator, valid: BoolArray) -> IntArray:
    """A uniformly random valid action of each row."""
    draws: IntArray = (rng.random(valid.shape) * valid).argmax(axis=1)
    return draws
