"""The limits a spec is held to before the passes that could not cope without them.

Three checks, each an error at the place in the text where the limit is crossed: the text's
length (:data:`~mitlc.limits.MAX_SPEC_CHARS`, before parsing), its nesting depth
(:data:`~mitlc.limits.MAX_SPEC_DEPTH`, on Lark's parse tree, which Lark builds without
recursion, before the recursive passes), and an interval bound's size
(:data:`~mitlc.limits.MAX_BOUND`, before its digits are converted).
"""

from __future__ import annotations

from lark import Token, Tree

from mitlc.errors import SpecSemanticError, SpecSyntaxError, locate
from mitlc.limits import MAX_BOUND, MAX_SPEC_CHARS, MAX_SPEC_DEPTH

MAX_SPEC_BYTES = 4 * MAX_SPEC_CHARS + 3
"""The most bytes a spec of :data:`MAX_SPEC_CHARS` characters takes in UTF-8 (a byte-order
mark and four bytes a character): a file longer than this is too long whatever it holds."""

_NOT_NESTING = frozenset({"start", "interval"})
"""Parse-tree nodes that add no level: the root, and an interval (it holds only tokens)."""


def too_long(text: str, filename: str) -> SpecSyntaxError:
    """The error for a spec longer than :data:`MAX_SPEC_CHARS`, at the first character past it
    (``text`` may be only the start of the spec)."""
    return SpecSyntaxError(
        f"the spec is too long: more than {MAX_SPEC_CHARS:,} characters (mitlc's limit)",
        locate(text, MAX_SPEC_CHARS, filename),
    )


def check_length(text: str, filename: str) -> None:
    """Refuse a spec longer than :data:`MAX_SPEC_CHARS` characters."""
    if len(text) > MAX_SPEC_CHARS:
        raise too_long(text, filename)


def check_depth(tree: Tree[Token], text: str, filename: str) -> None:
    """Refuse a parse tree nested deeper than :data:`MAX_SPEC_DEPTH`, pointing at the first
    subformula (in the text's order) that lies too deep. Walks the tree without recursion."""
    stack: list[tuple[Tree[Token], int]] = [(tree, 0)]
    while stack:
        node, depth = stack.pop()
        if node.data not in _NOT_NESTING:
            depth += 1
        if depth > MAX_SPEC_DEPTH:
            start = node.meta.start_pos if not node.meta.empty else 0
            raise SpecSyntaxError(
                f"the formula is nested too deeply: more than {MAX_SPEC_DEPTH} levels of "
                "operators and parentheses (mitlc's limit)",
                locate(text, start, filename),
            )
        stack.extend((c, depth) for c in reversed(node.children) if isinstance(c, Tree))


def bound_value(token: Token, text: str, filename: str) -> int:
    """The value of an interval bound's token: a non-negative integer at most
    :data:`MAX_BOUND`, checked on its digits before they are converted."""
    written = "".join(str(token).split())
    digits = written.lstrip("-").lstrip("0") or "0"
    location = locate(text, token.start_pos or 0, filename)
    shown = digits if len(digits) <= 20 else f"{digits[:12]}... ({len(digits):,} digits)"
    if written.startswith("-") and digits != "0":
        raise SpecSemanticError(
            f"interval bounds must be non-negative integers, found -{shown}", location
        )
    if len(digits) > len(str(MAX_BOUND)) or int(digits) > MAX_BOUND:
        raise SpecSemanticError(
            f"interval bound {shown} is too large: bounds are at most {MAX_BOUND:,} "
            "(write inf for no upper bound)",
            location,
        )
    return int(digits)
