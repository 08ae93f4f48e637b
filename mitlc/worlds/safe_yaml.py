"""PyYAML's safe loader, held to limits: the YAML reader of world files.

Only YAML's standard tags are constructed (``!!python/...`` is refused: nothing read runs
code). On top of PyYAML's safe loader this one refuses, each at its line and column:

* a key given twice in a mapping (PyYAML silently keeps the last);
* collections nested deeper than :data:`~mitlc.limits.MAX_YAML_DEPTH` (PyYAML's composer
  recurses per level);
* more than :data:`~mitlc.limits.MAX_YAML_ALIASES` aliases, an alias inside its own anchor, and
  a document that counts more than :data:`~mitlc.limits.MAX_YAML_NODES` values or nests deeper
  than the depth limit once every alias is expanded (a "billion laughs"), checked on the node
  graph before anything is constructed or walked;
* an integer longer than :data:`~mitlc.limits.MAX_YAML_INT_DIGITS` characters (checked before
  it is converted) or outside 64 bits;
* a value its tag cannot make (``!!int abc``, ``2001-13-45``), which PyYAML lets escape as a
  ``ValueError`` or ``KeyError``.
"""

from __future__ import annotations

from typing import Any

import yaml
from yaml.constructor import ConstructorError
from yaml.nodes import MappingNode, Node, ScalarNode, SequenceNode

from mitlc.limits import MAX_YAML_ALIASES, MAX_YAML_DEPTH, MAX_YAML_INT_DIGITS, MAX_YAML_NODES

INT64 = 2**63


class YamlLimitError(yaml.MarkedYAMLError):
    """A YAML document beyond one of mitlc's limits (``problem`` says which)."""

    def __init__(self, problem: str, mark: Any) -> None:
        super().__init__(None, None, problem, mark)


class Loader(yaml.SafeLoader):
    """The safe loader with mitlc's limits (see the module docstring)."""

    def __init__(self, stream: str) -> None:
        super().__init__(stream)
        self._depth = 0
        self._aliases = 0

    def compose_node(self, parent: Node | None, index: Any) -> Node:
        event: yaml.Event = self.peek_event()  # type: ignore[no-untyped-call]
        if isinstance(event, yaml.AliasEvent):
            self._aliases += 1
            if self._aliases > MAX_YAML_ALIASES:
                raise YamlLimitError(
                    f"more than {MAX_YAML_ALIASES} aliases (mitlc's limit)", event.start_mark
                )
        if self._depth >= MAX_YAML_DEPTH:
            raise YamlLimitError(_too_deep(), event.start_mark)
        self._depth += 1
        try:
            node: Node | None = super().compose_node(parent, index)
        finally:
            self._depth -= 1
        assert node is not None  # an event always makes a node
        return node

    def construct_object(self, node: Node, deep: bool = False) -> Any:
        try:
            return super().construct_object(node, deep=deep)
        except (ValueError, TypeError, KeyError, IndexError, OverflowError) as err:
            tag = node.tag.rsplit(":", 1)[-1]
            value = node.value if isinstance(node, ScalarNode) else ""
            shown = f" {value[:40]!r}" if value else ""
            raise ConstructorError(
                None, None, f"cannot read the {tag}{shown}: {err}", node.start_mark
            ) from None

    def construct_mapping(self, node: MappingNode, deep: bool = False) -> dict[Any, Any]:
        seen: dict[str, yaml.Mark] = {}
        for key, _ in node.value:
            if isinstance(key, ScalarNode) and key.value != "<<":
                if key.value in seen:
                    first = seen[key.value]
                    raise ConstructorError(
                        None,
                        None,
                        f"duplicate key {key.value!r} (first at line {first.line + 1}, "
                        f"column {first.column + 1})",
                        key.start_mark,
                    )
                seen[key.value] = key.start_mark
        return super().construct_mapping(node, deep=deep)

    def construct_bounded_int(self, node: ScalarNode) -> int:
        """An integer, refused when too long to convert or outside 64 bits."""
        written = str(node.value)
        if len(written.replace("_", "")) > MAX_YAML_INT_DIGITS:
            raise YamlLimitError(
                f"integer too long: more than {MAX_YAML_INT_DIGITS} characters (mitlc's limit)",
                node.start_mark,
            )
        value: int = self.construct_yaml_int(node)
        if not -INT64 <= value < INT64:
            raise YamlLimitError(
                f"integer {written} is out of range (-2**63 to 2**63 - 1)", node.start_mark
            )
        return value


Loader.add_constructor("tag:yaml.org,2002:int", Loader.construct_bounded_int)


def _too_deep() -> str:
    return f"nested more than {MAX_YAML_DEPTH} levels deep (mitlc's limit)"


def _children(node: Node) -> list[Node]:
    if isinstance(node, MappingNode):
        return [item for pair in node.value for item in pair]
    if isinstance(node, SequenceNode):
        return list(node.value)
    return []


def check_expansion(root: Node) -> None:
    """Refuse a node graph that aliases make cyclic, too large or too deep once expanded:
    sizes and depths are computed once per node (post-order, without recursion)."""
    size: dict[int, int] = {}
    depth: dict[int, int] = {}
    open_nodes: set[int] = set()
    stack: list[tuple[Node, bool]] = [(root, False)]
    while stack:
        node, finished = stack.pop()
        key = id(node)
        if finished:
            kids = _children(node)
            size[key] = 1 + sum(size[id(k)] for k in kids)
            depth[key] = 1 + max((depth[id(k)] for k in kids), default=0)
            open_nodes.discard(key)
            if size[key] > MAX_YAML_NODES:
                raise YamlLimitError(
                    f"more than {MAX_YAML_NODES:,} values with aliases expanded (mitlc's limit)",
                    node.start_mark,
                )
            if depth[key] > MAX_YAML_DEPTH:
                raise YamlLimitError(_too_deep() + " with aliases expanded", node.start_mark)
            continue
        if key in size:
            continue
        open_nodes.add(key)
        stack.append((node, True))
        for kid in _children(node):
            if id(kid) in open_nodes:
                raise YamlLimitError("an alias inside its own anchor", node.start_mark)
            if id(kid) not in size:
                stack.append((kid, False))


def load(text: str) -> tuple[Any, Node | None]:
    """The value of the one YAML document in ``text``, and its root node (``None`` for an empty
    document). Raises PyYAML's errors, :class:`YamlLimitError` among them."""
    loader = Loader(text)
    try:
        node = loader.get_single_node()
        if node is None:
            return None, None
        check_expansion(node)
        return loader.construct_document(node), node
    finally:
        loader.dispose()
