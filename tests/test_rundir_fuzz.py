"""Seeded fuzzing of the run-directory loader: the files of a real tiny run (tabular and DQN)
mutated at random (bits flipped, cut, bytes inserted or replaced, JSON values swapped for odd
ones), with the checkpoint index's digests sometimes updated so that the parsers and the state
checks meet the damage. Loading may succeed or fail with mitlc's own one-line errors, never
anything else."""

from __future__ import annotations

import hashlib
import json
import random
from pathlib import Path
from typing import Any

import pytest

from mitlc.errors import MitlcError
from mitlc.learn.plots import read_metrics
from mitlc.learn.run import load_learner, train
from mitlc.learn.rundir import checkpoint
from tests.test_checkpoint import CASE1, settings

ODD: list[Any] = [
    None,
    True,
    -1,
    0,
    3,
    2**70,
    1.5,
    float("nan"),
    "x",
    "\x00",
    [],
    [1, [2]],
    {},
    {"__ndarray__": "a0"},
    {"__tensor__": "t0"},
    {"__tuple__": [1]},
    {"__items__": [[0, {}]]},
    {"__bogus__": 1},
]
"""Values a JSON mutation puts in place of a random one."""


@pytest.fixture(scope="module")
def originals(tmp_path_factory: pytest.TempPathFactory) -> dict[str, dict[str, bytes]]:
    """The files of a tiny tabular run and a tiny DQN run, by name."""
    pytest.importorskip("torch")
    base = tmp_path_factory.mktemp("fuzz")
    train(CASE1, settings("q", 600), base / "q")
    train(CASE1, settings("dqn", 40), base / "dqn")
    return {
        algo: {p.name: p.read_bytes() for p in (base / algo).iterdir() if p.name != ".lock"}
        for algo in ("q", "dqn")
    }


def _nodes(value: Any, path: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    """The paths of every node of a JSON value."""
    found = [path]
    if isinstance(value, dict):
        for key, inner in value.items():
            found += _nodes(inner, (*path, key))
    elif isinstance(value, list):
        for i, inner in enumerate(value):
            found += _nodes(inner, (*path, i))
    return found


def mutate_json(data: bytes, rng: random.Random) -> bytes:
    """A random node of the JSON in ``data`` replaced by an odd value, or deleted."""
    document = json.loads(data)
    path = rng.choice(_nodes(document)[1:] or [()])
    if not path:
        return json.dumps(rng.choice(ODD)).encode()
    parent = document
    for key in path[:-1]:
        parent = parent[key]
    if rng.random() < 0.2:
        del parent[path[-1]]
    else:
        parent[path[-1]] = rng.choice(ODD)
    return json.dumps(document).encode()


def mutate_bytes(data: bytes, rng: random.Random) -> bytes:
    """A bit flipped, a cut, bytes inserted, a span replaced, or all of it random."""
    junk = bytes(rng.randrange(256) for _ in range(rng.randint(1, 8)))
    at = rng.randrange(len(data) + 1)
    how = rng.choice(["flip", "cut", "insert", "replace", "random"])
    if how == "flip" and data:
        at = min(at, len(data) - 1)
        return data[:at] + bytes([data[at] ^ (1 << rng.randrange(8))]) + data[at + 1 :]
    if how == "cut":
        return data[:at]
    if how == "insert":
        return data[:at] + junk + data[at:]
    if how == "replace":
        return data[:at] + junk + data[at + len(junk) :]
    return bytes(rng.randrange(256) for _ in range(rng.randint(0, 64)))


def mutated(files: dict[str, bytes], rng: random.Random) -> tuple[dict[str, bytes], str]:
    """A copy of ``files`` with one of them mutated, and what was done."""
    files = dict(files)
    name = rng.choice(sorted(n for n in files if n != "summary.json"))
    structural = name.endswith((".json", ".jsonl")) and rng.random() < 0.5
    if structural and name.endswith(".jsonl"):
        lines = files[name].splitlines(keepends=True)
        i = rng.randrange(len(lines))
        lines[i] = mutate_json(lines[i], rng) + b"\n"
        files[name] = b"".join(lines)
    elif structural:
        files[name] = mutate_json(files[name], rng)
    else:
        files[name] = mutate_bytes(files[name], rng)
    index = json.loads(files[checkpoint.INDEX]) if name != checkpoint.INDEX else {}
    fixed = name in index.get("files", {}) and rng.random() < 0.7
    if fixed:
        index["files"][name] = hashlib.sha256(files[name]).hexdigest()
        files[checkpoint.INDEX] = json.dumps(index).encode()
    kind = "json" if structural else "bytes"
    return files, f"{name}: {kind} mutation{', digest updated' if fixed else ''}"


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("algo", ["q", "dqn"])
def test_mutated_run_directories_fail_only_with_mitlc_errors(
    originals: dict[str, dict[str, bytes]], tmp_path: Path, algo: str, seed: int
) -> None:
    rng = random.Random(f"{algo}-{seed}")
    directory = tmp_path / "run"
    directory.mkdir()
    outcomes = {"loaded": 0, "refused": 0}
    for _ in range(20):
        files, what = mutated(originals[algo], rng)
        for old in directory.iterdir():
            old.unlink()
        for name, data in files.items():
            (directory / name).write_bytes(data)
        for load in (load_learner, read_metrics):
            try:
                load(directory)
                outcomes["loaded"] += 1
            except MitlcError as err:
                assert "\n" not in str(err) and str(directory) in str(err), (what, err)
                outcomes["refused"] += 1
            except Exception as err:  # any other error is a finding
                raise AssertionError(f"{what}: {type(err).__name__}: {err}") from err
    assert outcomes["refused"] > 0
