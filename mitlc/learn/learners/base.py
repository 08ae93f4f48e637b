"""What every learner shares: the interfaces, the learning signal (discount and shaping) and
action choice under a validity mask."""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from mitlc.automata.digital import DigitalAutomaton
from mitlc.learn.config import Discount, TrainConfig
from mitlc.learn.envs.vec import Step, Tables
from mitlc.task.potential import shaped, world_potential
from mitlc.worlds.model import BoolArray, FloatArray, IntArray, World


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


def product_potential(
    tables: Tables, world: World, automaton: DigitalAutomaton, scale: float, reach: float = 0.0
) -> FloatArray:
    """The shaping potential of each product state: ``scale`` times the task's potential of its
    world and automaton states (:func:`mitlc.task.potential.world_potential`); 0 at the
    absorbing states (an episode's end)."""
    table = world_potential(world, automaton, reach)
    live = tables.world_state >= 0
    phi: FloatArray = np.zeros(len(tables.world_state))
    phi[live] = scale * table[tables.automaton_state[live], tables.world_state[live]]
    return phi


class Shaping(Protocol):
    """Where a learner reads the (scaled) potential of the states its episodes are in and
    reach: :class:`ProductShaping` or :class:`EnvShaping`."""

    def before(self, env: Episodes) -> FloatArray: ...
    def after(self, step: Step) -> FloatArray: ...


@dataclass(frozen=True, slots=True)
class ProductShaping:
    """The potential of product states (:func:`product_potential`)."""

    phi: FloatArray

    def before(self, env: Episodes) -> FloatArray:
        """The potential of the episodes' product states now."""
        return self.phi[env.state]

    def after(self, step: Step) -> FloatArray:
        """The potential of the product states reached (0 where an episode ended decided)."""
        return self.phi[step.next_state]


@dataclass(frozen=True, slots=True)
class EnvShaping:
    """The potential the task wrapper reports (``info["potential"]``, 0 where an episode
    ended decided), times ``scale``."""

    scale: float

    def before(self, env: Episodes) -> FloatArray:
        """The potential of the episodes' positions now."""
        return self.scale * np.asarray(env.potential, dtype=np.float64)  # type: ignore[attr-defined]

    def after(self, step: Step) -> FloatArray:
        """The potential of the positions reached."""
        assert step.next_potential is not None, "the wrapped envs report their potential"
        return self.scale * np.asarray(step.next_potential, dtype=np.float64)


def learning_signal(
    step: Step, before: FloatArray | None, config: TrainConfig, shaping: Shaping | None
) -> tuple[FloatArray, FloatArray]:
    """The reward a learner maximises and the discount of each transition of ``step``: the
    world's reward, shaped (:func:`mitlc.task.potential.shaped`) from ``before``, the potential
    of the states left (``shaping.before`` of the episodes before the step), to that of the
    states reached."""
    gammas = step_discounts(step.accepting, config.discount)
    if shaping is None or before is None:
        return step.reward, gammas
    return shaped(step.reward, gammas, before, shaping.after(step)), gammas


def transition_signal(
    reward: FloatArray,
    accepting: BoolArray,
    before: IntArray,
    after: IntArray,
    config: TrainConfig,
    phi: FloatArray | None,
) -> tuple[FloatArray, FloatArray]:
    """The reward a learner maximises and the discount of each transition ``before -> after``
    (product states): the world's reward, shaped with the product states' potential ``phi``
    when there is one."""
    gammas = step_discounts(accepting, config.discount)
    if phi is not None:
        reward = shaped(reward, gammas, phi[before], phi[after])
    return reward, gammas


def masked_argmax(values: FloatArray, valid: BoolArray) -> IntArray:
    """The best valid action of each row."""
    best: IntArray = np.where(valid, values, -np.inf).argmax(axis=1)
    return best


def random_valid(rng: np.random.Generator, valid: BoolArray) -> IntArray:
    """A uniformly random valid action of each row."""
    draws: IntArray = (rng.random(valid.shape) * valid).argmax(axis=1)
    return draws
