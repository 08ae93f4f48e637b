"""The code blocks of the README and the site's pages, read and classified for
``tests/test_doc_examples.py`` (issue 45: examples that cannot rot).

Every fenced block of ``README.md`` and ``docs/**/*.md`` (not the generated ``docs/cli.md``, not
``docs/_build``) is one of:

* **run** -- a shell block (``sh``, ``bash``, ``console``, ``shell``; or a block without a
  language whose lines are ``$ `` prompts or ``mitlc`` commands) whose lines are ``mitlc ...`` /
  ``python -m mitlc ...`` commands (``echo TEXT | mitlc ...`` feeds standard input), run through
  the Typer app in a temporary copy of the shipped files; a ``python`` block, executed in a fresh
  namespace (a ``pycon`` block, or one of ``>>>`` lines, as a doctest);
* **compared** -- where a run block shows what it prints: the lines after a ``$ `` prompt (that
  command's), a ``# prints: TEXT`` comment (that line's), or a following ``text`` block marked
  ``<!-- output -->`` on the line before its fence (the whole block's). Pages show outputs
  trimmed, so the shown lines must appear in the output in their order, others between them
  (:func:`matches`); timings and the temporary folder are normalised;
* **validated** -- a ``yaml`` block that is a whole world file (``spec:`` and ``horizon:``) is read
  with :func:`mitlc.worlds.door.read_world`, one that is a whole sweep (``worlds:`` and
  ``learners:``) with :func:`mitlc.sweep.spec.load_sweep`;
* **not run** -- a block whose fence follows ``<!-- not run: REASON -->`` (on the line before it);
* **data** -- a block in a language of data (yaml, json, text, lark, csv, mitl, none, ...): not
  code, needs no marker; a MyST directive (``{toctree}``, ``{eval-rst}``) is no code block.

A block that is none of these (a shell block with another tool, a placeholder such as ``WORLD``
or ``[--episodes N]``, a language not listed) is a problem: the test names its file and line.

Training is run on a tiny budget: ``mitlc train`` gets ``--episodes``, ``sb3.steps`` and
``eval_episodes`` small enough for a second or two (:func:`tiny_budget`), ``mitlc eval`` a few
episodes; what such a block prints is then not compared. Under ``make verify`` (the ``slow``
marker) every block that trains and shows what it prints runs again with the budgets it shows,
and its output is compared. A block marked ``<!-- slow: REASON -->`` (a set-up of minutes) runs
only there.

``python -m tests.doc_blocks`` prints every block's class, page by page.
"""

from __future__ import annotations

import re
import shlex
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml
from markdown_it import MarkdownIt

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
GENERATED = {DOCS / "cli.md"}
"""Pages that the build writes (the CLI reference, from the Typer app)."""

SHELL = {"sh", "bash", "console", "shell", "shell-session", "zsh"}
PYTHON = {"python", "py", "python3"}
PYCON = {"pycon"}
DATA = {
    "", "yaml", "yml", "json", "jsonl", "json5", "text", "txt", "lark", "ebnf", "csv", "tsv",
    "mitl", "toml", "ini", "dot", "hoa", "output", "diff", "none", "plain",
}  # fmt: skip
"""Languages of data: their blocks are not code and need no marker."""

NOT_RUN = re.compile(r"^\s*<!--\s*not run:\s*(?P<reason>.*?)\s*-->\s*$")
SLOW = re.compile(r"^\s*<!--\s*slow:\s*(?P<reason>.*?)\s*-->\s*$")
OUTPUT = re.compile(r"^\s*<!--\s*output\s*-->\s*$")
ANY_MARKER = re.compile(r"^\s*<!--\s*(not run|slow|output)\b")

PROMPT = "$ "
BUDGETED = (("train",), ("eval",))
"""The commands whose output depends on their budget."""
MITLC = (("mitlc",), (".venv/bin/mitlc",), ("python", "-m", "mitlc"), ("python3", "-m", "mitlc"))
"""How a line of a shell block calls mitlc."""

PLACEHOLDER = re.compile(r"^(\[.*|.*\]|\.\.\.|[A-Z][A-Z0-9_]+(\.[a-z]+)?|<[^>]+>)$")
"""A word of a synopsis rather than a command: ``[--episodes N]``, ``...``, ``WORLD``,
``SWEEP.yaml``, ``<file>``."""

PRINTS = re.compile(r"#.*?\bprints:\s*(?P<text>.+?)\s*$")


@dataclass(frozen=True)
class Command:
    """One mitlc command of a shell block."""

    line: int
    """The line of the page it is on (1-based)."""
    text: str
    """As written, without the prompt and the comment."""
    argv: tuple[str, ...]
    """Its arguments after ``mitlc``."""
    stdin: str | None = None
    """What ``echo TEXT |`` feeds it."""
    expected: str | None = None
    """What the page shows it prints (after a prompt, or ``# prints:``), else None."""


@dataclass(frozen=True)
class Block:
    """A fenced code block of a page."""

    page: Path
    line: int
    """The line of its opening fence (1-based)."""
    info: str
    text: str
    marker: str | None = None
    """The reason of its ``<!-- not run: ... -->``."""
    slow: str | None = None
    """The reason of its ``<!-- slow: ... -->``."""
    output_of: Block | None = field(default=None, repr=False)
    """The run block whose output this (``<!-- output -->``) block shows."""
    output: str | None = None
    """The text of the ``<!-- output -->`` block that follows it."""

    @property
    def where(self) -> str:
        """``page:line``, the page relative to the repository."""
        return f"{self.page.relative_to(ROOT).as_posix()}:{self.line}"

    @property
    def language(self) -> str:
        """The fence's language, lower case (``{code-block} python``: python)."""
        words = self.info.split()
        if words and words[0] in ("{code-block}", "{code}", "{sourcecode}"):
            words = words[1:]
        return words[0].lower() if words else ""

    @property
    def directive(self) -> bool:
        """A MyST directive (``{toctree}``, ``{eval-rst}``), not a code block."""
        return self.info.startswith("{") and self.info.split()[0] not in (
            "{code-block}",
            "{code}",
            "{sourcecode}",
        )

    @property
    def kind(self) -> str:
        """``directive``, ``not run``, ``shell``, ``python``, ``pycon``, ``world``, ``sweep``,
        ``output``, ``data`` or ``unknown``."""
        if self.directive:
            return "directive"
        if self.marker is not None:
            return "not run"
        if self.output_of is not None:
            return "output"
        language = self.language
        if language in SHELL or (language == "" and _looks_like_commands(self.text)):
            return "shell"
        if language in PYTHON:
            return "pycon" if self.text.lstrip().startswith(">>>") else "python"
        if language in PYCON:
            return "pycon"
        if language in ("yaml", "yml"):
            return _yaml_kind(self.text)
        if language in DATA:
            return "data"
        return "unknown"

    def commands(self) -> list[Command]:
        """The block's mitlc commands; a :class:`NotRunnable` names the first line that is none
        (another tool, a placeholder, a pipe or redirection other than ``echo ... |``)."""
        lines = self.text.splitlines()
        transcript = any(line.startswith(PROMPT) for line in lines)
        found: list[Command] = []
        shown: list[list[str]] = []
        index = 0
        while index < len(lines):
            number = self.line + 1 + index
            raw = lines[index]
            index += 1
            if transcript and not raw.startswith(PROMPT):
                if shown:
                    shown[-1].append(raw)
                elif raw.strip():
                    raise NotRunnable(self, number, "output before the first '$ ' prompt")
                continue
            line = raw[len(PROMPT) :] if transcript else raw
            while line.rstrip().endswith("\\") and index < len(lines):
                line = line.rstrip()[:-1] + " " + lines[index].removeprefix("> ")
                index += 1
            if not line.strip() or line.lstrip().startswith("#"):
                continue
            found.append(_command(self, number, line))
            shown.append([])
        if transcript:
            found = [
                _with_expected(command, "\n".join(out).rstrip("\n") if any(out) else None)
                for command, out in zip(found, shown, strict=True)
            ]
        return found

    @property
    def budgeted(self) -> bool:
        """Whether the block trains or evaluates (``mitlc train``/``eval``): what that prints
        depends on the budget, so the fast run gives it a tiny one and compares nothing."""
        if self.kind != "shell":
            return False
        try:
            return any(command.argv[:1] in BUDGETED for command in self.commands())
        except NotRunnable:
            return False

    @property
    def shows_output(self) -> bool:
        """Whether the page shows what the block prints (an output block, a prompt's lines, a
        ``# prints:`` comment)."""
        if self.output is not None:
            return True
        if self.kind != "shell":
            return False
        try:
            return any(command.expected is not None for command in self.commands())
        except NotRunnable:
            return False


class NotRunnable(Exception):
    """A line of a shell block that the test cannot run."""

    def __init__(self, block: Block, line: int, why: str) -> None:
        where = f"{block.page.relative_to(ROOT).as_posix()}:{line}"
        super().__init__(
            f"{where}: {why}; run it with mitlc on shipped files, or mark the block with "
            f"<!-- not run: REASON --> on the line before its fence"
        )


def _with_expected(command: Command, expected: str | None) -> Command:
    if expected is None:
        return command
    return Command(command.line, command.text, command.argv, command.stdin, expected)


def _looks_like_commands(text: str) -> bool:
    """A block without a language that is a transcript (a first line ``$ ...``) or mitlc
    commands (every line starts with ``mitlc`` or ``python -m mitlc``)."""
    lines = [line for line in text.splitlines() if line.strip()]
    if not lines:
        return False
    if lines[0].startswith(PROMPT):
        return True
    return all(any(line.split()[: len(call)] == list(call) for call in MITLC) for line in lines)


def _yaml_kind(text: str) -> str:
    """``world`` for a whole world file, ``sweep`` for a whole sweep, else ``data``."""
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError:
        return "data"
    if isinstance(data, dict) and {"spec", "horizon"} <= data.keys():
        return "world"
    if isinstance(data, dict) and {"worlds", "learners"} <= data.keys():
        return "sweep"
    return "data"


def _command(block: Block, number: int, line: str) -> Command:
    """One line of a shell block as a mitlc command."""
    comment = PRINTS.search(line)
    try:
        words = shlex.split(line, comments=True)
    except ValueError as err:
        raise NotRunnable(block, number, f"cannot split the line ({err})") from None
    stdin = None
    if "|" in words:
        at = words.index("|")
        feed, words = words[:at], words[at + 1 :]
        if not feed or feed[0] != "echo" or "|" in words:
            raise NotRunnable(block, number, "a pipe other than 'echo TEXT | mitlc ...'")
        stdin = " ".join(feed[1:]) + "\n"
    for call in MITLC:
        if tuple(words[: len(call)]) == call:
            argv = tuple(words[len(call) :])
            break
    else:
        tool = words[0] if words else line.strip()
        raise NotRunnable(block, number, f"'{tool}' is not a mitlc command")
    for word in argv:
        if word in ("|", ">", ">>", "<", "&&", ";", "2>", "&"):
            raise NotRunnable(block, number, f"a shell operator {word!r}")
        if PLACEHOLDER.match(word):
            raise NotRunnable(block, number, f"a placeholder {word!r} (a synopsis)")
    expected = comment["text"] if comment else None
    return Command(number, line.strip(), argv, stdin, expected)


# -- the pages ---------------------------------------------------------------------------------


def pages() -> list[Path]:
    """README.md and every Markdown page of the site that is written by hand."""
    found = [ROOT / "README.md"]
    for path in sorted(DOCS.rglob("*.md")):
        if path.relative_to(DOCS).parts[0] == "_build" or path in GENERATED:
            continue
        found.append(path)
    return [path for path in found if path.exists()]


_PARSER = MarkdownIt("commonmark")


def blocks(page: Path) -> list[Block]:
    """The fenced code blocks of a page, with their markers, in order."""
    source = page.read_text(encoding="utf-8")
    lines = source.splitlines()
    found: list[Block] = []
    for token in _PARSER.parse(source):
        if token.type != "fence" or token.map is None:
            continue
        start = token.map[0]
        before = _line_before(lines, start)
        marker = NOT_RUN.match(before)
        slow = SLOW.match(before)
        block = Block(
            page=page,
            line=start + 1,
            info=token.info.strip(),
            text=token.content,
            marker=marker["reason"] if marker else None,
            slow=slow["reason"] if slow else None,
        )
        if OUTPUT.match(before):
            owner = next((b for b in reversed(found) if b.kind in ("shell", "python")), None)
            if owner is None:
                raise ValueError(f"{block.where}: <!-- output --> follows no shell or python block")
            index = found.index(owner)
            found[index] = _replace(owner, output=token.content)
            block = _replace(block, output_of=found[index])
        found.append(block)
    return found


def _replace(block: Block, **changes: Any) -> Block:
    values = {name: getattr(block, name) for name in Block.__dataclass_fields__}
    values.update(changes)
    return Block(**values)


def _line_before(lines: list[str], start: int) -> str:
    """The line just before a fence that opens at ``start`` (0-based), blank lines skipped."""
    index = start - 1
    while index >= 0 and not lines[index].strip():
        index -= 1
    return lines[index] if index >= 0 else ""


def stray_markers(page: Path) -> list[str]:
    """Markers (``<!-- not run: ... -->``, ``<!-- slow: ... -->``, ``<!-- output -->``) that no
    fence follows, as ``page:line: text``."""
    source = page.read_text(encoding="utf-8")
    lines = source.splitlines()
    starts = {
        token.map[0]
        for token in _PARSER.parse(source)
        if token.type == "fence" and token.map is not None
    }
    found = []
    for number, line in enumerate(lines):
        if not ANY_MARKER.match(line):
            continue
        following = number + 1
        while following < len(lines) and not lines[following].strip():
            following += 1
        if following not in starts:
            found.append(f"{page.relative_to(ROOT).as_posix()}:{number + 1}: {line.strip()}")
    return found


def all_blocks() -> list[Block]:
    """Every fenced block of every page."""
    return [block for page in pages() for block in blocks(page)]


# -- tiny budgets ------------------------------------------------------------------------------

TINY_EPISODES = 40
TINY_SB3_STEPS = 256
TINY_EVAL = 10
SB3_PREFIX = "sb3-"


def _drop_option(argv: list[str], name: str) -> list[str]:
    """``argv`` without ``name VALUE`` / ``name=VALUE``."""
    out: list[str] = []
    skip = False
    for word in argv:
        if skip:
            skip = False
            continue
        if word == name:
            skip = True
            continue
        if word.startswith(name + "="):
            continue
        out.append(word)
    return out


def _drop_settings(argv: list[str], keys: tuple[str, ...]) -> list[str]:
    """``argv`` without ``--set KEY=...`` for the given keys."""
    out: list[str] = []
    index = 0
    while index < len(argv):
        word = argv[index]
        if word == "--set" and index + 1 < len(argv):
            key = argv[index + 1].split("=", 1)[0]
            if key in keys:
                index += 2
                continue
        out.append(word)
        index += 1
    return out


def tiny_budget(argv: tuple[str, ...], resumes: int = 0) -> tuple[str, ...]:
    """A ``train`` or ``eval`` command on a budget of a second or two: ``train`` gets
    :data:`TINY_EPISODES` episodes (or :data:`TINY_SB3_STEPS` steps in 32-step rollouts and
    batches for an ``sb3-*`` learner; both where the world file picks the learner; each earlier
    run of the same ``--out`` doubles them, as ``--resume`` asks for more),
    :data:`TINY_EVAL` evaluation episodes and no progress bar; ``eval`` :data:`TINY_EVAL`
    episodes. Other commands are unchanged."""
    if not argv or argv[0] not in ("train", "eval"):
        return argv
    words = _drop_option(list(argv), "--episodes")
    scale = 2**resumes
    if argv[0] == "eval":
        return (*words, "--episodes", str(TINY_EVAL))
    words = _drop_settings(words, ("sb3.steps", "eval_episodes", "episodes"))
    algo = _option(argv, "--algo")
    settings = [f"eval_episodes={TINY_EVAL}"]
    if algo is None or algo.startswith(SB3_PREFIX):
        settings += [f"sb3.steps={TINY_SB3_STEPS * scale}", "sb3.n_steps=32", "sb3.batch_size=32"]
    if algo is None or not algo.startswith(SB3_PREFIX):
        words += ["--episodes", str(TINY_EPISODES * scale)]
    if "-q" not in words and "--quiet" not in words:
        words.append("-q")
    return (*words, *(arg for setting in settings for arg in ("--set", setting)))


def _option(argv: tuple[str, ...] | list[str], name: str) -> str | None:
    """The value of ``name VALUE`` or ``name=VALUE`` in ``argv``."""
    for index, word in enumerate(argv):
        if word == name and index + 1 < len(argv):
            return argv[index + 1]
        if word.startswith(name + "="):
            return word.split("=", 1)[1]
    return None


def out_dir(argv: tuple[str, ...]) -> str | None:
    """The ``--out`` of a train command, or its default ``runs/...`` (None: the world's own)."""
    return _option(argv, "--out")


# -- output ------------------------------------------------------------------------------------

_TIMING_LINE = re.compile(r"^\s*(seconds|elapsed|time)\s+[\d.]+\s*s?\s*$")
_SECONDS = re.compile(r"\b\d+(\.\d+)?\s?(s|ms|seconds)\b")


def normalise(text: str, folder: Path | None = None) -> list[str]:
    """Lines to compare: trailing spaces off, the temporary folder off, timing lines dropped
    and durations replaced by ``<t>``."""
    if folder is not None:
        text = text.replace(str(folder) + "/", "").replace(str(folder), ".")
    lines = []
    for line in text.rstrip("\n").splitlines():
        if _TIMING_LINE.match(line):
            continue
        lines.append(_SECONDS.sub("<t>", line.rstrip()))
    return lines


def matches(expected: list[str], actual: list[str]) -> bool:
    """Whether the lines ``expected`` appear in ``actual`` in this order, others between them
    (a page shows outputs trimmed; a line ``...`` says so and is skipped, a line ending in
    ``...`` stands for any line with that beginning)."""
    lines = iter(actual)
    for want in expected:
        if want.strip() == "...":
            continue
        if want.endswith("..."):
            head = want[:-3].rstrip()
            if not any(line.startswith(head) for line in lines):
                return False
        elif not any(line == want for line in lines):
            return False
    return True


# -- a summary ---------------------------------------------------------------------------------


def summary() -> dict[str, Counter[str]]:
    """Each page's blocks counted by class: ``run`` (shell and Python blocks that ``make test``
    runs), ``compared`` (of those, the ones whose shown output it compares), ``verify`` (blocks
    that ``make verify`` runs with their own budgets, comparing what they show), ``not run``,
    ``world``/``sweep`` (validated), ``output``, ``data``, ``problem``."""
    table: dict[str, Counter[str]] = {}
    for page in pages():
        counts: Counter[str] = Counter()
        for block in blocks(page):
            kind = block.kind
            if kind == "directive":
                continue
            if kind not in ("shell", "python", "pycon"):
                counts[kind] += 1
                continue
            if kind == "shell":
                try:
                    block.commands()
                except NotRunnable:
                    counts["problem"] += 1
                    continue
            if block.slow is None:
                counts["run"] += 1
                if (block.shows_output or kind == "pycon") and not block.budgeted:
                    counts["compared"] += 1
            if block.slow is not None or (block.budgeted and block.shows_output):
                counts["verify"] += 1
        table[page.relative_to(ROOT).as_posix()] = counts
    return table


def main() -> None:
    """Print each block's class, page by page, then the counts."""
    for block in all_blocks():
        if block.directive:
            continue
        why = block.marker or block.slow or ""
        problem = ""
        if block.kind == "shell":
            try:
                block.commands()
            except NotRunnable as err:
                problem = f"  PROBLEM {err}"
        print(f"{block.where:32} {block.language or '-':8} {block.kind:8} {why}{problem}")
    print()
    for page, counts in summary().items():
        print(f"{page:32} " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))


if __name__ == "__main__":
    main()
