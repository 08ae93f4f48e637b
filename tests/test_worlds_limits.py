"""The limits of world files (issue 11, part 3): deep YAML, alias bombs, huge numbers, the
horizon, tags and other odd YAML are refused with a :class:`WorldError` naming the file, line
and column; values just within a limit load."""

from __future__ import annotations

import os
import resource
from collections.abc import Iterator
from pathlib import Path

import pytest
from typer.testing import CliRunner

from mitlc.cli import app
from mitlc.limits import MAX_HORIZON, MAX_YAML_ALIASES, MAX_YAML_DEPTH
from mitlc.worlds import WorldError, load_world, read_world_file
from tests.conftest import ROOT

CASE1 = (
    (ROOT / "specs" / "paper" / "case1.yaml")
    .read_text(encoding="utf-8")
    .replace("spec: case1.mitl", "spec: {formula: '(!a U[5,10] a) & (!b U[15,20] b)'}")
)


def write(tmp_path: Path, text: str, name: str = "w.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def refused(path: Path, words: str, line: int | None = None) -> str:
    """The error of loading ``path``: it names the file (and ``line``) and says ``words``."""
    with pytest.raises(WorldError) as info:
        load_world(path)
    text = str(info.value)
    where = f"{path}:{line}:" if line is not None else f"{path}:"
    assert text.startswith(where) and words in text, text
    return text


@pytest.fixture
def memory_cap() -> Iterator[None]:
    """At most 2 GB of address space more than now, so that a limit that fails to refuse an
    exponential input fails the test instead of the machine."""
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    with open("/proc/self/statm") as statm:
        used = int(statm.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")
    resource.setrlimit(resource.RLIMIT_AS, (used + 2 * 2**30, hard))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))


def test_yaml_nested_10000_deep_is_refused(tmp_path: Path) -> None:
    path = write(tmp_path, CASE1 + "training: " + "[" * 10_000 + "]" * 10_000 + "\n")
    refused(path, f"nested more than {MAX_YAML_DEPTH} levels deep", CASE1.count("\n") + 1)
    block = "".join(" " * i + "k:\n" for i in range(1, 1_000))
    refused(write(tmp_path, CASE1 + "training:\n" + block), "nested more than")


def test_yaml_nested_just_within_the_limit_loads(tmp_path: Path) -> None:
    depth = MAX_YAML_DEPTH - 2  # the document and `training` are two levels
    path = write(tmp_path, CASE1 + "extra: " + "{k: " * depth + "1" + "}" * depth + "\n")
    refused(path, "unknown field")  # nested fine, then the unknown field
    path = write(
        tmp_path,
        CASE1.replace("training:", "t0:") + "training: " + "[" * depth + "]" * depth + "\n",
    )
    with pytest.raises(WorldError, match="unknown field"):
        read_world_file(path)


@pytest.mark.skipif(not Path("/proc/self/statm").exists(), reason="needs /proc")
def test_an_alias_bomb_is_refused_without_growing(tmp_path: Path, memory_cap: None) -> None:
    bomb = "lol0: &l0 [x, x, x, x, x, x, x, x, x, x]\n" + "".join(
        f"lol{i}: &l{i} [{', '.join([f'*l{i - 1}'] * 10)}]\n" for i in range(1, 9)
    )  # 10^9 values once expanded, from 80 aliases
    path = write(tmp_path, bomb + CASE1.replace("labels:", "labels:\n  c: *l8"))
    refused(path, "more than 1,000,000 values with aliases expanded", 6)  # at lol5


def test_too_many_aliases_and_recursive_aliases_are_refused(tmp_path: Path) -> None:
    many = "x: &a 1\ny: [" + ", ".join(["*a"] * (MAX_YAML_ALIASES + 1)) + "]\n"
    refused(write(tmp_path, many + CASE1), f"more than {MAX_YAML_ALIASES} aliases", 2)
    few = "x: &a 1\ny: [" + ", ".join(["*a"] * MAX_YAML_ALIASES) + "]\n"
    refused(write(tmp_path, few + CASE1), "unknown field")  # the aliases themselves are fine
    refused(write(tmp_path, CASE1 + "training: &t {x: [*t]}\n"), "an alias inside its own anchor")


@pytest.mark.parametrize(
    ("old", "new", "words"),
    [
        ("horizon: 30", "horizon: 1000000000", f"expected at most {MAX_HORIZON:,} steps"),
        ("horizon: 30", "horizon: " + "9" * 5000, "integer too long"),
        ("horizon: 30", "horizon: 0x" + "f" * 4000, "integer too long"),
        ("horizon: 30", "horizon: 9223372036854775808", "out of range"),
        ("horizon: 30", "horizon: 1.0e+309", "expected a positive integer, got Infinity"),
        ("horizon: 30", "horizon: true", "expected a positive integer, got true"),
        ("horizon: 30", "horizon: -5", "expected a positive integer, got -5"),
        ("horizon: 30", "horizon: !!int ''", "cannot read the int"),
        ("rows: 5", "rows: 4611686018427387904", "grid is too large"),
        ("rows: 5", "rows: .nan", "expected a positive integer, got NaN"),
        ("intended: 0.8", "intended: .nan", "expected a probability"),
        ("move: 0}", "move: .inf}", "expected a number, got Infinity"),
        ("move: 0}", "move: .NaN}", "expected a number, got NaN"),
        ("discount: 0.99", "discount: .inf", "expected a number in (0, 1]"),
        ("start: [4, 4]", "start: [-9223372036854775808, 4]", "is outside the 5x5 grid"),
        ("name: case1-5x5", "name: 2001-13-45", "cannot read the timestamp '2001-13-45'"),
        ("name: case1-5x5", "name: !!bool maybe", "cannot read the bool"),
        ("name: case1-5x5", "name: !!python/object/apply:os.getcwd []", "could not determine"),
        ("name: case1-5x5", "name: ../../elsewhere", "without / or \\ or a leading ."),
        ("name: case1-5x5", "name: /tmp/run", "without / or \\ or a leading ."),
        ("name: case1-5x5", 'name: "a\\x1b[2Jb"', "printable characters"),
    ],
)
def test_odd_values_are_refused_at_their_line(
    tmp_path: Path, old: str, new: str, words: str
) -> None:
    assert old in CASE1
    text = CASE1.replace(old, new)
    line = text[: text.index(new)].count("\n") + 1
    refused(write(tmp_path, text), words, line)


def test_the_horizon_limit_itself_is_accepted(tmp_path: Path) -> None:
    path = write(tmp_path, CASE1.replace("horizon: 30", f"horizon: {MAX_HORIZON}"))
    assert read_world_file(path).horizon == MAX_HORIZON


def test_python_tags_never_run(tmp_path: Path) -> None:
    marker = tmp_path / "ran"
    text = f"!!python/object/apply:os.mkdir ['{marker}']\n"
    refused(write(tmp_path, text), "could not determine a constructor", 1)
    assert not marker.exists()


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("- 1\n- 2\n", "expected a mapping of the world's fields, got [1, 2]"),
        ("42\n", "expected a mapping of the world's fields, got 42"),
        ("", "got an empty file"),
        ("# nothing\n", "got an empty file"),
        ("\ufeff" + "grid: 1\n" * 2, "duplicate key 'grid'"),
        ("a: 1\r\nb: 2\r\n", "unknown field"),
        (
            "a: 1\nb: [\t1]\n",
            "2:5: invalid YAML: found character '\\t' that cannot start any token",
        ),
        ("grid: {rows: 2, cols: 2}\n" + "\x00", "the character U+0000 is not allowed"),
    ],
)
def test_odd_documents_are_refused(tmp_path: Path, text: str, words: str) -> None:
    refused(write(tmp_path, text), words)


def test_non_utf8_world_names_the_byte(tmp_path: Path) -> None:
    path = tmp_path / "w.yaml"
    path.write_bytes(b"\xef\xbb\xbfname: caf\xe9\n")
    refused(path, "1:10: invalid UTF-8: byte 0xe9")


def test_a_world_file_too_large_is_refused(tmp_path: Path) -> None:
    path = write(tmp_path, CASE1 + "#" * 2_000_000 + "\n")
    refused(path, "the world file is too large: more than 1,000,000 bytes")


@pytest.mark.parametrize("spec", ["binary.mitl", "deep.mitl", "/dev/zero", "missing.mitl", "."])
def test_spec_files_named_by_a_world_are_read_safely(tmp_path: Path, spec: str) -> None:
    (tmp_path / "binary.mitl").write_bytes(bytes(range(256)))
    (tmp_path / "deep.mitl").write_text("!" * 500 + "a", encoding="utf-8")
    text = CASE1.replace("spec: {formula: '(!a U[5,10] a) & (!b U[15,20] b)'}", f"spec: {spec}")
    message = refused(write(tmp_path, text), "spec: ", 28)
    assert "Traceback" not in message


def test_the_command_line_reports_world_errors(tmp_path: Path) -> None:
    path = write(tmp_path, CASE1.replace("horizon: 30", "horizon: 1000000000"))
    for args in (["check", str(path)], ["train", str(path), "--episodes", "1"]):
        result = CliRunner().invoke(app, args)
        assert result.exit_code == 1, result.output
        assert result.output.startswith(f"{path}:30:10: horizon: expected at most 10,000 steps")
