"""Checkpoints hold data only (:mod:`mitlc.learn.rundir.checkpoint`): exact round trips for every
learner, files named by steps and pruned, crafted pickles under every file name of a run
directory that never run, damaged files of every kind reported in one line naming the file,
and the run directory's lock."""

from __future__ import annotations

import hashlib
import io
import json
import os
import pickle
import shlex
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner

from mitlc.cli import app
from mitlc.errors import MitlcError
from mitlc.learn.config import ConfigError, DQNConfig, TrainConfig, resolve
from mitlc.learn.envs.vec import VecProduct
from mitlc.learn.evaluation.evaluate import evaluate
from mitlc.learn.plots import plot_run, read_metrics
from mitlc.learn.run import (
    ROWS,
    UNCHECKED,
    RunError,
    Tally,
    load_learner,
    make_learner,
    prepare,
    train,
)
from mitlc.learn.rundir import checkpoint
from mitlc.learn.rundir.files import locked
from mitlc.learn.rundir.state import restore
from tests.conftest import ROOT, TINY_DRQN

CASE1 = ROOT / "specs" / "paper" / "case1.yaml"
CASE3 = ROOT / "specs" / "paper" / "case3-office.yaml"
DQN = DQNConfig(num_envs=4, hidden=16, batch_size=16, warmup_steps=32, target_update=10)
DRQN = TINY_DRQN
WORLDS = {"q": CASE1, "dqn": CASE1, "drqn": CASE3}
EPISODES = {"q": 2000, "dqn": 40, "drqn": 20}


def settings(algo: str, episodes: int) -> TrainConfig:
    """A tiny run of ``algo``."""
    if algo == "q":
        training = {"episodes": episodes, "q": {"num_envs": 64}}
        return resolve(
            {**training, "log_every": 200, "checkpoint_every": 500}, {}, discount=0.99, pomdp=False
        )
    every = EPISODES[algo]  # the same for every total, so that a run may be resumed
    return TrainConfig(
        algo=algo,  # type: ignore[arg-type]
        seed=3,
        episodes=episodes,
        log_every=every // 4,
        checkpoint_every=every // 2,
        dqn=DQN,
        drqn=DRQN,
    )


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    pytest.importorskip("torch")
    base = tmp_path_factory.mktemp("runs")
    for algo, episodes in EPISODES.items():
        train(WORLDS[algo], settings(algo, episodes), base / algo)
    return {algo: base / algo for algo in EPISODES}


def copy_run(source: Path, target: Path) -> Path:
    shutil.copytree(source, target)
    return target


def index(directory: Path) -> dict[str, Any]:
    data: dict[str, Any] = json.loads((directory / checkpoint.INDEX).read_text())
    return data


def latest(directory: Path, kind: str) -> Path:
    """The latest checkpoint's file of ``kind`` (json, npz, safetensors)."""
    return directory / f"{index(directory)['latest']}.{kind}"


def replace_file(path: Path, data: bytes, *, fix_digest: bool) -> None:
    """Write ``data`` to ``path``; with ``fix_digest``, record its SHA-256 in the index so
    that the parser, not the checksum, meets it."""
    path.write_bytes(data)
    if fix_digest:
        saved = index(path.parent)
        saved["files"][path.name] = hashlib.sha256(data).hexdigest()
        (path.parent / checkpoint.INDEX).write_text(json.dumps(saved))


def one_line_error(action: Callable[[], object], names: str) -> str:
    with pytest.raises(MitlcError) as caught:
        action()
    message = str(caught.value)
    assert "\n" not in message and names in message, message
    return message


# -- round trips -----------------------------------------------------------------------------


@pytest.mark.parametrize("algo", ["q", "dqn", "drqn"])
def test_saved_state_continues_exactly(algo: str, tmp_path: Path) -> None:
    if algo != "q":
        pytest.importorskip("torch")
    setting = prepare(WORLDS[algo], settings(algo, 100))
    learner = make_learner(setting, np.random.default_rng(1))
    env = VecProduct(setting.tables, learner.num_envs, np.random.default_rng(2))
    tally = Tally()
    for _ in range(60):
        learner.train_step(env, 0.3)
    tally.steps = 60 * env.num_envs
    state = {"learner": learner.state_dict(), "env": env.state_dict(), "tally": tally.state_dict()}
    checkpoint.save(tmp_path, tally.steps, state)
    twin = make_learner(setting, np.random.default_rng(99))
    twin_env = VecProduct(setting.tables, twin.num_envs, np.random.default_rng(98))
    parts = {"learner": twin, "env": twin_env, "tally": Tally()}
    restore(tmp_path, parts, rows=ROWS, unchecked=UNCHECKED)  # type: ignore[arg-type]
    for _ in range(40):
        a, b = learner.train_step(env, 0.5), twin.train_step(twin_env, 0.5)
        assert np.array_equal(a.next_state, b.next_state) and np.array_equal(a.reward, b.reward)
    ours, theirs = learner.state_dict(), twin.state_dict()
    assert ours["rng"] == theirs["rng"]
    if algo == "q":
        assert np.array_equal(ours["q_table"], theirs["q_table"])
    else:
        import torch

        assert all(torch.equal(ours["net"][k], theirs["net"][k]) for k in ours["net"])


def test_files_are_data_named_by_steps_and_the_old_ones_pruned(tmp_path: Path) -> None:
    config = resolve(
        {"episodes": 2000, "q": {"num_envs": 64}, "checkpoint_every": 200, "keep_checkpoints": 3},
        {},
        discount=0.99,
        pomdp=False,
    )
    result = train(CASE1, config, tmp_path / "run")
    saved = index(tmp_path / "run")
    assert saved["steps"] == result.steps
    assert saved["latest"] == f"checkpoint_{result.steps:012d}_steps"
    for name, digest in saved["files"].items():
        assert hashlib.sha256((tmp_path / "run" / name).read_bytes()).hexdigest() == digest
    stems = {p.name.split(".")[0] for p in (tmp_path / "run").glob("checkpoint_*_steps.*")}
    assert len(stems) == 3 and max(stems) == saved["latest"]
    assert not list((tmp_path / "run").glob("*.pkl"))
    with pytest.raises(ConfigError, match=r"training\.keep_checkpoints: expected a positive"):
        resolve({"keep_checkpoints": 0}, {}, discount=0.99, pomdp=False)


# -- crafted pickles never run -----------------------------------------------------------------


class Payload:
    """Unpickling this runs a shell command that creates ``marker``."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self) -> tuple[Any, tuple[str]]:
        return (os.system, (f"touch {shlex.quote(str(self.marker))}",))


def test_the_payload_runs_code_when_unpickled(tmp_path: Path) -> None:
    """The control: the payload of the test below does run when something unpickles it."""
    marker = tmp_path / "pwned"
    pickle.loads(pickle.dumps(Payload(marker)))
    assert marker.exists()


def every_use(directory: Path, world: Path, config: TrainConfig) -> None:
    """Load, evaluate, plot and resume the run; each may fail with mitlc's errors only."""
    actions: list[Callable[[], object]] = [
        lambda: load_learner(directory),
        lambda: evaluate(directory, episodes=20),
        lambda: plot_run(directory, directory / "plots", trajectories=1),
        lambda: train(world, config, directory, resume=True),
    ]
    for action in actions:
        try:
            action()
        except MitlcError as err:
            assert "\n" not in str(err), err


DATA = ["json", "npz", "safetensors"]
CASES = [(name, False) for name in ["index", "legacy", "config", "metrics", "summary", *DATA]]
CASES += [(name, True) for name in DATA]  # with the index's digest updated: the parsers meet it


@pytest.mark.parametrize(("name", "fix_digest"), CASES)
def test_a_crafted_pickle_under_any_name_runs_nothing(
    runs: dict[str, Path], tmp_path: Path, name: str, fix_digest: bool
) -> None:
    directory = copy_run(runs["dqn"], tmp_path / "run")
    marker = tmp_path / "pwned"
    payload = pickle.dumps(Payload(marker))
    if name in DATA:
        replace_file(latest(directory, name), payload, fix_digest=fix_digest)
    elif name == "legacy":
        for path in directory.glob("checkpoint*"):
            path.unlink()
        (directory / checkpoint.LEGACY).write_bytes(payload)
        one_line_error(lambda: load_learner(directory), "old pickle format")
    else:
        files = {"index": checkpoint.INDEX, "config": "config.json"}
        files |= {"metrics": "metrics.jsonl", "summary": "summary.json"}
        (directory / files[name]).write_bytes(payload)
    every_use(directory, CASE1, settings("dqn", 60))
    assert not marker.exists()


def test_a_pickled_object_array_in_the_npz_is_refused(
    runs: dict[str, Path], tmp_path: Path
) -> None:
    directory = copy_run(runs["q"], tmp_path / "run")
    marker = tmp_path / "pwned"
    buffer = io.BytesIO()
    np.savez(buffer, a0=np.array([Payload(marker)], dtype=object), allow_pickle=True)
    replace_file(latest(directory, "npz"), buffer.getvalue(), fix_digest=True)
    one_line_error(lambda: load_learner(directory), "not a plain dtype")
    assert not marker.exists()


# -- damaged files ---------------------------------------------------------------------------


def damage(data: bytes, how: str) -> bytes:
    rng = np.random.default_rng(len(data))
    if how == "empty":
        return b""
    if how == "truncated":
        return data[: len(data) // 2]
    if how == "garbage":
        return rng.integers(0, 256, len(data), dtype=np.uint8).tobytes()
    # not UTF-8: in the middle (an .npz's array data, under its CRC), but in a .safetensors
    # file's JSON header (its tensor data has no checksum of its own)
    at = 20 if data[8:10] == b'{"' else len(data) // 2
    return data[:at] + b"\xff\xfe" + data[at + 2 :]


HOW = ["empty", "truncated", "garbage", "not-utf8"]


@pytest.mark.parametrize("fix_digest", [False, True], ids=["checksum", "parser"])
@pytest.mark.parametrize("how", HOW)
@pytest.mark.parametrize("kind", ["json", "npz", "safetensors"])
def test_a_damaged_checkpoint_file_is_one_line_naming_it(
    runs: dict[str, Path], tmp_path: Path, kind: str, how: str, fix_digest: bool
) -> None:
    directory = copy_run(runs["dqn"], tmp_path / "run")
    path = latest(directory, kind)
    replace_file(path, damage(path.read_bytes(), how), fix_digest=fix_digest)
    message = one_line_error(lambda: load_learner(directory), path.name)
    assert ("SHA-256" in message) != fix_digest


@pytest.mark.parametrize("how", HOW)
@pytest.mark.parametrize("name", [checkpoint.INDEX, "config.json"])
def test_a_damaged_index_or_config_is_one_line_naming_it(
    runs: dict[str, Path], tmp_path: Path, name: str, how: str
) -> None:
    directory = copy_run(runs["q"], tmp_path / "run")
    path = directory / name
    path.write_bytes(damage(path.read_bytes(), how))
    one_line_error(lambda: load_learner(directory), name)


def test_damaged_metrics_name_the_line(runs: dict[str, Path], tmp_path: Path) -> None:
    directory = copy_run(runs["q"], tmp_path / "run")
    path = directory / "metrics.jsonl"
    lines = path.read_bytes().splitlines(keepends=True)
    path.write_bytes(b"".join([*lines[:3], b'{"episodes": \xff}\n', *lines[3:]]))
    one_line_error(lambda: read_metrics(directory), "metrics.jsonl: line 4: not UTF-8")
    config = settings("q", 3000)
    one_line_error(lambda: train(CASE1, config, directory, resume=True), "line 4")
    path.write_bytes(b"".join([*lines[:1], b"[1, 2]\n", *lines[1:]]))
    one_line_error(lambda: read_metrics(directory), "line 2: expected a JSON object")
    path.write_bytes(b"".join([*lines[:1], b'{"episodes": 5}\n', *lines[1:]]))
    one_line_error(lambda: read_metrics(directory), "line 2: 'success_rate' is missing")
    path.write_bytes(b"".join(lines)[:-7])  # the last line cut short: left out, no error
    assert len(read_metrics(directory).episodes) == len(lines) - 1


def modified(directory: Path, change: Callable[[dict[str, Any]], None]) -> None:
    """Rewrite the run's latest checkpoint with ``change`` applied to its state (well-formed
    files with the right checksums: only the checks of the state can catch it)."""
    loaded = checkpoint.load(directory)
    change(loaded.state)
    checkpoint.save(directory, loaded.steps, loaded.state)


CHANGES: dict[str, tuple[str, Callable[[dict[str, Any]], None], str]] = {
    "wrong shape": ("q", lambda s: s["learner"].update(q_table=np.zeros((2, 3))), ".npz"),
    "wrong dtype": ("q", lambda s: s["env"].update(state=s["env"]["state"] * 1.0), ".npz"),
    "missing key": ("q", lambda s: s["learner"].pop("q_table"), ".json"),
    "extra key": ("q", lambda s: s["tally"].update(extra=1), ".json"),
    "wrong type": ("q", lambda s: s["tally"].update(episodes="many"), ".json"),
    "state out of range": ("q", lambda s: s["env"]["state"].fill(10**9), "env: state"),
    "absorbing state": ("q", lambda s: s["env"]["state"].fill(0), "absorbing"),
    "bad rng": ("q", lambda s: s["env"]["rng"]["state"].update(state=-1), "env:"),
    "tensor shape": (
        "dqn",
        lambda s: s["learner"]["net"].update({"0.bias": s["learner"]["net"]["0.weight"]}),
        ".safetensors",
    ),
    "replay rows": ("dqn", lambda s: s["learner"]["replay"].update(size=3), "replay"),
    "replay index": (
        "dqn",
        lambda s: s["learner"]["replay"]["data"]["action"].fill(99),
        "replay.action",
    ),
    "moments": (
        "dqn",
        lambda s: s["learner"]["optimizer"]["state"][0].update(
            exp_avg=s["learner"]["optimizer"]["state"][1]["exp_avg"]
        ),
        "optimizer.state[0].exp_avg",
    ),
    "streams": (
        "drqn",
        lambda s: s["learner"].update(length=s["learner"]["length"] + 10**6),
        "length",
    ),
}


@pytest.mark.parametrize("case", sorted(CHANGES))
def test_a_state_unlike_the_run_is_one_line_naming_the_file(
    runs: dict[str, Path], tmp_path: Path, case: str
) -> None:
    algo, change, expected = CHANGES[case]
    directory = copy_run(runs[algo], tmp_path / "run")
    modified(directory, change)
    message = one_line_error(lambda: load_learner(directory), expected)
    assert "checkpoint_" in message


def test_cli_reports_a_damaged_run_in_one_line(runs: dict[str, Path], tmp_path: Path) -> None:
    directory = copy_run(runs["q"], tmp_path / "run")
    path = latest(directory, "npz")
    path.write_bytes(path.read_bytes()[:100])
    resume = ["train", str(CASE1), "--out", str(directory), "--resume", "--episodes", "9000"]
    for args in (["eval", str(directory)], ["plot", str(directory)], [*resume, "-q"]):
        result = CliRunner().invoke(app, args)
        assert result.exit_code == 1, result.output
        assert "Traceback" not in result.output and result.output.count("\n") == 1, result.output
        assert path.name in result.output and "SHA-256" in result.output


# -- the lock --------------------------------------------------------------------------------

HOLD = (
    "import sys, time; from pathlib import Path; from mitlc.learn.rundir.files import locked\n"
    "with locked(Path(sys.argv[1])):\n    print('held', flush=True); time.sleep(120)\n"
)


def test_a_run_directory_in_use_is_refused_naming_the_process(
    runs: dict[str, Path], tmp_path: Path
) -> None:
    directory = copy_run(runs["q"], tmp_path / "run")
    config = settings("q", 3000)
    with locked(directory):  # a second open file description in this process
        message = one_line_error(lambda: train(CASE1, config, directory, resume=True), "in use")
        assert f"process {os.getpid()} (" in message and "wait for it to finish" in message
    empty = tmp_path / "empty"
    empty.mkdir()
    with locked(empty):  # a fresh run is refused too, whatever the timing
        one_line_error(lambda: train(CASE1, config, empty), f"{empty}: in use by process")
    assert {p.name for p in empty.iterdir()} == {".lock"}
    holder = subprocess.Popen(
        [sys.executable, "-c", HOLD, str(directory)], stdout=subprocess.PIPE, text=True, cwd=ROOT
    )
    try:
        assert holder.stdout is not None and holder.stdout.readline() == "held\n"
        message = one_line_error(lambda: train(CASE1, config, directory, resume=True), "in use")
        assert f"process {holder.pid} (python" in message
        fresh = tmp_path / "fresh"
        fresh.mkdir()
        shutil.copy(directory / ".lock", fresh / ".lock")
        with locked(fresh):  # the lock is the open file's, not the file's text
            pass
    finally:
        holder.send_signal(signal.SIGKILL)
        holder.wait(timeout=30)
    result, deadline = None, time.monotonic() + 10
    while result is None and time.monotonic() < deadline:  # the OS drops a dead process's lock
        try:
            result = train(CASE1, config, directory, resume=True)
        except RunError as err:
            assert "in use" in str(err)
            time.sleep(0.1)
    assert result is not None and 3000 <= result.episodes < 3000 + 64
