"""Seeded fuzzing of everything that reads a user's file: the spec parser (random strings over
the grammar's alphabet, mutated real specs), the world loader (the repository's worlds mutated:
bytes flipped, lines deleted or doubled, values replaced with huge, negative, non-finite or
odd ones, deep nesting, aliases) and the trace reader (mutated CSV and JSON Lines traces), and a
sample of each through the command line. Every input may be accepted or refused with one of
mitlc's own errors (:class:`~mitlc.errors.MitlcError`); any other exception fails the test."""

from __future__ import annotations

import random
import re
import shutil
from collections.abc import Callable
from functools import partial
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from mitlc.automata import compile_formula
from mitlc.cli import app
from mitlc.errors import MitlcError
from mitlc.syntax import parse, parse_bytes, to_text
from mitlc.traces import read_trace, trace_columns
from mitlc.worlds import load_world
from tests.conftest import ROOT

SPECS = sorted(ROOT.glob("specs/**/*.mitl")) + sorted((ROOT / "tests" / "golden").glob("*/*.mitl"))
WORLDS = sorted((ROOT / "specs" / "paper").glob("*.yaml")) + sorted(
    (ROOT / "tests" / "worlds").glob("*.yaml")
)
TOKENS = [
    *"abpxX FGUR!&|()[],:_#~01239-\n\t",
    "true", "false", "inf", "..", "->", "<->", "&&", "||", "/\\", "\\/", "F[", "G_[", "U[",
    "[0,inf)", "(2,5]", "[1..3]", " ", " ", "a1", "room_2", "¬", "∧", "∨", "→", "↔", "○", "◇",
    "□", "∞", "⊤", "\x00", "\r", "\ufeff", "\u2028", "\udcff", "9" * 12, "9" * 5000,
    "!" * 150, "(" * 150, ")" * 150, "X " * 150, "a U " * 150, "a & " * 150,
]  # fmt: skip
ODD_VALUES = [
    "-1", "0", "2", "-9223372036854775809", "9223372036854775808", "9" * 40, "1e309", "-1e309",
    ".nan", ".inf", "true", "null", "''", "[]", "{}", "[[0, 0]]", "0x" + "f" * 20, "1:2:3",
    "2001-13-45", "!!int abc", "!!python/object:os.system {}", "*nowhere", "&x [*x]", "~",
    "[" * 80 + "]" * 80, "{a: " * 70 + "1" + "}" * 70, "\"\\x00\"", "!!binary '%%'",
    "[" + ", ".join(["[1, 2]"] * 200) + "]",
]  # fmt: skip
"""What a value replacement puts in a world file in place of a value."""
ALIAS_BOMB = "lol0: &l0 [x, x, x, x, x, x, x, x, x, x]\n" + "".join(
    f"lol{i}: &l{i} [{', '.join([f'*l{i - 1}'] * 10)}]\n" for i in range(1, 7)
)


def accept_only_mitlc_errors(run: Callable[[], object], what: object) -> None:
    """Run ``run``: it may return or raise a MitlcError, nothing else."""
    try:
        run()
    except MitlcError:
        pass
    except Exception as err:  # the point of the test: name the input that broke through
        raise AssertionError(f"{type(err).__name__}: {err} on {what!r:.300}") from err


def mutate_bytes(data: bytes, rng: random.Random) -> bytes:
    """One to four random byte-level edits: flip, delete, insert, duplicate or cut."""
    out = bytearray(data)
    for _ in range(rng.randint(1, 4)):
        where = rng.randrange(len(out) + 1)
        kind = rng.randrange(6)
        if kind == 0 and out:
            out[min(where, len(out) - 1)] ^= 1 << rng.randrange(8)
        elif kind == 1:
            del out[where : where + rng.randint(1, 8)]
        elif kind == 2:
            out[where:where] = rng.choice(
                [b"\xff", b"\x00", b"\xc3", b"\r", b"\t", b"\xef\xbb\xbf"]
            )
        elif kind == 3:
            chunk = out[where : where + rng.randint(1, 16)]
            out[where:where] = chunk * rng.randint(2, 60)
        elif kind == 4:
            del out[where:]
        else:
            out[where:where] = rng.choice(TOKENS).encode("utf-8", "surrogatepass")
    return bytes(out)


def mutate_yaml(text: str, rng: random.Random) -> str:
    """A YAML-aware edit: a value replaced, a line deleted or doubled, an alias bomb or deep
    nesting added; else byte-level edits."""
    lines = text.split("\n")
    kind = rng.randrange(6)
    if kind <= 1:
        values = [i for i, line in enumerate(lines) if re.search(r":\s*\S", line)]
        if values:
            i = rng.choice(values)
            key, _, _ = lines[i].partition(":")
            lines[i] = f"{key}: {rng.choice(ODD_VALUES)}"
        else:
            numbers = list(re.finditer(r"-?\d+(\.\d+)?", text))
            if numbers:
                m = rng.choice(numbers)
                return text[: m.start()] + rng.choice(ODD_VALUES) + text[m.end() :]
    elif kind == 2 and lines:
        del lines[rng.randrange(len(lines))]
    elif kind == 3 and lines:
        i = rng.randrange(len(lines))
        lines.insert(i, lines[i])
    elif kind == 4:
        extra = rng.choice([ALIAS_BOMB, "deep:\n  " + "- " * 500 + "x", "x: &a {b: *a}"])
        lines.insert(rng.randrange(len(lines) + 1) if rng.random() < 0.3 else 0, extra)
    else:
        return mutate_bytes(text.encode("utf-8", "surrogateescape"), rng).decode(
            "utf-8", "surrogateescape"
        )
    return "\n".join(lines)


# --- specs --------------------------------------------------------------------------------


@settings(
    derandomize=True,
    max_examples=400,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
@given(st.lists(st.sampled_from(TOKENS), max_size=30).map("".join) | st.text(max_size=40))
def test_random_spec_text_parses_or_is_refused(text: str) -> None:
    def run() -> None:
        formula = parse(text, "<fuzz>")
        assert parse(to_text(formula)) == formula
        if len(text) < 40:
            compile_formula(formula, max_states=200)

    accept_only_mitlc_errors(run, text)


def test_mutated_specs_parse_or_are_refused() -> None:
    rng = random.Random(11)
    sources = [p.read_bytes() for p in SPECS]
    sources += [line.encode() for line in (ROOT / "bench" / "formulas.txt").read_text().split("\n")]
    for _ in range(1500):
        data = mutate_bytes(rng.choice(sources), rng)
        accept_only_mitlc_errors(partial(parse_bytes, data, "<fuzz>"), data)


# --- worlds -------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def world_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A directory with the specs the worlds name, so that mutated worlds find them."""
    directory = tmp_path_factory.mktemp("worlds")
    for spec in [
        *(ROOT / "specs" / "paper").glob("*.mitl"),
        *(ROOT / "tests" / "worlds").glob("*.mitl"),
    ]:
        shutil.copy(spec, directory / spec.name)
    return directory


def test_mutated_worlds_load_or_are_refused(world_dir: Path) -> None:
    rng = random.Random(5)
    sources = [p.read_bytes().decode("utf-8", "surrogateescape") for p in WORLDS]
    path = world_dir / "fuzz.yaml"
    for i in range(800):
        text = rng.choice(sources)
        for _ in range(rng.randint(1, 3)):
            text = mutate_yaml(text, rng)
        path.write_bytes(text.encode("utf-8", "surrogateescape"))
        accept_only_mitlc_errors(lambda: load_world(path), (i, text))


# --- traces -------------------------------------------------------------------------------


def sample_trace(rng: random.Random, jsonl: bool) -> str:
    steps = [rng.sample(["a", "b", "printer"], rng.randint(0, 3)) for _ in range(rng.randint(0, 8))]
    if jsonl:
        return "".join(
            (str(sorted(s)).replace("'", '"') if rng.random() < 0.5 else
             "{" + ", ".join(f'"{p}": {str(p in s).lower()}' for p in ("a", "b")) + "}") + "\n"
            for s in steps
        )  # fmt: skip
    return "step,a,b\n" + "".join(
        f"{t},{int('a' in s)},{int('b' in s)}\n" for t, s in enumerate(steps)
    )


def test_mutated_traces_read_or_are_refused(tmp_path: Path) -> None:
    rng = random.Random(3)
    odd = ["[" * 3000, "9" * 5000, "1e999", "NaN", '"\\ud800"', '{"a": 1}', "\x00", '"', ",,,"]
    for i in range(2000):
        jsonl = i % 2 == 0
        data = mutate_bytes(sample_trace(rng, jsonl).encode(), rng)
        if rng.random() < 0.3:
            text = data.decode("utf-8", "replace")
            where = rng.randrange(len(text) + 1)
            data = (text[:where] + rng.choice(odd) + text[where:]).encode()
        path = tmp_path / f"trace{i % 2}.{'jsonl' if jsonl else 'csv'}"
        path.write_bytes(data)

        def run(path: Path = path, data: bytes = data) -> None:
            trace_columns(path, data.decode("utf-8", "replace"))
            read_trace(path)

        accept_only_mitlc_errors(run, data)


# --- the command line ----------------------------------------------------------------------


def test_command_line_never_shows_a_traceback(tmp_path: Path, world_dir: Path) -> None:
    rng = random.Random(8)
    runner = CliRunner()
    spec = tmp_path / "fuzz.mitl"
    trace = tmp_path / "fuzz.jsonl"
    world = world_dir / "cli.yaml"
    sources = [p.read_bytes() for p in SPECS]
    worlds = [p.read_bytes().decode("utf-8", "surrogateescape") for p in WORLDS[:4]]
    for i in range(40):
        spec.write_bytes(mutate_bytes(rng.choice(sources), rng))
        trace.write_bytes(mutate_bytes(sample_trace(rng, True).encode(), rng))
        world.write_bytes(mutate_yaml(rng.choice(worlds), rng).encode("utf-8", "surrogateescape"))
        commands = [
            ["fmt", str(spec)],
            ["parse", "--json", str(spec)],
            ["monitor", "-", str(trace), "--max-states", "2000"]
            if i % 2
            else ["compile", "--batch", str(spec), "--max-states", "2000"],
        ]
        if i % 4 == 0:
            commands.append(["check", str(world), "--no-pomdp-bounds", "--max-states", "2000"])
        for args in commands:
            result = runner.invoke(app, args, input=spec.read_bytes())
            assert result.exit_code in (0, 1), (args, result.output)
            assert result.exception is None or isinstance(result.exception, SystemExit), (
                args,
                repr(result.exception),
            )
            assert "Traceback" not in result.output
