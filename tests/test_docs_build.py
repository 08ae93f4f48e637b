"""The documentation site's structure, checked without building it (``make docs`` builds it).

Every page under ``docs/`` is reachable from the home page's toctrees, every toctree entry is a
page, and the CLI reference (``docs/_ext/cli_reference.py``) lists every command of the Typer
app with every visible parameter. A few milliseconds each, apart from importing the CLI.
"""

from __future__ import annotations

import importlib.util
import re
import sys
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"

_TOCTREE = re.compile(r"^(`{3,}|:{3,})\{toctree\}[^\n]*\n(.*?)^\1\s*$", re.S | re.M)
_ENTRY = re.compile(r"^(?:.*<(?P<target>[^>]+)>|(?P<plain>\S+))$")


def _extension(name: str) -> ModuleType:
    """A module of ``docs/_ext`` by file (docs/ is no package)."""
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, DOCS / "_ext" / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def _generated() -> set[str]:
    """The pages that the build writes (git-ignored), as docnames."""
    return {_extension("cli_reference").PAGE.removesuffix(".md")}


def _pages() -> set[str]:
    """Every Markdown page under docs/ that the build reads, as docnames (``api/index``)."""
    found = set()
    for path in DOCS.rglob("*.md"):
        relative = path.relative_to(DOCS)
        if relative.parts[0] == "_build":
            continue
        found.add(relative.with_suffix("").as_posix())
    return found - _generated()


def toctree_entries(docname: str) -> list[str]:
    """The docnames that ``docname``'s toctrees list, resolved against its folder."""
    text = (DOCS / f"{docname}.md").read_text(encoding="utf-8")
    folder = Path(docname).parent
    entries = []
    for _, body in _TOCTREE.findall(text):
        for line in body.splitlines():
            line = line.strip()
            if not line or line.startswith(":"):
                continue
            match = _ENTRY.match(line)
            assert match, f"{docname}: toctree entry {line!r}"
            target = (match["target"] or match["plain"]).removesuffix(".md")
            if target.startswith("/"):
                entries.append(target.lstrip("/"))
            else:
                entries.append((folder / target).as_posix())
    return entries


def reachable(root: str = "index") -> set[str]:
    """The pages reached from ``root`` through toctrees (generated ones end the walk)."""
    seen = {root}
    todo = [root]
    while todo:
        docname = todo.pop()
        for entry in toctree_entries(docname):
            if entry not in seen:
                seen.add(entry)
                if entry not in _generated():
                    todo.append(entry)
    return seen


def test_every_page_is_in_a_toctree() -> None:
    pages = _pages()
    found = reachable()
    assert pages - found == set(), "pages no toctree reaches"
    assert found - pages - _generated() == set(), "toctree entries that are no page"
    assert _generated() <= found, "the generated pages are listed too"


def test_toctree_parsing() -> None:
    assert "api/syntax" in toctree_entries("api/index")
    assert {"cli", "api/index", "changelog", "envs"} <= set(toctree_entries("index"))


def _app_commands(command: Any, path: tuple[str, ...] = ()) -> dict[tuple[str, ...], Any]:
    """The Click tree of the Typer app, walked through its ``commands`` mappings."""
    found = {path: command}
    for name, sub in getattr(command, "commands", {}).items():
        if not sub.hidden:
            found.update(_app_commands(sub, (*path, name)))
    return found


def test_cli_reference_lists_every_command() -> None:
    import typer

    from mitlc.cli import app

    reference = _extension("cli_reference")
    commands = reference.command_tree()
    tree = _app_commands(typer.main.get_command(app))
    assert [command.path for command in commands] == list(tree)
    assert {"check", "train", "eval", "plot", "sweep", "report"} <= {p[0] for p in tree if p}
    page = reference.render(commands)
    for command in commands:
        assert f"({reference.anchor(command)})=" in page
        assert f"`{command.name}`" in page
        assert command.usage in page
        options = {
            opt for param in tree[command.path].params if not param.hidden for opt in param.opts
        }
        shown = {
            word.strip(",")
            for parameter in command.parameters
            for word in parameter.declaration.split()
        }
        missing = {opt for opt in options if opt.startswith("-") and opt not in shown}
        assert missing <= {"--help"}, f"{command.name}: {missing}"
    assert reference.render(reference.command_tree()) == page, "the page is deterministic"


def test_cli_reference_text_reads_back() -> None:
    """The escaped help texts render to themselves (nothing read as Markdown)."""
    markdown_it = pytest.importorskip("markdown_it")
    reference = _extension("cli_reference")
    tricky = "a *b* _c_ `d` [e](f) <g> | h $x$ {i}`j` & k \\ l 1. m"
    for text in (tricky, "- a list?", "# a heading?", "3) item?", "12. item", "+ plus", ": x"):
        tokens = markdown_it.MarkdownIt("commonmark").parse(reference.escape(text))
        inline = [t for t in tokens if t.type == "inline"]
        assert len(inline) == 1 and [c.type for c in inline[0].children] == ["text"], text
        assert inline[0].children[0].content == text


def test_existing_refs_checks_existence() -> None:
    refs = _extension("existing_refs")
    assert refs.exists("numpy.ndarray")
    assert refs.exists("mitlc.learn.rundir.files.RunError")
    assert not refs.exists("mitlc.learn.rundir.files.NoSuchError")
    assert not refs.exists("The explicit view")
    # a docstring's short name, read where the docstring is written (under TYPE_CHECKING too)
    context = ["mitlc.worlds.World"]
    assert any(refs.exists(c) for c in refs.candidates("IntArray", context))
    assert any(refs.exists(c) for c in refs.candidates("GridMap", context))
    assert not any(refs.exists(c) for c in refs.candidates("NoSuchName", context))
