"""Nitpicky cross-references that check existence where there is no page to link to.

The site builds with ``-n``: every Python cross-reference (a docstring's ``:class:``, ``:func:``,
``:mod:`` role, a signature's type) must resolve. Many name things that exist but have no page:
numpy's and gymnasium's types (the site reaches no network, so there is no intersphinx), and
mitlc's own modules below the documented packages. For those, this hook keeps the reference as
plain code text, without a link, on one condition: the name exists now, as written or as the
module it is written in would read it (its globals, and its imports, those for type checkers
included), where that module is the one of the documented object or of the docstring. A name
that exists nowhere (a typo, a renamed function, a removed module) still fails the build.
"""

from __future__ import annotations

import ast
import builtins
import importlib
import types
from functools import cache
from pathlib import Path
from typing import Any

_MISSING = object()


@cache
def _module(name: str) -> Any:
    try:
        return importlib.import_module(name)
    except Exception:  # any failure to import means "not this module"
        return None


@cache
def exists(path: str) -> bool:
    """Whether the dotted ``path`` names a builtin, a module, or an attribute reached from one."""
    return hasattr(builtins, path) or _resolve(path) is not _MISSING


def _resolve(path: str) -> Any:
    """The object that the dotted ``path`` names, or ``_MISSING``."""
    parts = path.split(".")
    if not all(part.isidentifier() for part in parts):
        return _MISSING
    for cut in range(len(parts), 0, -1):
        owner = _module(".".join(parts[:cut]))
        if owner is None:
            continue
        for attribute in parts[cut:]:
            owner = getattr(owner, attribute, _MISSING)
            if owner is _MISSING:
                return _MISSING
        return owner
    return _MISSING


@cache
def imported_names(module: str) -> dict[str, str]:
    """Every name that ``module``'s source binds by an import, anywhere in the file (under
    ``if TYPE_CHECKING:`` too), and the dotted path it stands for."""
    found = _module(module)
    filename = getattr(found, "__file__", None)
    if not filename or not filename.endswith(".py"):
        return {}
    tree = ast.parse(Path(filename).read_text(encoding="utf-8"))
    names: dict[str, str] = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            for alias in node.names:
                names[alias.asname or alias.name] = f"{node.module}.{alias.name}"
        elif isinstance(node, ast.Import):
            for alias in node.names:
                # `import a.b as c` binds c to a.b; `import a.b` binds a to a
                bound = alias.name if alias.asname else alias.name.split(".")[0]
                names[alias.asname or bound] = bound
    return names


def home_modules(names: list[str]) -> list[str]:
    """The modules that hold the objects ``names`` (dotted) and their owners, innermost first:
    where a reference in their docstrings or annotations is read."""
    homes: list[str] = []
    for name in names:
        parts = name.split(".")
        for cut in range(len(parts), 0, -1):
            prefix = ".".join(parts[:cut])
            found = _resolve(prefix)
            if found is _MISSING:
                continue
            if isinstance(found, types.ModuleType):
                home: Any = prefix
            else:
                home = getattr(found, "__module__", None)
            if isinstance(home, str) and home not in homes:
                homes.append(home)
    return homes


def candidates(target: str, context: list[str]) -> list[str]:
    """The dotted paths a reference to ``target`` may mean, read from the objects ``context``
    (the documented object, the docstring's owner): as written, then within each of them, then
    through their modules' imports."""
    # a subscripted type split by Sphinx at its commas, ``typing.Literal['q'``: its origin
    target = target.lstrip(".~").split("[", 1)[0]
    found = [target]
    for name in context:
        found.append(f"{name}.{target}")
    first, _, rest = target.partition(".")
    for home in home_modules(context):
        found.append(f"{home}.{target}")
        imported = imported_names(home).get(first)
        if imported:
            found.append(f"{imported}.{rest}" if rest else imported)
    return found


def _context(node: Any) -> list[str]:
    module, klass = node.get("py:module"), node.get("py:class")
    names = []
    source = node.source or ""
    if "docstring of " in source:
        names.append(source.rsplit("docstring of ", 1)[1])
    signature = node.parent
    while signature is not None and signature.tagname != "desc_signature":
        signature = signature.parent
    if signature is not None and signature.get("module") and signature.get("fullname"):
        names.append(f"{signature['module']}.{signature['fullname']}")
    if module:
        if klass:
            names.append(f"{module}.{klass}")
        names.append(module)
    return names


def _missing_reference(sphinx: Any, env: Any, node: Any, contnode: Any) -> Any:
    if node.get("refdomain") != "py":
        return None
    if any(exists(path) for path in candidates(node.get("reftarget", ""), _context(node))):
        return contnode
    return None


def setup(sphinx: Any) -> dict[str, Any]:
    """The Sphinx extension: a ``missing-reference`` hook, last among the resolvers."""
    sphinx.connect("missing-reference", _missing_reference, priority=900)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
