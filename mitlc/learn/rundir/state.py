"""Restoring a run's objects from its latest checkpoint: ``restore(directory, parts)``.

Before anything is restored, :func:`conform` compares the loaded state with the state of the
fresh objects it will go into: the same dict keys, list lengths and scalar types, arrays and
tensors of the same dtype and shape. Then each object's ``load_state_dict`` checks what only it
knows (indices within its tables, a replay memory's size within its capacity). Whatever is
wrong is a :class:`~mitlc.learn.rundir.files.RunError` naming the checkpoint's file, on one line.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Protocol

import numpy as np

from mitlc.learn.rundir import checkpoint
from mitlc.learn.rundir.checkpoint import tensor_type
from mitlc.learn.rundir.files import RunError


class Stateful(Protocol):
    """An object saved in checkpoints (learners, the simulator, the run's tally)."""

    def state_dict(self) -> dict[str, Any]: ...
    def load_state_dict(self, saved: dict[str, Any]) -> None: ...


def one_line(err: BaseException) -> str:
    """An exception's message on one line, at most 300 characters."""
    return " ".join(str(err).split())[:300]


def restore(
    directory: Path,
    parts: dict[str, Stateful],
    *,
    rows: tuple[str, ...] = (),
    unchecked: tuple[str, ...] = (),
    optional: tuple[str, ...] = (),
) -> checkpoint.Loaded:
    """Load the latest checkpoint of ``directory`` into the fresh objects ``parts`` (by their
    key in the saved state); ``rows``, ``unchecked`` and ``optional`` as for :func:`conform`."""
    loaded = checkpoint.load(directory)
    template = {name: part.state_dict() for name, part in parts.items()}
    try:
        conform(loaded.state, template, rows=rows, unchecked=unchecked, optional=optional)
    except Mismatch as err:
        raise RunError(f"{loaded.files.get(err.kind, loaded.files['json'])}: {err}") from None
    for name, part in parts.items():
        try:
            part.load_state_dict(loaded.state[name])
        except (
            ValueError,
            TypeError,
            KeyError,
            IndexError,
            AttributeError,
            OverflowError,
            RuntimeError,
        ) as err:
            raise RunError(f"{loaded.files['json']}: {name}: {one_line(err)}") from None
    return loaded


FREE_FORM = ("env_info",)
"""Names of entries whose structure is their writer's (see :func:`conform`)."""


class Mismatch(ValueError):
    """A loaded state unlike the fresh one; ``kind`` is the file the entry comes from."""

    def __init__(self, where: str, message: str, kind: str = "json") -> None:
        super().__init__(f"{where or 'the state'}: {message}")
        self.kind = kind


def conform(
    saved: Any,
    template: Any,
    where: str = "",
    *,
    rows: tuple[str, ...] = (),
    unchecked: tuple[str, ...] = (),
    optional: tuple[str, ...] = (),
) -> None:
    """Raise :class:`Mismatch` unless ``saved`` has ``template``'s structure: the same dict
    keys, list lengths and scalar types, arrays and tensors of the same dtype and shape (arrays
    under a path in ``rows`` may have another number of rows). Paths in ``unchecked`` are left
    to the object that restores them, and so is every entry named :data:`FREE_FORM` (a task
    wrapper's copy of its env's last ``info``, whose keys are the env's). Paths in
    ``optional`` may be missing (a checkpoint of an older mitlc); where present they are
    checked."""
    if where in unchecked or where.rpartition(".")[2] in FREE_FORM:
        return
    tensor = tensor_type()
    if isinstance(template, np.ndarray):
        _same_array(saved, template, where, where in rows or where.rpartition(".")[0] in rows)
    elif tensor is not None and isinstance(template, tensor):
        if not isinstance(saved, tensor):
            raise Mismatch(where, f"expected a tensor, found {_kind(saved)}")
        if saved.dtype != template.dtype or saved.shape != template.shape:
            wanted = f"{template.dtype} {tuple(template.shape)}"
            found = f"{saved.dtype} {tuple(saved.shape)}"
            raise Mismatch(where, f"expected {wanted}, found {found}", "safetensors")
    elif isinstance(template, dict):
        if not isinstance(saved, dict):
            raise Mismatch(where, f"expected a mapping, found {_kind(saved)}")
        missing, extra = template.keys() - saved.keys(), saved.keys() - template.keys()
        missing = {k for k in missing if (f"{where}.{k}" if where else str(k)) not in optional}
        if missing or extra:
            raise Mismatch(
                where, f"missing {sorted(map(str, missing))}, unexpected {sorted(map(str, extra))}"
            )
        for key, value in template.items():
            if key in saved:
                path = f"{where}.{key}" if where else str(key)
                conform(saved[key], value, path, rows=rows, unchecked=unchecked, optional=optional)
    elif isinstance(template, list | tuple):
        if type(saved) is not type(template) or len(saved) != len(template):
            size = f" of {len(saved)}" if isinstance(saved, list | tuple) else ""
            wanted = f"{type(template).__name__} of {len(template)}"
            raise Mismatch(where, f"expected a {wanted}, found {_kind(saved)}{size}")
        for i, (a, b) in enumerate(zip(saved, template, strict=True)):
            conform(a, b, f"{where}[{i}]", rows=rows, unchecked=unchecked, optional=optional)
    elif type(saved) is not type(template) and _scalar_kind(saved) != _scalar_kind(template):
        raise Mismatch(where, f"expected {_kind(template)}, found {_kind(saved)}")


def _scalar_kind(value: Any) -> str | None:
    """A scalar's kind, numpy's and Python's alike (JSON keeps no numpy scalar type: a saved
    ``numpy.int64`` comes back an ``int``): ``"bool"``, ``"int"``, ``"float"`` or ``None``."""
    if isinstance(value, bool | np.bool_):
        return "bool"
    if isinstance(value, int | np.integer):
        return "int"
    if isinstance(value, float | np.floating):
        return "float"
    return None


def _same_array(saved: Any, template: np.ndarray[Any, Any], where: str, any_rows: bool) -> None:
    if not isinstance(saved, np.ndarray):
        raise Mismatch(where, f"expected an array, found {_kind(saved)}")
    same_shape = saved.shape[1:] == template.shape[1:] and saved.ndim == template.ndim
    if (
        saved.dtype != template.dtype
        or not same_shape
        or (not any_rows and saved.shape != template.shape)
    ):
        shape = ("N", *template.shape[1:]) if any_rows else template.shape
        raise Mismatch(
            where, f"expected {template.dtype} {shape}, found {saved.dtype} {saved.shape}", "npz"
        )


def _kind(value: Any) -> str:
    return type(value).__name__
