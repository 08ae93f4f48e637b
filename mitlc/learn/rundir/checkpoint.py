"""Checkpoints that hold data only: ``save(directory, steps, state)`` and ``load(directory)``.

A checkpoint is the nested state the learners, :class:`~mitlc.learn.envs.vec.VecProduct` and the
run's tally produce (dicts, lists, tuples, numbers, strings, numpy arrays, torch tensors),
stored in up to three files named by the run's environment steps, as Stable-Baselines3 names
its checkpoints:

* ``checkpoint_<steps>_steps.json``: the structure, settings, counters and random-generator
  states, with markers for what JSON cannot hold (``{"__ndarray__": key}``,
  ``{"__tensor__": key}``, ``{"__tuple__": [...]}``, and ``{"__items__": [[key, value], ...]}``
  for a dict whose keys are not all plain strings, e.g. a torch optimiser's state);
* ``checkpoint_<steps>_steps.npz``: the numpy arrays (an uncompressed ``np.savez`` archive,
  read with ``allow_pickle=False`` after its headers are checked);
* ``checkpoint_<steps>_steps.safetensors``: the torch tensors.

``checkpoint.json``, written last and atomically, names the latest checkpoint and the SHA-256
of each of its files; :func:`load` checks them before parsing anything. Older checkpoints
beyond ``keep`` are deleted. No file is ever unpickled: a run directory with only the old
``checkpoint.pkl`` is refused. :mod:`mitlc.learn.rundir.state` checks a loaded state against fresh
objects before anything is restored from it.
"""

from __future__ import annotations

import hashlib
import io
import json
import re
import sys
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.lib import format as npy

from mitlc.files import write_atomically
from mitlc.inputs import (
    MAX_CHECKPOINT_BYTES,
    MAX_RECORD_BYTES,
    MAX_TENSOR_HEADER_BYTES,
    MAX_ZIP_DIRECTORY_BYTES,
    size_text,
    too_large,
)
from mitlc.learn.rundir.files import (
    RECORD,
    RunError,
    decode,
    file_size,
    parse_json,
    read_bytes,
    read_text,
)

INDEX, LEGACY = "checkpoint.json", "checkpoint.pkl"
FORMAT, INDEX_FORMAT = "mitlc.checkpoint/1", "mitlc.checkpoint-index/1"
NAME = re.compile(r"(checkpoint_([0-9]{12,})_steps)\.(json|npz|safetensors)")
MARKERS = ("__ndarray__", "__tensor__", "__tuple__", "__items__")
DATA = ("npz", "safetensors")
"""The kinds of a checkpoint's files held to :data:`~mitlc.inputs.MAX_CHECKPOINT_BYTES`."""
HELD = "a checkpoint's arrays and tensors"
"""What :data:`~mitlc.inputs.MAX_CHECKPOINT_BYTES` bounds, as a refusal names it."""


def stem(steps: int) -> str:
    """The file name (without extension) of the checkpoint at ``steps`` environment steps."""
    return f"checkpoint_{steps:012d}_steps"


def tensor_type() -> Any:
    """``torch.Tensor`` if torch is loaded (a run without tensors never imports it)."""
    torch = sys.modules.get("torch")
    return None if torch is None else torch.Tensor


# -- saving ----------------------------------------------------------------------------------------


class _Encoder:
    """The JSON tree of a state; its arrays and tensors set aside under keys."""

    def __init__(self) -> None:
        self.arrays: dict[str, np.ndarray[Any, Any]] = {}
        self.tensors: dict[str, Any] = {}
        self.tensor = tensor_type()

    def encode(self, value: Any) -> Any:
        if isinstance(value, np.ndarray):
            if value.dtype.hasobject:
                raise TypeError("object arrays cannot be checkpointed")
            key = f"a{len(self.arrays)}"
            self.arrays[key] = np.ascontiguousarray(value)
            return {"__ndarray__": key}
        if self.tensor is not None and isinstance(value, self.tensor):
            key = f"t{len(self.tensors)}"
            self.tensors[key] = value.detach().cpu().clone().contiguous()
            return {"__tensor__": key}
        if isinstance(value, np.generic):
            return value.item()
        if value is None or isinstance(value, bool | int | float | str):
            return value
        if isinstance(value, tuple):
            return {"__tuple__": [self.encode(v) for v in value]}
        if isinstance(value, list):
            return [self.encode(v) for v in value]
        if isinstance(value, dict):
            if all(isinstance(k, str) and not k.startswith("__") for k in value):
                return {k: self.encode(v) for k, v in value.items()}
            if not all(isinstance(k, str | int) and not isinstance(k, bool) for k in value):
                raise TypeError(f"dict keys must be str or int, got {list(value)!r}")
            return {"__items__": [[k, self.encode(v)] for k, v in value.items()]}
        raise TypeError(f"cannot checkpoint a {type(value).__name__}")


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def save(directory: Path, steps: int, state: dict[str, Any], keep: int = 2) -> Path:
    """Write ``state`` as the checkpoint at ``steps`` (data files atomically, then the index),
    then delete all but the ``keep`` latest checkpoints; the index's path. Saving again at the
    same ``steps`` replaces that checkpoint's files before the index is rewritten."""
    encoder = _Encoder()
    tree = encoder.encode(state)
    name = stem(steps)
    body = {"format": FORMAT, "steps": steps, "state": tree}
    blobs = {f"{name}.json": json.dumps(body, separators=(",", ":")).encode()}
    if encoder.arrays:
        buffer = io.BytesIO()  # what np.savez writes, without a way to pickle
        with zipfile.ZipFile(buffer, "w", zipfile.ZIP_STORED) as archive:
            for key, array in encoder.arrays.items():
                with archive.open(f"{key}.npy", "w", force_zip64=True) as member:
                    npy.write_array(member, array, allow_pickle=False)
        blobs[f"{name}.npz"] = buffer.getvalue()
    if encoder.tensors:
        from safetensors.torch import save as save_tensors

        blobs[f"{name}.safetensors"] = save_tensors(encoder.tensors)
    for file, data in blobs.items():
        write_atomically(directory / file, data)
    index = {
        "format": INDEX_FORMAT,
        "latest": name,
        "steps": steps,
        "files": {file: _sha256(data) for file, data in blobs.items()},
    }
    write_atomically(directory / INDEX, (json.dumps(index, indent=2) + "\n").encode())
    prune(directory, steps, keep)
    return directory / INDEX


def prune(directory: Path, latest: int, keep: int) -> None:
    """Delete the checkpoint files of all but the ``keep`` latest checkpoints up to ``latest``
    steps (files of later steps are leftovers of a run that died before its index named them)."""
    found: dict[int, list[Path]] = {}
    for path in directory.iterdir():
        match = NAME.fullmatch(path.name)
        if match:
            found.setdefault(int(match.group(2)), []).append(path)
    kept = set(sorted(s for s in found if s <= latest)[-max(keep, 1) :])
    for steps, paths in found.items():
        if steps not in kept:
            for path in paths:
                path.unlink(missing_ok=True)


# -- loading ---------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Loaded:
    """A checkpoint read back: its state, its steps and its files (by kind)."""

    state: dict[str, Any]
    steps: int
    files: dict[str, Path]


def exists(directory: Path) -> bool:
    """Whether ``directory`` holds a checkpoint (of this format or the old one)."""
    return (directory / INDEX).exists() or (directory / LEGACY).exists()


def _index(directory: Path) -> tuple[int, dict[str, tuple[Path, str]]]:
    """The latest checkpoint's steps and files with their SHA-256 by kind, from the index."""
    path = directory / INDEX
    if not path.exists():  # a FIFO or a device there is refused by read_text, not waited on
        if (directory / LEGACY).exists():
            raise RunError(
                f"{directory / LEGACY}: a checkpoint in the old pickle format, which mitlc no "
                "longer reads (loading a pickle can run any code); train the run again"
            )
        raise RunError(f"{directory}: no {INDEX} (no checkpoint to load)")
    index = parse_json(read_text(path), path)
    if not isinstance(index, dict) or index.get("format") != INDEX_FORMAT:
        raise RunError(f"{path}: not a checkpoint index (no format {INDEX_FORMAT!r})")
    name, steps, files = index.get("latest"), index.get("steps"), index.get("files")
    if not (isinstance(steps, int) and not isinstance(steps, bool) and steps >= 0):
        raise RunError(f"{path}: 'steps' is not a count ({steps!r})")
    if name != stem(steps):
        raise RunError(f"{path}: 'latest' should be {stem(steps)!r}, found {name!r}")
    if not isinstance(files, dict) or f"{name}.json" not in files:
        raise RunError(f"{path}: 'files' does not list {name}.json")
    found = {}
    for file, digest in files.items():
        match = NAME.fullmatch(file)
        if not match or match.group(1) != name:
            raise RunError(f"{path}: {file!r} is not a file of checkpoint {name}")
        if not (isinstance(digest, str) and re.fullmatch(r"[0-9a-f]{64}", digest)):
            raise RunError(f"{path}: the SHA-256 of {file} is not a hex digest")
        found[match.group(3)] = (directory / file, digest)
    return steps, found


def _check_sizes(listed: dict[str, tuple[Path, str]]) -> None:
    """Refuse, before reading any, a checkpoint whose ``.npz`` and ``.safetensors`` are larger
    than :data:`~mitlc.inputs.MAX_CHECKPOINT_BYTES`, alone or together."""
    sizes = {listed[kind][0]: file_size(listed[kind][0]) for kind in DATA if kind in listed}
    for path, size in sizes.items():
        if size > MAX_CHECKPOINT_BYTES:
            raise RunError(f"{path}: {too_large(path, size, MAX_CHECKPOINT_BYTES, HELD).strerror}")
    total = sum(sizes.values())
    if total > MAX_CHECKPOINT_BYTES:
        names = " and ".join(str(path) for path in sizes)
        raise RunError(
            f"{names}: {size_text(total)} together, larger than the "
            f"{size_text(MAX_CHECKPOINT_BYTES)} {HELD} may hold"
        )


def _read_verified(path: Path, digest: str, kind: str) -> bytes:
    """The bytes of the checkpoint file ``path`` (of ``kind``), within its cap, whose SHA-256
    is ``digest``."""
    limit, what = (MAX_CHECKPOINT_BYTES, HELD) if kind in DATA else (MAX_RECORD_BYTES, RECORD)
    data = read_bytes(path, limit, what)
    if _sha256(data) != digest:
        raise RunError(f"{path}: damaged (its SHA-256 is not the one {INDEX} records)")
    return data


def _zip_directory_size(data: bytes) -> int:
    """The size of the zip directory of the archive ``data``, as :mod:`zipfile` finds it (its
    end record, the zip64 one where there is one) before it builds an object per entry."""
    end = getattr(zipfile, "_EndRecData")(io.BytesIO(data))  # noqa: B009 (private in typeshed)
    if not end:
        raise ValueError("not a zip archive (no end of central directory)")
    return int(end[5])  # zipfile._ECD_SIZE


def _check_members(archive: zipfile.ZipFile, stored: int) -> None:
    """Every member of ``archive`` (``stored`` bytes in all) is stored, not compressed, and
    together they declare no more bytes than the archive holds, so reading them allocates no
    more than its size."""
    declared = 0
    for info in archive.infolist():
        if info.compress_type != zipfile.ZIP_STORED or not info.filename.endswith(".npy"):
            raise ValueError(f"unexpected member {info.filename!r}")
        if info.file_size != info.compress_size:
            raise ValueError(f"{info.filename}: declares {info.file_size} bytes, stores "
                             f"{info.compress_size}")  # fmt: skip
        declared += info.file_size
    if declared > stored:
        raise ValueError(f"its members declare {declared} bytes, the archive has {stored}")


def _check_header(archive: zipfile.ZipFile, info: zipfile.ZipInfo) -> None:
    """The ``.npy`` member ``info`` has a plain dtype and claims no more data than it holds."""
    with archive.open(info) as member:
        version = npy.read_magic(member)
        read = {(1, 0): npy.read_array_header_1_0, (2, 0): npy.read_array_header_2_0}
        if version not in read:
            raise ValueError(f"{info.filename}: unsupported .npy version {version}")
        shape, _, dtype = read[version](member)
        if dtype.hasobject or dtype.fields is not None:
            raise ValueError(f"{info.filename}: not a plain dtype ({dtype})")
        if int(np.prod(shape, dtype=object)) * dtype.itemsize > info.file_size:
            raise ValueError(f"{info.filename}: claims more data than it holds")


def _arrays(path: Path, data: bytes) -> dict[str, np.ndarray[Any, Any]]:
    """The arrays of an ``.npz`` (uncompressed members of plain dtypes whose headers claim no
    more data than they hold, declaring no more than the archive holds, listed in a directory
    within :data:`~mitlc.inputs.MAX_ZIP_DIRECTORY_BYTES`)."""
    try:
        directory = _zip_directory_size(data)
        if directory > MAX_ZIP_DIRECTORY_BYTES:
            raise ValueError(f"a zip directory of {size_text(directory)}, larger than the "
                             f"{size_text(MAX_ZIP_DIRECTORY_BYTES)} mitlc reads")  # fmt: skip
        with zipfile.ZipFile(io.BytesIO(data)) as archive:
            _check_members(archive, len(data))
            for info in archive.infolist():
                _check_header(archive, info)
            with np.load(io.BytesIO(data), allow_pickle=False) as npz:
                return {key: npz[key] for key in npz.files}
    except Exception as err:  # any failure to parse these bytes is damage
        raise RunError(f"{path}: not a valid .npz ({type(err).__name__}: {err})") from None


def _tensors(path: Path, data: bytes) -> dict[str, Any]:
    header = int.from_bytes(data[:8], "little")
    if header > MAX_TENSOR_HEADER_BYTES:
        raise RunError(
            f"{path}: not a valid .safetensors (a header of {size_text(header)}, larger than "
            f"the {size_text(MAX_TENSOR_HEADER_BYTES)} mitlc reads)"
        )
    try:
        from safetensors.torch import load as load_tensors
    except ImportError:
        raise RunError(
            f"{path}: reading it needs torch and safetensors (pip install 'mitlc[learn]')"
        ) from None
    try:
        return load_tensors(data)
    except Exception as err:  # any failure to parse these bytes is damage
        raise RunError(f"{path}: not a valid .safetensors ({type(err).__name__}: {err})") from None


def load(directory: Path) -> Loaded:
    """The latest checkpoint in ``directory``, checked against its index and decoded; a
    :class:`RunError` naming the file for anything missing, damaged or malformed."""
    steps, listed = _index(directory)
    files = {kind: path for kind, (path, _) in listed.items()}
    _check_sizes(listed)
    blobs = {kind: _read_verified(path, digest, kind) for kind, (path, digest) in listed.items()}
    body = parse_json(decode(blobs["json"], files["json"]), files["json"])
    if not isinstance(body, dict) or body.get("format") != FORMAT or "state" not in body:
        raise RunError(f"{files['json']}: not a checkpoint (no format {FORMAT!r})")
    if body.get("steps") != steps:
        raise RunError(f"{files['json']}: holds steps {body.get('steps')!r}, the index {steps}")
    # Each file's bytes are let go once decoded: at most both files and one decoded at once.
    arrays = _arrays(files["npz"], blobs.pop("npz")) if "npz" in blobs else {}
    tensors = (
        _tensors(files["safetensors"], blobs.pop("safetensors")) if "safetensors" in blobs else {}
    )
    try:
        state = _decode(body["state"], arrays, tensors)
    except (ValueError, TypeError, KeyError, RecursionError) as err:
        raise RunError(f"{files['json']}: {err}") from None
    if not isinstance(state, dict):
        raise RunError(f"{files['json']}: the state is not a JSON object")
    return Loaded(state, steps, files)


def _decode(value: Any, arrays: dict[str, Any], tensors: dict[str, Any]) -> Any:
    if isinstance(value, list):
        return [_decode(v, arrays, tensors) for v in value]
    if not isinstance(value, dict):
        return value
    marked = [k for k in value if k.startswith("__")]
    if not marked:
        return {k: _decode(v, arrays, tensors) for k, v in value.items()}
    if len(value) != 1 or marked[0] not in MARKERS:
        raise ValueError(f"unknown marker {marked[0]!r}")
    marker, inner = marked[0], value[marked[0]]
    if marker in ("__ndarray__", "__tensor__"):
        store, what = (arrays, "array") if marker == "__ndarray__" else (tensors, "tensor")
        if not isinstance(inner, str) or inner not in store:
            raise KeyError(f"no {what} {inner!r} in its file")
        return store[inner]
    if not isinstance(inner, list):
        raise TypeError(f"{marker} needs a list, got {type(inner).__name__}")
    if marker == "__tuple__":
        return tuple(_decode(v, arrays, tensors) for v in inner)
    items: dict[Any, Any] = {}
    for pair in inner:
        if not (isinstance(pair, list) and len(pair) == 2 and isinstance(pair[0], str | int)):
            raise TypeError(f"__items__ needs [key, value] pairs, got {pair!r}")
        items[pair[0]] = _decode(pair[1], arrays, tensors)
    return items
