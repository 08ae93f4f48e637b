"""Napoleon for functions and classes, and not for attributes, data and properties.

Napoleon reads the first line of an attribute's docstring as Google's ``type: description``:
everything before its first colon becomes the attribute's type. mitlc's attribute docstrings
are prose with colons ("The explicit view: ..."), and the attributes' types come from their
annotations, so this extension loads napoleon and hands it every docstring but those
(``Args:``/``Returns:`` sections in functions and classes still read as napoleon reads them).
"""

from __future__ import annotations

from typing import Any

_PROSE = frozenset({"attribute", "data", "property"})


def setup(sphinx: Any) -> dict[str, Any]:
    """The Sphinx extension: napoleon's docstring hook, replaced by one that skips attributes."""
    sphinx.setup_extension("sphinx.ext.napoleon")
    from sphinx.ext.napoleon import _process_docstring

    for listener in list(sphinx.events.listeners["autodoc-process-docstring"]):
        if listener.handler is _process_docstring:
            sphinx.disconnect(listener.id)

    def napoleon_unless_prose(
        app: Any, what: Any, name: str, obj: Any, options: Any, lines: list[str]
    ) -> None:
        if what not in _PROSE:
            _process_docstring(app, what, name, obj, options, lines)

    sphinx.connect("autodoc-process-docstring", napoleon_unless_prose)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
