"""Torch pieces the deep learners share: what the agent sees as a feature vector, the networks,
seeding, a numpy replay ring and the (Double) DQN target.

The agent sees the world's observation (the cell of an MDP), the automaton state and the
frontier mask; :class:`Encoder` turns them (and optionally the previous action) into one-hot
blocks concatenated. The learners keep every random draw after construction in their numpy
generator (saved in their checkpoints), so torch's own generator only initialises the weights,
from a seed drawn from that generator, without touching torch's global random state.
"""

from __future__ import annotations

import copy
from typing import Any, Protocol

import numpy as np
import torch
from torch import nn

from mitlc.learn.envs.vec import Tables
from mitlc.worlds.model import BoolArray, IntArray

THREADS = 1
"""Torch threads for the deep learners: the networks are small, and one thread is several
times faster than two on a 2-core machine (threads contend with the numpy simulator)."""


def configure_torch() -> None:
    """Fix torch's threads (process-wide) so that runs are fast and repeatable."""
    if torch.get_num_threads() != THREADS:
        torch.set_num_threads(THREADS)


def torch_seed(rng: np.random.Generator) -> int:
    """A seed for torch drawn from ``rng``."""
    return int(rng.integers(0, 2**62))


def build(seed: int, factory: Any) -> Any:
    """``factory()`` with torch's random state seeded by ``seed`` and restored afterwards."""
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seed)
        return factory()


def mlp(inputs: int, hidden: int, layers: int, outputs: int) -> nn.Sequential:
    """``layers`` hidden ReLU layers of width ``hidden``, then a linear output layer."""
    modules: list[nn.Module] = []
    width = inputs
    for _ in range(layers):
        modules += [nn.Linear(width, hidden), nn.ReLU()]
        width = hidden
    modules.append(nn.Linear(width, outputs))
    return nn.Sequential(*modules)


def optimistic(layer: nn.Module, value: float) -> None:
    """Start an output ``layer`` (``nn.Linear``) at ``value`` for every input: bias ``value``,
    weights a hundredth of their initial size."""
    assert isinstance(layer, nn.Linear)
    with torch.no_grad():
        layer.weight.mul_(0.01)
        layer.bias.fill_(value)


NEGATIVE = -1e9
"""The value of an invalid action in a maximum (finite, so that 0 times it stays 0)."""


def masked(values: torch.Tensor, valid: torch.Tensor) -> torch.Tensor:
    """``values`` with invalid actions at :data:`NEGATIVE`."""
    return values.masked_fill(~valid, NEGATIVE)


def greedy(values: torch.Tensor, valid: BoolArray) -> IntArray:
    """The best valid action of each row of ``values`` (on any device)."""
    mask = torch.from_numpy(valid).to(values.device)
    best: IntArray = masked(values, mask).argmax(dim=-1).cpu().numpy()
    return best.astype(np.int64)


def bootstrap(
    online_next: torch.Tensor,
    target_next: torch.Tensor,
    next_valid: torch.Tensor,
    terminated: torch.Tensor,
    double: bool,
) -> torch.Tensor:
    """The value of the next state: ``max_a Q_target(next, a)`` over valid actions (Mnih et al.,
    Nature 2015), or with ``double`` ``Q_target(next, argmax_a Q_online(next, a))`` (van Hasselt,
    Guez and Silver, AAAI 2016); 0 after a terminal step."""
    if double:
        best = masked(online_next, next_valid).argmax(dim=-1, keepdim=True)
        value = target_next.gather(-1, best).squeeze(-1)
    else:
        value = masked(target_next, next_valid).max(dim=-1).values
    return torch.where(terminated, torch.zeros_like(value), value)


def huber(error: torch.Tensor, weight: torch.Tensor) -> torch.Tensor:
    """The Huber loss of ``error`` (delta 1), averaged with ``weight`` (0 drops an entry)."""
    loss = torch.nn.functional.huber_loss(error, torch.zeros_like(error), reduction="none")
    return (loss * weight).sum() / weight.sum().clamp(min=1.0)


def gradient_step(
    loss: torch.Tensor, optimizer: torch.optim.Optimizer, params: list[nn.Parameter], clip: float
) -> None:
    """One optimiser step on ``loss`` with the gradient norm clipped to ``clip``."""
    optimizer.zero_grad(set_to_none=True)
    loss.backward()  # type: ignore[no-untyped-call]
    nn.utils.clip_grad_norm_(params, clip)
    optimizer.step()


def anneal(optimizer: torch.optim.Optimizer, lr: float, end_ratio: float, fraction: float) -> None:
    """Set the learning rate to ``lr`` falling linearly to ``lr * end_ratio`` over the run."""
    rate = lr * (1.0 + (end_ratio - 1.0) * min(1.0, max(0.0, fraction)))
    for group in optimizer.param_groups:
        group["lr"] = rate


class Ring:
    """A replay memory: fixed-capacity numpy arrays written in a ring, sampled uniformly."""

    def __init__(self, capacity: int, fields: dict[str, tuple[tuple[int, ...], Any]]) -> None:
        """``fields`` maps a name to the shape of one entry and its dtype."""
        self.capacity, self.position, self.size = capacity, 0, 0
        self.data = {
            name: np.zeros((capacity, *shape), dtype=dtype)
            for name, (shape, dtype) in fields.items()
        }

    def add(self, entries: dict[str, np.ndarray[Any, Any]]) -> None:
        """Append a batch of entries (the oldest are overwritten when full)."""
        count = len(next(iter(entries.values())))
        where = (self.position + np.arange(count)) % self.capacity
        for name, values in entries.items():
            self.data[name][where] = values
        self.position = int((self.position + count) % self.capacity)
        self.size = min(self.capacity, self.size + count)

    def sample(self, rng: np.random.Generator, count: int) -> dict[str, np.ndarray[Any, Any]]:
        """``count`` entries drawn uniformly with replacement."""
        index = rng.integers(0, self.size, size=count)
        return {name: values[index] for name, values in self.data.items()}

    def state_dict(self) -> dict[str, Any]:
        """The stored entries and the write position."""
        return {
            "position": self.position,
            "size": self.size,
            "data": {name: values[: self.size].copy() for name, values in self.data.items()},
        }

    def load_state_dict(self, saved: dict[str, Any]) -> None:
        """Restore :meth:`state_dict` (``ValueError`` if it does not fit this memory)."""
        position, size, data = int(saved["position"]), int(saved["size"]), saved["data"]
        if not 0 <= size <= self.capacity:
            raise ValueError(f"replay size {size} outside 0..{self.capacity}")
        if not 0 <= position < self.capacity or (size < self.capacity and position != size):
            raise ValueError(f"replay position {position} does not fit its size {size}")
        if data.keys() != self.data.keys():
            raise ValueError(f"replay fields {sorted(data)}, expected {sorted(self.data)}")
        for name, values in data.items():
            mine = self.data[name]
            if values.shape != (size, *mine.shape[1:]) or values.dtype != mine.dtype:
                raise ValueError(
                    f"replay field {name}: {values.dtype} {values.shape}, expected "
                    f"{mine.dtype} {(size, *mine.shape[1:])}"
                )
        self.position, self.size = position, size
        for name, values in data.items():
            self.data[name][:size] = values


CPU = torch.device("cpu")


def tensors(
    batch: dict[str, np.ndarray[Any, Any]], *names: str, device: torch.device = CPU
) -> list[torch.Tensor]:
    """The named arrays of ``batch`` as tensors on ``device``."""
    return [torch.from_numpy(np.ascontiguousarray(batch[name])).to(device) for name in names]


class DeepLearner(Protocol):
    """What :func:`deep_state` saves of a deep learner (the objects are restored in place)."""

    vector_steps: int
    gradient_steps: int
    _epsilon: float

    @property
    def net(self) -> nn.Module: ...
    @property
    def target(self) -> nn.Module: ...
    @property
    def optimizer(self) -> torch.optim.Optimizer: ...
    @property
    def replay(self) -> Ring: ...
    @property
    def rng(self) -> np.random.Generator: ...


def deep_state(learner: DeepLearner) -> dict[str, Any]:
    """A deep learner's networks, optimiser, replay memory, counters and random states."""
    return {
        "net": copy.deepcopy(learner.net.state_dict()),
        "target": copy.deepcopy(learner.target.state_dict()),
        "optimizer": copy.deepcopy(learner.optimizer.state_dict()),
        "replay": learner.replay.state_dict(),
        "vector_steps": learner.vector_steps,
        "gradient_steps": learner.gradient_steps,
        "epsilon": learner._epsilon,
        "rng": copy.deepcopy(learner.rng.bit_generator.state),
        "torch_rng": torch.get_rng_state(),
    }


def check_indices(data: dict[str, Any], tables: Tables, where: str) -> None:
    """``ValueError`` unless the index fields of ``data`` (arrays named as in the replay
    memories: observations, automaton states, masks, actions, previous actions) lie in the
    ranges of ``tables``, so that a restored memory cannot index outside the encoder."""
    top = {
        "observation": tables.num_observations,
        "automaton": tables.num_automaton_states,
        "mask": tables.all_sets + 1,
        "action": tables.num_actions,
        "previous": tables.num_actions,
    }
    for name, values in data.items():
        high = top.get(name.removeprefix("next_"))
        if high is None or not np.size(values):
            continue
        low = -1 if name == "previous" else 0
        if int(np.min(values)) < low or int(np.max(values)) >= high:
            raise ValueError(f"{where}{name}: values outside {low}..{high - 1}")


def _check_optimizer(saved: dict[str, Any], optimizer: torch.optim.Optimizer) -> None:
    """``ValueError`` unless ``saved`` is an Adam state for ``optimizer``'s parameters (torch
    does not check the shapes of the moments, and a wrong one fails only at the next step)."""
    mine = optimizer.state_dict()["param_groups"]
    groups = saved["param_groups"]
    if [g["params"] for g in groups] != [g["params"] for g in mine]:
        raise ValueError("optimizer: parameter groups unlike this network's")
    params = [p for group in optimizer.param_groups for p in group["params"]]
    if not isinstance(saved["state"], dict):
        raise ValueError("optimizer.state: expected a mapping")
    for key, entry in saved["state"].items():
        if not isinstance(key, int) or isinstance(key, bool) or not 0 <= key < len(params):
            raise ValueError(f"optimizer.state: no parameter {key!r}")
        if not isinstance(entry, dict) or set(entry) != {"step", "exp_avg", "exp_avg_sq"}:
            raise ValueError(f"optimizer.state[{key}]: expected step, exp_avg, exp_avg_sq")
        shape = params[key].shape
        for name, expected in (("step", ()), ("exp_avg", shape), ("exp_avg_sq", shape)):
            value = entry[name]
            if not isinstance(value, torch.Tensor) or value.shape != expected:
                raise ValueError(
                    f"optimizer.state[{key}].{name}: expected a tensor of shape {tuple(expected)}"
                )
            if value.dtype != torch.float32:
                raise ValueError(f"optimizer.state[{key}].{name}: expected float32")


def load_deep_state(learner: DeepLearner, saved: dict[str, Any]) -> None:
    """Restore :func:`deep_state` into ``learner`` (``ValueError`` or ``RuntimeError`` if it
    does not fit)."""
    _check_optimizer(saved["optimizer"], learner.optimizer)
    learner.net.load_state_dict(saved["net"])
    learner.target.load_state_dict(saved["target"])
    learner.optimizer.load_state_dict(copy.deepcopy(saved["optimizer"]))
    learner.replay.load_state_dict(saved["replay"])
    learner.vector_steps = int(saved["vector_steps"])
    learner.gradient_steps = int(saved["gradient_steps"])
    learner._epsilon = float(saved["epsilon"])
    learner.rng.bit_generator.state = saved["rng"]
    torch.set_rng_state(saved["torch_rng"])
