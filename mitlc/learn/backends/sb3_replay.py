"""The replay memory of SB3's off-policy algorithms (``sb3-dqn``, ``sb3-sac``, ``sb3-td3``) as
checkpointed state: :class:`ReplayState`, a part of :class:`mitlc.learn.backends.sb3.ModelState`.

A checkpoint holds the memory's filled rows (all of them once it has wrapped around), its write
position and whether it is full, as arrays in the checkpoint's ``.npz`` (no pickle): SB3's
``observations``, ``next_observations`` (none with ``optimize_memory_usage``), ``actions``,
``rewards``, ``dones`` and ``timeouts``, each key of a dict observation as
``observations:KEY``; and for counterfactual experience
(:class:`mitlc.learn.backends.sb3_crm.CounterfactualReplay`) which rows are counterfactual, how
many were made and the state of the generator that samples them. So a resumed run samples from
the memory the stopped one had and goes on learning from its first step, as an uninterrupted
run would. Not held: the counterfactuals still waiting for a whole row of ``n_envs`` (fewer
than ``n_envs`` transitions), and each env's task state (the envs start new episodes on resume).

A memory whose rows take more than :data:`REPLAY_BYTES` is not saved (the checkpoint says so):
the resumed run then refills it, taking random actions for ``sb3.learning_starts`` steps before
it learns again, as a checkpoint written before mitlc saved replay memories does.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from mitlc.inputs import MAX_CHECKPOINT_BYTES, size_text

REPLAY_BYTES = MAX_CHECKPOINT_BYTES // 2
"""The most bytes of replay rows a checkpoint holds (half of what mitlc reads of one)."""

FIELDS = ("observations", "next_observations", "actions", "rewards", "dones", "timeouts",
          "counterfactual")  # fmt: skip
"""The memory's arrays, by their attribute (those it has): SB3's, and which rows are
counterfactual."""

Arrays = dict[str, npt.NDArray[Any]]


def _buffers(memory: Any) -> Arrays:
    """Every array of :data:`FIELDS` that ``memory`` has, whole (a dict observation's keys as
    ``observations:KEY``)."""
    found: Arrays = {}
    for name in FIELDS:
        value = getattr(memory, name, None)
        if isinstance(value, dict):
            found.update({f"{name}:{key}": array for key, array in value.items()})
        elif isinstance(value, np.ndarray):
            found[name] = value
    return found


class ReplayState:
    """An SB3 replay memory as :class:`~mitlc.learn.rundir.state.Stateful` data (see the
    module docstring); ``restored`` says whether :meth:`load_state_dict` put rows back."""

    def __init__(self, memory: Any) -> None:
        self.memory = memory
        self.restored = False
        self.missing = "the checkpoint holds no replay memory (an older mitlc's)"
        """Why :meth:`load_state_dict` put no rows back, where it did not."""

    def rows(self) -> int:
        """The filled rows."""
        return int(self.memory.buffer_size if self.memory.full else self.memory.pos)

    def state_dict(self) -> dict[str, Any]:
        memory, rows = self.memory, self.rows()
        arrays = {name: array[:rows] for name, array in _buffers(memory).items()}
        kept = sum(array.nbytes for array in arrays.values()) <= REPLAY_BYTES
        state: dict[str, Any] = {
            "kept": kept,
            "pos": int(memory.pos),
            "full": bool(memory.full),
            "arrays": arrays if kept else {},
        }
        if hasattr(memory, "made"):  # counterfactual experience
            state["made"] = int(memory.made)
            state["rng"] = memory.rng.bit_generator.state
        return state

    def load_state_dict(self, saved: dict[str, Any]) -> None:
        """Put the saved rows back (a ``ValueError`` where they do not fit this memory)."""
        memory = self.memory
        if hasattr(memory, "made"):
            memory.made = int(saved["made"])
            memory.rng.bit_generator.state = saved["rng"]
        if not saved["kept"]:
            self.missing = (f"the replay memory was not saved (its rows take more than "
                            f"{size_text(REPLAY_BYTES)})")  # fmt: skip
            return
        pos, full, arrays = int(saved["pos"]), bool(saved["full"]), saved["arrays"]
        size = int(memory.buffer_size)
        if not 0 <= pos < size:
            raise ValueError(f"replay: position {pos} outside a memory of {size} rows")
        rows = size if full else pos
        buffers = _buffers(memory)
        if set(arrays) != set(buffers):
            raise ValueError(f"replay: arrays {sorted(arrays)}, expected {sorted(buffers)}")
        for name, buffer in buffers.items():
            array = arrays[name]
            if array.dtype != buffer.dtype or array.shape != (rows, *buffer.shape[1:]):
                raise ValueError(
                    f"replay: {name} is {array.dtype} {array.shape}, expected {buffer.dtype} "
                    f"{(rows, *buffer.shape[1:])}"
                )
        for name, buffer in buffers.items():
            buffer[:rows] = arrays[name]
        memory.pos, memory.full = pos, full
        self.restored = True
