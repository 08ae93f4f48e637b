"""Every file mitlc reads is read within a size cap, and a path that is not a regular file (a
FIFO, a device, a directory) is refused before it is opened (issue 26): huge sparse files in a
run directory for ``eval``, ``plot`` and ``train --resume``, ``render`` of a link to
``/dev/zero``, FIFOs given as a spec, a trace, a world, a batch or a sweep file; and the one
rule of both trace forms (no unknown proposition, no repeated column).

A command that opened a FIFO for reading would wait for a writer for ever: every call here runs
under an alarm (``SIGALRM`` interrupts the blocked ``open``), so a regression fails instead of
hanging."""

from __future__ import annotations

import hashlib
import json
import os
import resource
import shutil
import signal
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from types import FrameType
from typing import TypeVar

import pytest
from typer.testing import CliRunner, Result

from mitlc import inputs
from mitlc.cli import app
from mitlc.learn.rundir import checkpoint
from mitlc.learn.rundir.files import RunError
from tests.conftest import ROOT

T = TypeVar("T")
CASE1_WORLD = ROOT / "specs" / "paper" / "case1.yaml"
CASE1_SPEC = ROOT / "specs" / "paper" / "case1.mitl"
HUGE = 6 * 2**30
"""The size of the sparse files (instant to make, no disk taken)."""
WAIT = 20.0
"""Seconds a call may take before it counts as blocked."""
MEMORY = 300 * 2**20
"""Bytes by which a refusal may raise the process's peak memory."""

RECORD = "4 MiB a run's JSON record"
METRICS = "128 MiB a run's metrics"
DATA = "2 GiB a checkpoint's arrays and tensors"
CAPS = {
    "config.json": RECORD,
    "checkpoint.json": RECORD,
    "ckpt.json": RECORD,
    "ckpt.npz": DATA,
    "ckpt.safetensors": DATA,
    "metrics.jsonl": METRICS,
}
"""The cap named in the refusal of each file of a run directory (``ckpt``: the latest)."""


class Blocked(BaseException):
    """A call still running at its time limit (a BaseException: no ``except Exception`` in
    the code under test swallows it)."""


@contextmanager
def time_limit(seconds: float = WAIT) -> Iterator[None]:
    """Raise :class:`Blocked` in the ``with`` block once ``seconds`` have passed, also out of a
    blocked system call such as opening a FIFO (main thread only, as signals are)."""

    def expire(signum: int, frame: FrameType | None) -> None:
        raise Blocked(f"still running after {seconds} s: blocked opening a FIFO?")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def within(call: Callable[[], T], seconds: float = WAIT) -> T:
    """``call()``, stopped by :class:`Blocked` after ``seconds``."""
    with time_limit(seconds):
        return call()


def invoke(*args: str | Path, stdin: str | None = None) -> Result:
    """The command line run in-process within :data:`WAIT` seconds, never raising."""
    result = within(lambda: CliRunner().invoke(app, [str(a) for a in args], input=stdin))
    assert result.exception is None or isinstance(result.exception, SystemExit), repr(
        result.exception
    )
    return result


def refused(result: Result, line: str) -> None:
    """Exit status 1 and the one line ``line``, no traceback."""
    assert result.exit_code == 1, result.output
    assert result.output == line + "\n"


def peak() -> int:
    """The process's peak resident memory so far, in bytes (Linux reports KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def huge(path: Path) -> None:
    """Replace ``path`` by a sparse file of :data:`HUGE` bytes."""
    path.unlink(missing_ok=True)
    path.touch()
    os.truncate(path, HUGE)


@pytest.fixture
def fifo() -> Callable[[Path], Path]:
    """Make a FIFO at a path (in place of what is there)."""

    def make(path: Path) -> Path:
        path.unlink(missing_ok=True)
        os.mkfifo(path)
        return path

    return make


# --- a run directory --------------------------------------------------------------------------


@pytest.fixture(scope="module")
def trained(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A tiny real run (tabular Q-learning on case 1, 2,000 episodes)."""
    out = tmp_path_factory.mktemp("caps") / "run"
    result = CliRunner().invoke(
        app, ["train", str(CASE1_WORLD), "--episodes", "2000", "--out", str(out), "-q", "--no-eval"]
    )
    assert result.exit_code == 0, result.output
    return out


@pytest.fixture
def run(trained: Path, tmp_path: Path) -> Path:
    """A copy of the tiny run."""
    copy = tmp_path / "run"
    shutil.copytree(trained, copy)
    return copy


def member(run: Path, name: str) -> Path:
    """The file ``name`` of ``run``; ``ckpt.EXT`` is the latest checkpoint's, and a
    ``ckpt.safetensors`` (which a Q-learning run has not) is listed in the index, empty."""
    if not name.startswith("ckpt."):
        return run / name
    index = json.loads((run / checkpoint.INDEX).read_text(encoding="utf-8"))
    path = run / f"{index['latest']}{name.removeprefix('ckpt')}"
    if not path.exists():
        relist(run, path, b"")
    return path


def relist(run: Path, path: Path, data: bytes) -> None:
    """Write ``data`` into the checkpoint file ``path`` with its digest in the index."""
    path.write_bytes(data)
    index = json.loads((run / checkpoint.INDEX).read_text(encoding="utf-8"))
    index["files"][path.name] = hashlib.sha256(data).hexdigest()
    (run / checkpoint.INDEX).write_text(json.dumps(index), encoding="utf-8")


def command(name: str, run: Path) -> list[str | Path]:
    """The arguments of ``mitlc NAME`` on ``run``."""
    if name == "eval":
        return ["eval", run, "--episodes", "10"]
    if name == "plot":
        return ["plot", run, "--out", run.parent / "png", "--trajectories", "0"]
    return ["train", CASE1_WORLD, "--resume", "--out", run, "--episodes", "4000", "-q", "--no-eval"]


CASES = [
    (name, file)
    for name in ("eval", "plot", "train")
    for file in CAPS
    if not (name == "eval" and file == "metrics.jsonl")  # eval does not read the metrics
]


@pytest.mark.parametrize(("name", "file"), CASES)
def test_a_huge_run_file_is_refused_before_it_is_read(run: Path, name: str, file: str) -> None:
    path = member(run, file)
    huge(path)
    before = peak()
    result = invoke(*command(name, run))
    refused(result, f"{path}: 6 GiB, larger than the {CAPS[file]} may hold")
    assert peak() - before < MEMORY


@pytest.mark.parametrize(("name", "file"), [("eval", "config.json"), ("plot", "metrics.jsonl"),
                                            ("train", "ckpt.npz")])  # fmt: skip
def test_a_fifo_in_a_run_is_refused(run: Path, fifo: Callable[[Path], Path], name: str,
                                    file: str) -> None:  # fmt: skip
    path = fifo(member(run, file))
    refused(invoke(*command(name, run)), f"{path}: not a regular file (a FIFO)")


def test_a_fifo_as_the_lock_file_is_refused(run: Path, fifo: Callable[[Path], Path]) -> None:
    path = fifo(run / ".lock")
    result = invoke(*command("train", run))
    refused(result, f"{path}: not a regular file, so not a run's lock file; remove it")


def test_the_run_still_reads_and_resumes(run: Path) -> None:
    assert invoke(*command("eval", run)).exit_code == 0
    result = invoke(*command("train", run))
    assert result.exit_code == 0, result.output


@pytest.mark.parametrize(
    ("fields", "words"),
    [
        (slice(24, 28), "declares 2147483647 bytes, stores"),  # uncompressed size alone
        (slice(20, 28), r"its members declare \d+ bytes, the archive has \d+"),  # both
    ],
)
def test_npz_members_may_not_declare_more_than_the_archive_holds(
    run: Path, fields: slice, words: str
) -> None:
    path = member(run, "ckpt.npz")
    data = bytearray(path.read_bytes())
    entry = data.rindex(b"PK\x01\x02")  # the last member's directory entry
    start, stop = entry + fields.start, entry + fields.stop
    data[start:stop] = (2**31 - 1).to_bytes(4, "little") * ((stop - start) // 4)
    relist(run, path, bytes(data))
    with pytest.raises(RunError, match=rf"not a valid \.npz .*{words}"):
        checkpoint.load(run)


def test_an_npz_directory_larger_than_its_cap_is_refused_unread(run: Path) -> None:
    path = member(run, "ckpt.npz")
    data = bytearray(path.read_bytes())
    assert data[-22:-18] == b"PK\x05\x06"  # the end record, no comment
    data[-10:-6] = (64 * 2**20).to_bytes(4, "little")  # the directory's size: 64 MiB
    relist(run, path, bytes(data))
    with pytest.raises(RunError, match="a zip directory of 64 MiB, larger than the 1 MiB"):
        checkpoint.load(run)


def test_a_safetensors_header_larger_than_its_cap_is_refused_unread(run: Path) -> None:
    path = member(run, "ckpt.safetensors")
    relist(run, path, (2**40).to_bytes(8, "little") + b"{}")
    with pytest.raises(RunError, match="a header of 1024 GiB, larger than the 1 MiB mitlc reads"):
        checkpoint.load(run)


def test_a_checkpoint_larger_than_its_cap_together_is_refused(run: Path) -> None:
    for name in ("ckpt.npz", "ckpt.safetensors"):
        path = member(run, name)
        path.unlink()
        path.touch()
        os.truncate(path, 1200 * 2**20)
    with pytest.raises(RunError, match=f"2.3 GiB together, larger than the {DATA} may hold"):
        checkpoint.load(run)


# --- render, specs, traces, worlds, batches, sweeps -------------------------------------------


@pytest.mark.skipif(not os.path.exists("/dev/zero"), reason="needs /dev/zero")
def test_render_refuses_a_link_to_dev_zero(tmp_path: Path) -> None:
    link = tmp_path / "automaton.json"
    link.symlink_to("/dev/zero")
    result = invoke("render", link, "-o", tmp_path / "a.dot")
    refused(result, f"mitlc: {link}: not a regular file (a character device)")


def test_render_refuses_a_huge_artifact(tmp_path: Path) -> None:
    path = tmp_path / "automaton.json"
    huge(path)
    result = invoke("render", path, "-o", tmp_path / "a.dot")
    refused(result, f"mitlc: {path}: 6 GiB, larger than the 16 MiB an automaton artifact may hold")


def test_fifo_inputs_are_refused_before_they_are_opened(
    tmp_path: Path, fifo: Callable[[Path], Path]
) -> None:
    spec = fifo(tmp_path / "task.mitl")
    refused(invoke("compile", spec), f"mitlc: {spec}: not a regular file (a FIFO)")
    refused(invoke("compile", "--batch", spec), f"mitlc: {spec}: not a regular file (a FIFO)")
    trace = fifo(tmp_path / "trace.csv")
    refused(
        invoke("monitor", CASE1_SPEC, trace),
        f"{trace}: cannot read the trace: not a regular file (a FIFO)",
    )
    world = fifo(tmp_path / "world.yaml")
    result = invoke("check", world)
    assert result.exit_code == 1 and "not a regular file (a FIFO)" in result.output
    assert len(result.output.splitlines()) == 1 and str(world) in result.output


def test_a_world_naming_a_fifo_spec_is_refused(
    tmp_path: Path, fifo: Callable[[Path], Path]
) -> None:
    fifo(tmp_path / "case1.mitl")
    shutil.copy(CASE1_WORLD, tmp_path / "case1.yaml")
    result = invoke("check", tmp_path / "case1.yaml")
    assert result.exit_code == 1 and "not a regular file (a FIFO)" in result.output


def test_sweep_files_and_results_that_are_fifos_are_refused(
    tmp_path: Path, fifo: Callable[[Path], Path]
) -> None:
    from mitlc.sweep.report import report
    from mitlc.sweep.spec import SweepError, load_sweep

    sweep = fifo(tmp_path / "sweep.yaml")
    with pytest.raises(SweepError, match="not a regular file"):
        within(lambda: load_sweep(sweep))
    (tmp_path / "out" / "trials" / "t0").mkdir(parents=True)
    result = fifo(tmp_path / "out" / "trials" / "t0" / "result.json")
    with pytest.raises(SweepError, match=f"^{result}: not a regular file"):
        within(lambda: report(tmp_path / "out"))


def test_standard_input_still_works() -> None:
    result = invoke("fmt", "-", stdin="F[0,5] a\n")
    assert result.exit_code == 0 and result.output == "F[0,5] a\n"


# --- the trace rule ----------------------------------------------------------------------------

UNKNOWN = "'zz' is not a proposition of the spec"


@pytest.mark.parametrize(
    ("name", "text", "message"),
    [
        ("t.jsonl", '["zz"]\n', f":1: {UNKNOWN} (its propositions: a, b)"),
        ("t.jsonl", '["a"]\n{"zz": false}\n', f":2: {UNKNOWN}"),
        ("t.csv", "a,b,zz\n1,0,0\n", f":1: {UNKNOWN}"),
        ("t.csv", "zz\n1\n", ": no column for the spec's proposition(s) a, b"),
        ("t.csv", "a,a,b\n1,0,0\n", ":1: the header names 'a' twice"),
        ("t.jsonl", '{"a": true, "a": false}\n', ":1: the step names 'a' twice"),
    ],
)
def test_both_trace_forms_follow_one_rule(
    tmp_path: Path, name: str, text: str, message: str
) -> None:
    trace = tmp_path / name
    trace.write_text(text, encoding="utf-8")
    result = invoke("monitor", CASE1_SPEC, trace)
    assert result.exit_code == 1
    assert result.output.startswith(f"{trace}{message}") and result.output.count("\n") == 1


def test_known_propositions_and_step_columns_still_read(tmp_path: Path) -> None:
    for name, text in (("t.csv", "Step,b,a\n0,0,1\n"), ("t.jsonl", '["a"]\n{"b": false}\n[]\n')):
        trace = tmp_path / name
        trace.write_text(text, encoding="utf-8")
        result = invoke("monitor", CASE1_SPEC, trace)
        assert result.exit_code == 0, result.output


# --- the shared reader -------------------------------------------------------------------------


def test_read_capped_takes_the_cap_and_refuses_one_byte_more(tmp_path: Path) -> None:
    path = tmp_path / "f"
    path.write_bytes(b"x" * 10)
    assert inputs.read_capped(path, 10, "a test file") == b"x" * 10
    with pytest.raises(inputs.FileTooLarge) as info:
        inputs.read_capped(path, 9, "a test file")
    assert info.value.strerror == "10 bytes, larger than the 9 bytes a test file may hold"
    assert isinstance(info.value, OSError) and info.value.filename == str(path)


def test_a_file_that_grows_while_read_is_cut_at_the_cap(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "f"
    path.write_bytes(b"line\n" * 4)
    monkeypatch.setattr("mitlc.inputs.regular_size", lambda _: 0)  # as if it was empty then
    with pytest.raises(inputs.FileTooLarge, match="grew past the 9 bytes a test file may hold"):
        inputs.read_capped(path, 9, "a test file")
    with pytest.raises(inputs.FileTooLarge, match="grew past"):
        list(inputs.read_lines_capped(path, 9, "a test file"))


def test_lines_are_read_with_and_without_their_newline(tmp_path: Path) -> None:
    path = tmp_path / "f"
    path.write_bytes(b"a\nb\nc")
    assert list(inputs.read_lines_capped(path, 5, "a test file")) == [b"a\n", b"b\n", b"c"]


def test_not_regular_files_are_refused_by_kind(tmp_path: Path) -> None:
    with pytest.raises(
        inputs.NotRegularFile, match=r"^\[Errno 21\] not a regular file \(a directory\)"
    ):
        inputs.read_capped(tmp_path, inputs.MAX_RECORD_BYTES, "a test file")
    if os.path.exists("/dev/null"):
        with pytest.raises(inputs.NotRegularFile, match="a character device"):
            inputs.read_capped("/dev/null", inputs.MAX_RECORD_BYTES, "a test file")
