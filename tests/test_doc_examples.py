"""Every code block of the README and the site is run, validated, data, or marked not run with
a reason (issue 45 item 3; the classes are in ``tests/doc_blocks.py``).

Shell blocks run through the Typer app in a temporary copy of the shipped files (``specs/``,
``tests/worlds/``, ``examples/``), training on a tiny budget, and what a block shows it prints is
compared where it does not depend on the budget; Python blocks are executed in a fresh namespace
(``>>>`` blocks as doctests); whole world files and sweeps shown in YAML are read and validated.
Blocks marked ``<!-- slow: ... -->`` run only under ``make verify`` (the ``slow`` marker), with
the budgets they show. ``python -m tests.doc_blocks`` lists every block's class.
"""

from __future__ import annotations

import contextlib
import doctest
import io
import re
import shutil
import textwrap
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from tests import doc_blocks
from tests.doc_blocks import (
    BUDGETED,
    ROOT,
    Block,
    NotRunnable,
    all_blocks,
    blocks,
    matches,
    normalise,
    out_dir,
    pages,
    stray_markers,
    tiny_budget,
)

ALREADY_THERE = re.compile(r"^(?P<dir>\S+): a run is already there", re.M)

SHIPPED = ("specs", "tests/worlds", "examples")
"""What a block's commands may read, copied into its temporary folder."""

BLOCKS = all_blocks()
RUNNABLE = [block for block in BLOCKS if block.kind in ("shell", "python", "pycon")]
RUN = [block for block in RUNNABLE if block.slow is None]
SLOW = [
    block for block in RUNNABLE if block.slow is not None or (block.budgeted and block.shows_output)
]
VALIDATED = [block for block in BLOCKS if block.kind in ("world", "sweep")]


def _id(block: Block) -> str:
    return block.where


def test_every_block_is_run_or_marked() -> None:
    problems: list[str] = []
    for page in pages():
        problems += [f"{stray}: no code block follows the marker" for stray in stray_markers(page)]
    for block in BLOCKS:
        if block.kind == "unknown":
            problems.append(
                f"{block.where}: a ```{block.language} block is neither run nor data; mark it "
                f"<!-- not run: REASON --> on the line before its fence"
            )
        elif block.kind == "shell":
            try:
                block.commands()
            except NotRunnable as err:
                problems.append(str(err))
        if block.marker is not None and not block.marker:
            problems.append(f"{block.where}: <!-- not run: --> without a reason")
        if block.slow is not None and block.kind not in ("shell", "python", "pycon"):
            problems.append(f"{block.where}: <!-- slow: ... --> on a block that is not run")
    assert not problems, "\n".join(problems)


def _workspace(tmp_path: Path) -> Path:
    """A temporary folder with copies of the shipped files, as a clone's root has them."""
    for name in SHIPPED:
        source = ROOT / name
        if source.is_dir():
            shutil.copytree(source, tmp_path / name)
    return tmp_path


def _run_shell(block: Block, folder: Path, *, full: bool) -> None:
    """Run a shell block's commands in ``folder``; compare what they print where the page shows
    it, unless they ran on a tiny budget."""
    from mitlc.cli import app

    runner = CliRunner()
    runs: dict[str | None, int] = {}
    printed: list[str] = []
    budgeted = False
    for command in block.commands():
        argv = command.argv
        if argv[:1] == ("train",):
            key = out_dir(argv)
            resumes = runs.get(key, 0)
            runs[key] = resumes + 1
        else:
            resumes = 0
        tiny = not full and argv[:1] in BUDGETED
        if tiny:
            argv = tiny_budget(argv, resumes)
            budgeted = True
        result = runner.invoke(app, list(argv), input=command.stdin)
        taken = ALREADY_THERE.search(result.output) if argv[:1] == ("train",) else None
        if (
            taken
            and "--resume" not in argv
            and (folder / taken["dir"]).resolve().is_relative_to(folder.resolve())
        ):
            # Lines that train into the same directory are alternatives ("or ..."): the later
            # one replaces the earlier run, as it would after `rm -r DIR`.
            shutil.rmtree(folder / taken["dir"])
            result = runner.invoke(app, list(argv), input=command.stdin)
        shown = f"{block.page.name}:{command.line}: $ mitlc {' '.join(argv)}\n{result.output}"
        if result.exception is not None and not isinstance(result.exception, SystemExit):
            raise AssertionError(shown) from result.exception
        printed.append(result.output)
        if command.expected is None or tiny:
            assert result.exit_code == 0, shown
        else:
            _compare(
                f"line {command.line}: `{command.text}`", command.expected, result.output, folder
            )
    if block.output is not None and not budgeted:
        _compare(f"{block.where}", block.output, "".join(printed), folder)


def _compare(what: str, shown: str, output: str, folder: Path | None) -> None:
    expected = normalise(shown)
    actual = normalise(output, folder)
    assert matches(expected, actual), (
        f"{what} prints\n"
        + textwrap.indent("\n".join(actual), "    ")
        + "\nwhere the page shows\n"
        + textwrap.indent("\n".join(expected), "    ")
    )


def _close(namespace: dict[str, Any]) -> None:
    """Close the envs a Python block made (vector envs hold worker processes)."""
    for value in namespace.values():
        module = type(value).__module__
        if module.startswith(("gymnasium", "mitlc", "pettingzoo", "mpe2")):
            close = getattr(value, "close", None)
            if callable(close):
                with contextlib.suppress(Exception):
                    close()


def _run_python(block: Block) -> None:
    namespace: dict[str, Any] = {"__name__": "__doc_example__"}
    printed = io.StringIO()
    code = compile(block.text, block.where, "exec")
    try:
        with contextlib.redirect_stdout(printed):
            exec(code, namespace)
    finally:
        _close(namespace)
    if block.output is not None:
        _compare(block.where, block.output, printed.getvalue(), None)


def _run_doctest(block: Block) -> None:
    parser = doctest.DocTestParser()
    test = parser.get_doctest(block.text, {}, block.where, str(block.page), block.line)
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    report: list[str] = []
    runner.run(test, out=report.append)
    assert runner.failures == 0, "".join(report)


def _run(block: Block, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, *, full: bool) -> None:
    folder = _workspace(tmp_path)
    monkeypatch.chdir(folder)
    if block.kind == "shell":
        try:
            _run_shell(block, folder, full=full)
        except NotRunnable as err:
            pytest.fail(str(err), pytrace=False)
    elif block.kind == "python":
        _run_python(block)
    else:
        _run_doctest(block)


@pytest.mark.parametrize("block", RUN, ids=_id)
def test_block_runs(block: Block, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    _run(block, tmp_path, monkeypatch, full=False)


@pytest.mark.slow
@pytest.mark.parametrize("block", SLOW, ids=_id)
def test_block_runs_with_its_budget(
    block: Block, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    _run(block, tmp_path, monkeypatch, full=True)


@pytest.mark.parametrize("block", VALIDATED, ids=_id)
def test_yaml_file_is_valid(block: Block, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    folder = _workspace(tmp_path)
    monkeypatch.chdir(folder)
    shown = folder / "shown"
    shown.mkdir()
    path = shown / f"{block.kind}.yaml"
    path.write_text(block.text, encoding="utf-8")
    if block.kind == "world":
        from mitlc.worlds.door import read_world

        read_world(path)
    else:
        from mitlc.sweep.spec import load_sweep

        load_sweep(path)


# -- the reader itself -------------------------------------------------------------------------

PAGE = """\
# A page

```sh
mitlc fmt -e 'F[0,5] a'   # prints: F[0,5] a
echo 'a U b' | python -m mitlc fmt -
```

<!-- not run: trains for hours -->
```sh
mitlc train WORLD --episodes 1000000
```

```
$ mitlc fmt -e 'a &'
error
  at a
$ mitlc fmt -e 'b'
```

```sh
make test
```

<!-- output -->
```text
b
```

```yaml
name: w
spec: {formula: F a}
horizon: 3
```

```{toctree}
a
```

```rust
fn main() {}
```
"""


def test_reader_classifies_a_page(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(doc_blocks, "ROOT", tmp_path)
    page = tmp_path / "page.md"
    page.write_text(PAGE, encoding="utf-8")
    found = blocks(page)
    kinds = [block.kind for block in found]
    assert kinds == [
        "shell", "not run", "shell", "shell", "output", "world", "directive", "unknown"
    ]  # fmt: skip
    assert found[1].marker == "trains for hours"
    first = found[0].commands()
    assert [c.argv for c in first] == [("fmt", "-e", "F[0,5] a"), ("fmt", "-")]
    assert first[0].expected == "F[0,5] a" and first[1].stdin == "a U b\n"
    transcript = found[2].commands()
    assert [c.expected for c in transcript] == ["error\n  at a", None]
    assert found[2].line == 13 and transcript[1].line == 17
    with pytest.raises(NotRunnable, match=r"page.md:21: 'make' is not a mitlc command"):
        found[3].commands()
    assert found[3].output == "b\n" and found[4].output_of is not None
    assert stray_markers(page) == []
    page.write_text("<!-- not run: x -->\n\ntext\n", encoding="utf-8")
    assert stray_markers(page) == ["page.md:1: <!-- not run: x -->"]


@pytest.mark.parametrize(
    "line",
    ["mitlc train WORLD", "mitlc eval RUN [--json]", "mitlc sweep SWEEP.yaml", "mitlc x ..."],
)
def test_placeholders_are_not_run(
    line: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(doc_blocks, "ROOT", tmp_path)
    page = tmp_path / "p.md"
    page.write_text(f"```sh\n{line}\n```\n", encoding="utf-8")
    with pytest.raises(NotRunnable, match="placeholder"):
        blocks(page)[0].commands()


def test_tiny_budget() -> None:
    argv = ("train", "w.yaml", "--episodes", "300000", "--set", "q.alpha=0.3")
    assert tiny_budget(argv) == (
        "train", "w.yaml", "--set", "q.alpha=0.3", "--episodes", "40", "-q",
        "--set", "eval_episodes=10", "--set", "sb3.steps=256", "--set", "sb3.n_steps=32",
        "--set", "sb3.batch_size=32",
    )  # fmt: skip
    ppo = ("train", "w.yaml", "--algo", "sb3-ppo", "--set", "sb3.steps=20000", "--out", "r")
    assert tiny_budget(ppo, resumes=1) == (
        "train", "w.yaml", "--algo", "sb3-ppo", "--out", "r", "-q",
        "--set", "eval_episodes=10", "--set", "sb3.steps=512", "--set", "sb3.n_steps=32",
        "--set", "sb3.batch_size=32",
    )  # fmt: skip
    assert tiny_budget(("eval", "r", "--episodes", "10000")) == ("eval", "r", "--episodes", "10")
    assert tiny_budget(("check", "w.yaml")) == ("check", "w.yaml")


def test_output_matching() -> None:
    assert matches(["a", "...", "d"], ["a", "b", "c", "d"])
    assert matches(["a", "..."], ["a"])
    assert matches(["a", "d"], ["a", "b", "d"]), "trimmed"
    assert not matches(["d", "a"], ["a", "b", "d"]), "in order"
    assert not matches(["a", "a"], ["a", "b"]), "each line once"
    assert not matches(["a", "e"], ["a", "b", "d"])
    assert matches(["world  x..."], ["world  xyz"])
    assert not matches(["world  y..."], ["world  xyz"])
    folder = Path("/tmp/abc")
    assert normalise("seconds   0.0194\nran in 3.5 s\n/tmp/abc/runs/x\n", folder) == [
        "ran in <t>",
        "runs/x",
    ]
