"""Scenario YAML read within bounds: file size, nesting depth, alias references, expanded size.

A scenario is a small document (the shipped ones: at most 4 kB, 6 levels of nesting, 270
values). A hostile or broken file must get a one-line :class:`~strapdown_ros.config.base.
ScenarioError`, not a ``RecursionError`` (YAML nested thousands of levels deep) nor minutes of
work and gigabytes of memory (a "billion laughs" document: a few aliases, each referring to a
list of the previous ones, expand to 10⁹ values when validated). :func:`load_yaml` parses with
PyYAML's safe loader, counting while it composes (so that a refused document is never built):

* :data:`MAX_BYTES` of text (the file is not read further);
* :data:`MAX_DEPTH` nested lists / mappings;
* :data:`MAX_ALIASES` alias references (``*name``);
* :data:`MAX_VALUES` values once every alias is expanded (what validation walks), counted on
  the composed node graph without expanding it; an alias inside the value it names (a
  recursive document) is refused.

:func:`check_document` applies the same depth and size limits to a document already in memory
(overrides applied, or built by a program). ``--set`` values are YAML too and are read with
:func:`load_yaml`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

import yaml
from yaml.events import AliasEvent
from yaml.nodes import MappingNode, Node, SequenceNode

__all__ = [
    "MAX_ALIASES",
    "MAX_BYTES",
    "MAX_DEPTH",
    "MAX_VALUES",
    "LimitError",
    "check_document",
    "load_yaml",
]

#: Largest scenario text (bytes): 1 MiB, a hundred times the largest shipped scenario.
MAX_BYTES = 1 << 20
#: Deepest nesting of lists and mappings (the shipped scenarios: 6).
MAX_DEPTH = 32
#: Most alias references (``*name``) in one document.
MAX_ALIASES = 10_000
#: Most values (scalars, lists, mappings, mapping keys included) with every alias expanded.
MAX_VALUES = 200_000


class LimitError(ValueError):
    """A document beyond one of the limits; ``line``/``column`` (1-based) where, when known."""

    def __init__(self, problem: str, mark: Any = None) -> None:
        self.problem = problem
        self.line = None if mark is None else mark.line + 1
        self.column = None if mark is None else mark.column + 1
        where = "" if mark is None else f" (at line {self.line}, column {self.column})"
        super().__init__(problem + where)


#: The problems, worded to follow "<file> " / "the value " / "the scenario ".
DEEP = (
    f"has lists and mappings nested more than {MAX_DEPTH} levels deep, the most a scenario may have"
)
MANY_ALIASES = f"has more than {MAX_ALIASES} alias references (*name), the most a scenario may have"
MANY_VALUES = (
    f"has more than {MAX_VALUES} values with its aliases expanded, the most a scenario may have"
)
RECURSIVE = "has an alias inside the value it refers to (a recursive document)"


def too_large(size: int) -> str:
    """The problem of a text of ``size`` bytes (> :data:`MAX_BYTES`)."""
    return f"has {size} bytes, more than the {MAX_BYTES} (1 MiB) a scenario may have"


_N = TypeVar("_N", SequenceNode, MappingNode)


class _BoundedLoader(yaml.SafeLoader):
    """PyYAML's safe loader, refusing documents beyond the limits while composing them."""

    def __init__(self, text: str) -> None:
        super().__init__(text)
        self._depth = 0
        self._aliases = 0

    def compose_node(self, parent: Node | None, index: Any) -> Node:  # type: ignore[override]
        if self.check_event(AliasEvent):
            self._aliases += 1
            if self._aliases > MAX_ALIASES:
                raise LimitError(MANY_ALIASES, self.peek_event().start_mark)
        return super().compose_node(parent, index)

    def _nested(self, compose: Callable[[str | None], _N], anchor: str | None) -> _N:
        """``compose(anchor)`` one level deeper, refused beyond :data:`MAX_DEPTH`."""
        self._depth += 1
        try:
            if self._depth > MAX_DEPTH:
                raise LimitError(DEEP, self.peek_event().start_mark)
            return compose(anchor)
        finally:
            self._depth -= 1

    def compose_sequence_node(self, anchor: str | None) -> SequenceNode:
        return self._nested(super().compose_sequence_node, anchor)

    def compose_mapping_node(self, anchor: str | None) -> MappingNode:
        return self._nested(super().compose_mapping_node, anchor)

    def get_single_node(self) -> Node | None:
        node = super().get_single_node()
        if node is not None:
            _measure_nodes(node)
        return node


def _node_children(node: Node) -> list[Node]:
    if isinstance(node, SequenceNode):
        return list(node.value)
    if isinstance(node, MappingNode):
        return [n for pair in node.value for n in pair]
    return []


def _walk_sizes(
    root: Any,
    children: Callable[[Any], list[Any]],
    is_collection: Callable[[Any], bool],
    mark: Callable[[Any], Any],
    recursive: str,
) -> None:
    """Refuse a graph (a YAML node graph or a document in memory) too large, too deep or
    containing itself.

    Post-order walk of the graph, each value once (a value reached twice, e.g. through an
    alias, is shared): the expanded size of a value is 1 plus those of its children, its depth
    ``is_collection`` (1 or 0) plus the deepest child's. ``mark`` gives a value's place in the
    text (or None), ``recursive`` the problem of a value inside itself.
    """
    size: dict[int, int] = {}
    depth: dict[int, int] = {}
    open_: set[int] = set()
    stack: list[tuple[Any, bool]] = [(root, False)]
    while stack:
        value, finished = stack.pop()
        key = id(value)
        inner = children(value)
        if finished:
            open_.discard(key)
            size[key] = 1 + sum(size[id(c)] for c in inner)
            depth[key] = is_collection(value) + max((depth[id(c)] for c in inner), default=0)
            if size[key] > MAX_VALUES:
                raise LimitError(MANY_VALUES, mark(value))
            if depth[key] > MAX_DEPTH:
                raise LimitError(DEEP, mark(value))
            continue
        if key in size:
            continue
        if not inner:  # a scalar (or an empty collection): no walk
            size[key] = 1
            depth[key] = int(is_collection(value))
            continue
        open_.add(key)
        stack.append((value, True))
        for child in inner:
            if id(child) in open_:
                raise LimitError(recursive, mark(child))
            if id(child) not in size:
                stack.append((child, False))


def _measure_nodes(root: Node) -> None:
    """Refuse a composed document whose aliases make it too large, too deep or recursive (an
    alias is a shared node)."""
    _walk_sizes(
        root,
        _node_children,
        lambda node: isinstance(node, SequenceNode | MappingNode),
        lambda node: node.start_mark,
        RECURSIVE,
    )


def load_yaml(text: str) -> Any:
    """``yaml.safe_load(text)`` within the limits of the module docstring.

    Raises
    ------
    LimitError
        Beyond a limit (with the line and column where it was found).
    yaml.YAMLError
        Not valid YAML.
    """
    size = len(text.encode("utf-8", "surrogatepass")) if len(text) * 4 > MAX_BYTES else 0
    if size > MAX_BYTES:
        raise LimitError(too_large(size))
    loader = _BoundedLoader(text)
    try:
        return loader.get_single_data()
    finally:
        loader.dispose()


def check_document(document: Any) -> None:
    """Refuse a document in memory beyond :data:`MAX_DEPTH` or :data:`MAX_VALUES` (shared
    parts counted each time they occur, as validation walks them) or containing itself.

    Raises
    ------
    LimitError
        Without a line (the document is not text).
    """
    _walk_sizes(
        document,
        _value_children,
        lambda value: isinstance(value, dict | list | tuple),
        lambda value: None,
        "has a value inside itself (a recursive document)",
    )


def _value_children(value: Any) -> list[Any]:
    if isinstance(value, dict):
        return [x for pair in value.items() for x in pair]
    if isinstance(value, list | tuple):
        return list(value)
    return []
