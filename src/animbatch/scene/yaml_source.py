"""Safe YAML loading that remembers where every key and value came from.

PyYAML's ``safe_load`` returns plain data and forgets positions, so errors found later (by the schema) could not say
``file:line:column``. Here the document is composed into nodes, and the nodes are turned into plain Python data while
the position of each key and value is recorded under its *key path* (``("bodies", 2, "mass")``).

Scalars follow YAML 1.2 (core schema) rather than PyYAML's YAML 1.1 defaults, because the 1.1 rules surprise scene
authors: ``1e-6`` would be a string (1.1 floats need a dot), ``no``/``on`` would be booleans, ``012`` would be octal 10.
Only ``true``/``false`` are booleans here, and ``1e-6`` is a float. No tag that constructs Python objects is accepted
(the loader derives from ``SafeLoader``). Duplicate keys are errors instead of silently keeping the last one.

Hostile documents are refused before they cost anything: the text's size, the nesting depth and the number of nodes
*after expanding aliases* (an alias bomb, "billion laughs", is a few lines that expand to 10⁹ nodes) are counted on
PyYAML's event stream while the nodes are composed, by a loop rather than PyYAML's recursive composer, so a document
nested thousands of levels deep gives a SceneError, not a RecursionError. Once composed, a document is at most
``MAX_DEPTH`` levels deep, aliases included, which bounds every later walk of it; the nodes are turned into plain
data by a loop too. Numbers too large or too small to be physical (``1e300`` m, ``1e-300`` kg) are refused here
too, with their position, because they overflow later.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any

import yaml

from animbatch.errors import SceneError, SceneIssue

KeyPath = tuple[str | int, ...]

#: Largest scene file [bytes]: far above any hand-written scene (a 100 000-point polyline is ~4 MB).
MAX_DOCUMENT_BYTES = 16 * 1024 * 1024
#: Deepest nesting of mappings and lists, counting what aliases expand to (real scenes nest about 6 levels).
MAX_DEPTH = 64
#: Most nodes (keys, values, list items) after expanding aliases, so that an alias bomb cannot exhaust memory.
MAX_NODES = 2_000_000
#: Numbers in a scene are 0 or have a magnitude in this range [SI units]: from an electron's mass (9.1e-31 kg) to
#: fifty thousand suns (1e35 kg). Beyond it, squares and products overflow or underflow float64 in the physics.
NUMBER_RANGE = (1e-35, 1e35)


@dataclass(frozen=True)
class Position:
    """A 1-based line and column in a file."""

    line: int
    column: int


@dataclass
class SourceMap:
    """Where each piece of a loaded scene came from: file positions, or a ``--set`` override."""

    filename: str
    values: dict[KeyPath, Position] = field(default_factory=dict)
    keys: dict[KeyPath, Position] = field(default_factory=dict)
    overrides: dict[KeyPath, str] = field(default_factory=dict)

    def source_of(self, path: KeyPath, *, key: bool = False) -> str:
        """``file:line:col`` (or ``--set …``) of the value at ``path``, or of its key when ``key`` is true.

        A path with no recorded position (a missing key, say) is reported at its closest recorded ancestor.
        """
        for depth in range(len(path), -1, -1):
            prefix = path[:depth]
            if prefix in self.overrides:
                return self.overrides[prefix]
            position = (self.keys.get(prefix) if key and depth == len(path) else None) or self.values.get(prefix)
            if position is not None:
                return f"{self.filename}:{position.line}:{position.column}"
        return self.filename

    def forget_below(self, path: KeyPath) -> None:
        """Drop positions at and under ``path`` (its value was replaced by an override)."""
        n = len(path)
        for table in (self.values, self.keys, self.overrides):
            for recorded in [p for p in table if p[:n] == path]:
                del table[recorded]


def format_path(path: KeyPath) -> str:
    """``("bodies", 2, "mass")`` -> ``"bodies[2].mass"``."""
    text = ""
    for part in path:
        if isinstance(part, int):
            text += f"[{part}]"
        else:
            text += f".{part}" if text else str(part)
    return text


class SceneYamlLoader(getattr(yaml, "CSafeLoader", yaml.SafeLoader)):  # type: ignore[misc]  # C loader if built
    """``SafeLoader`` with YAML 1.2 core-schema booleans, integers and floats; libyaml's parser where PyYAML was
    built with it (a list of 300 000 numbers loads in 3 s instead of 12 s)."""


_BOOL_TAG = "tag:yaml.org,2002:bool"
_INT_TAG = "tag:yaml.org,2002:int"
_FLOAT_TAG = "tag:yaml.org,2002:float"

SceneYamlLoader.yaml_implicit_resolvers = {
    first: [(tag, regexp) for tag, regexp in resolvers if tag not in (_BOOL_TAG, _INT_TAG, _FLOAT_TAG)]
    for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()
}
SceneYamlLoader.add_implicit_resolver(
    _BOOL_TAG, re.compile(r"^(?:true|True|TRUE|false|False|FALSE)$"), list("tTfF"))
SceneYamlLoader.add_implicit_resolver(
    _INT_TAG, re.compile(r"^(?:[-+]?[0-9]+|0o[0-7]+|0x[0-9a-fA-F]+)$"), list("-+0123456789"))
SceneYamlLoader.add_implicit_resolver(
    _FLOAT_TAG,
    re.compile(r"^(?:[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?"
               r"|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$"),
    list("-+.0123456789"))


def _construct_int(loader: yaml.SafeLoader, node: yaml.ScalarNode) -> int:
    text = loader.construct_scalar(node)
    if text.startswith("0o"):
        return int(text[2:], 8)
    if text.startswith("0x"):
        return int(text[2:], 16)
    return int(text, 10)  # decimal, even with leading zeros (YAML 1.1 would read 012 as octal)


SceneYamlLoader.add_constructor(_INT_TAG, _construct_int)


_PLAIN_COLLECTION_TAGS = frozenset({"tag:yaml.org,2002:map", "tag:yaml.org,2002:seq"})


def _position(mark: yaml.Mark) -> Position:
    return Position(mark.line + 1, mark.column + 1)


class _Builder:
    """Turns composed YAML nodes into plain data while filling a SourceMap, by a loop over a stack of nodes still to
    build (no recursion, whatever the depth)."""

    def __init__(self, loader: SceneYamlLoader, source: SourceMap) -> None:
        self.loader = loader
        self.source = source
        self.issues: list[SceneIssue] = []
        self._pairs: dict[int, list[tuple[yaml.Node, yaml.Node, bool]]] = {}  # id(mapping) -> its flattened pairs

    def build(self, root: yaml.Node, path: KeyPath) -> Any:
        """Plain data of ``root``, found at ``path``."""
        holder: list[Any] = [None]
        todo: list[tuple[yaml.Node, KeyPath, Any, Any]] = [(root, path, holder, 0)]  # (node, path, container, slot)
        while todo:
            node, where, container, slot = todo.pop()
            self.source.values.setdefault(where, _position(node.start_mark))
            if not isinstance(node, yaml.ScalarNode) and node.tag not in _PLAIN_COLLECTION_TAGS:
                # SafeLoader would refuse these too, but only when constructing; we build collections ourselves.
                at = _position(node.start_mark)
                raise SceneError([SceneIssue(f"{self.source.filename}:{at.line}:{at.column}", format_path(where),
                                             f"YAML tag not allowed: {node.tag!r}; scene files hold plain data only "
                                             "(mappings, lists, numbers, text)")])
            children: list[tuple[Any, tuple[str | int, ...], Any, str | int]]  # (node, path, parent, key)
            if isinstance(node, yaml.MappingNode):
                value: Any = {}
                children = [(child, (*where, key), value, key) for key, child in self._mapping(node, where)]
            elif isinstance(node, yaml.SequenceNode):
                value = [None] * len(node.value)
                children = [(child, (*where, index), value, index) for index, child in enumerate(node.value)]
            else:
                value, children = self._scalar(node, where), []
            container[slot] = value
            todo.extend(reversed(children))  # in document order, so that first positions are recorded first
        return holder[0]

    def _scalar(self, node: yaml.ScalarNode, path: KeyPath) -> Any:
        try:
            value = self.loader.construct_object(node, deep=True)
        except ValueError:  # Python refuses to read integers of more than 4300 digits
            value = None
            problem: str | None = f"the number {node.value[:20]}… has {len(node.value)} digits; " + _range_text()
        else:
            problem = number_problem(value)
        if problem is not None:
            where = _position(node.start_mark)
            self.issues.append(SceneIssue(f"{self.source.filename}:{where.line}:{where.column}", format_path(path),
                                          problem))
        return value

    def _flattened(self, node: yaml.MappingNode) -> list[tuple[yaml.Node, yaml.Node, bool]]:
        """(key, value, written in this mapping) for each pair, merged ones ('<<: *anchor') first, so that own values
        override them. Kept per node: PyYAML flattens in place, and an alias builds the same node again."""
        if id(node) not in self._pairs:
            own = {id(key) for key, _ in node.value if key.tag != "tag:yaml.org,2002:merge"}
            self.loader.flatten_mapping(node)
            self._pairs[id(node)] = [(key, value, id(key) in own) for key, value in node.value]
        return self._pairs[id(node)]

    def _mapping(self, node: yaml.MappingNode, path: KeyPath) -> list[tuple[str, yaml.Node]]:
        """The (key, value node) pairs that make the mapping at ``path``: text keys, no own duplicates, the last
        value of each key (own over merged); records the keys' positions."""
        chosen: dict[str, yaml.Node] = {}
        own_seen: dict[str, Position] = {}
        for key_node, value_node, own in self._flattened(node):
            key = self.loader.construct_object(key_node, deep=True)
            where = _position(key_node.start_mark)
            if not isinstance(key, str):
                self.issues.append(SceneIssue(f"{self.source.filename}:{where.line}:{where.column}",
                                              format_path(path),
                                              f"keys must be text, got {key!r} ({type(key).__name__})"))
                continue
            if own:
                if key in own_seen:
                    self.issues.append(SceneIssue(
                        f"{self.source.filename}:{where.line}:{where.column}", format_path((*path, key)),
                        f"duplicate key (first given at line {own_seen[key].line}); keep only one"))
                    continue
                own_seen[key] = where
            chosen[key] = value_node  # an own value replaces a merged one (in its place), before either is built
            self.source.keys[(*path, key)] = where
        return list(chosen.items())


def load_yaml(text: str, filename: str) -> tuple[Any, SourceMap]:
    """Parse one YAML document into plain data and a SourceMap; raise SceneError on any problem."""
    source = SourceMap(filename)
    if len(text) > MAX_DOCUMENT_BYTES // 4 and len(text.encode("utf-8")) > MAX_DOCUMENT_BYTES:
        raise SceneError([SceneIssue(filename, "", f"the file is {len(text.encode('utf-8')) / 2**20:.1f} MiB; scene "
                                                   f"files are limited to {MAX_DOCUMENT_BYTES // 2**20} MiB "
                                                   "(MAX_DOCUMENT_BYTES)")])
    loader = SceneYamlLoader(text)
    try:
        node = _compose(loader, filename)
        if node is None:
            raise SceneError([SceneIssue(filename, "", "the scene file is empty")])
        builder = _Builder(loader, source)
        data = builder.build(node, ())
    except yaml.MarkedYAMLError as error:
        raise SceneError([_syntax_issue(error, filename)]) from None
    except yaml.YAMLError as error:  # errors without a position (rare: e.g. a reader error)
        raise SceneError([SceneIssue(filename, "", f"YAML error: {error}")]) from None
    finally:
        loader.dispose()
    if builder.issues:
        raise SceneError(builder.issues)
    return data, source


def number_problem(value: Any) -> str | None:
    """Why a loaded number cannot be physical (outside NUMBER_RANGE), or None. NaN and infinity are left to the
    schema, which refuses them with the key's own rules."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    size = abs(value)
    if size == 0 or size != size or size == float("inf") or NUMBER_RANGE[0] <= size <= NUMBER_RANGE[1]:
        return None
    return f"{value:.3g} is {'too large' if size > 1 else 'too small'}; " + _range_text()


def _range_text() -> str:
    low, high = NUMBER_RANGE
    return (f"numbers in a scene are 0 or between {low:g} and {high:g} in size (SI units; from an electron's mass "
            "to 50 000 suns), so that the physics cannot overflow. Choose units that bring the values into range "
            "(e.g. G = 1 with scaled masses)")


def _limit(filename: str, mark: yaml.Mark, message: str) -> SceneError:
    where = _position(mark)
    return SceneError([SceneIssue(f"{filename}:{where.line}:{where.column}", "", message)])


def _compose(loader: SceneYamlLoader, filename: str) -> yaml.Node | None:
    """The document's root node, composed from PyYAML's events by a loop (PyYAML's composer recurses once per level).

    While composing, it counts nodes after expanding aliases and the depth they expand to, and stops at the first
    event beyond MAX_NODES or MAX_DEPTH: an alias bomb or a deep document is refused in milliseconds.
    """
    loader.get_event()  # StreamStart
    if loader.check_event(yaml.StreamEndEvent):
        loader.get_event()
        return None
    loader.get_event()  # DocumentStart
    anchors: dict[str, yaml.Node] = {}
    expanded: dict[int, tuple[int, int]] = {}  # id(collection) -> (nodes it expands to, its height)
    open_nodes: list[tuple[yaml.Node, int, list[int]]] = []  # (node, node count at its start, [height of children])
    pending_key: list[yaml.Node | None] = []  # per open mapping: its key waiting for a value
    count = 0
    root: yaml.Node | None = None

    def finish(node: yaml.Node, size: int, height: int, mark: yaml.Mark) -> yaml.Node | None:
        nonlocal count
        count += size
        if count > MAX_NODES:
            raise _limit(filename, mark, f"the document expands to more than {MAX_NODES:,} nodes (MAX_NODES), "
                                         "counting what its aliases (*name) repeat; an alias bomb?")
        if len(open_nodes) + height > MAX_DEPTH:
            raise _limit(filename, mark, f"mappings and lists are nested more than {MAX_DEPTH} levels deep "
                                         "(MAX_DEPTH), counting what aliases (*name) expand to; scenes need about 6")
        if not open_nodes:
            return node
        parent, _, heights = open_nodes[-1]
        heights.append(height)
        if isinstance(parent, yaml.SequenceNode):
            parent.value.append(node)
        elif pending_key[-1] is None:
            pending_key[-1] = node
        else:
            parent.value.append((pending_key[-1], node))
            pending_key[-1] = None
        return None

    while root is None:
        event = loader.get_event()
        if isinstance(event, yaml.AliasEvent):
            if event.anchor not in anchors:
                raise yaml.composer.ComposerError(None, None, f"found undefined alias {event.anchor!r}",
                                                  event.start_mark)
            target = anchors[event.anchor]
            if isinstance(target, yaml.CollectionNode) and id(target) not in expanded:
                raise _limit(filename, event.start_mark, f"the alias *{event.anchor} is inside the collection it "
                                                         "names, so it would repeat forever")
            size, height = expanded.get(id(target), (1, 0))
            root = finish(target, size, height, event.start_mark)
        elif isinstance(event, yaml.ScalarEvent):
            tag = event.tag
            if tag is None or tag == "!":
                tag = loader.resolve(yaml.ScalarNode, event.value, event.implicit)
            node: yaml.Node = yaml.ScalarNode(tag, event.value, event.start_mark, event.end_mark, style=event.style)
            if event.anchor is not None:
                anchors[event.anchor] = node
            root = finish(node, 1, 0, event.start_mark)
        elif isinstance(event, yaml.CollectionStartEvent):
            tag = event.tag
            is_mapping = isinstance(event, yaml.MappingStartEvent)
            kind = yaml.MappingNode if is_mapping else yaml.SequenceNode
            if tag is None or tag == "!":
                tag = loader.resolve(kind, None, event.implicit)
            node = kind(tag, [], event.start_mark, None, flow_style=event.flow_style)
            if event.anchor is not None:
                anchors[event.anchor] = node
            if len(open_nodes) >= MAX_DEPTH:
                raise _limit(filename, event.start_mark, f"mappings and lists are nested more than {MAX_DEPTH} "
                                                         "levels deep (MAX_DEPTH); scenes need about 6")
            open_nodes.append((node, count, []))
            pending_key.append(None)
        else:  # SequenceEnd or MappingEnd
            node, start, heights = open_nodes.pop()
            pending_key.pop()
            node.end_mark = event.end_mark
            size, height = 1 + count - start, 1 + max(heights, default=0)
            expanded[id(node)] = (size, height)
            count = start  # its children were counted already; count it whole, once
            root = finish(node, size, height, event.start_mark)
    loader.get_event()  # DocumentEnd
    if not loader.check_event(yaml.StreamEndEvent):
        event = loader.get_event()
        raise _limit(filename, event.start_mark,
                     "the file holds more than one YAML document (---); a scene file holds exactly one")
    return root


def _syntax_issue(error: yaml.MarkedYAMLError, filename: str) -> SceneIssue:
    mark = error.problem_mark or error.context_mark
    where = f"{filename}:{mark.line + 1}:{mark.column + 1}" if mark else filename
    problem = error.problem or "invalid YAML"
    if isinstance(error, yaml.constructor.ConstructorError) and "tag" in problem:
        message = (f"YAML tag not allowed: {problem.replace('could not determine a constructor for the tag ', '')}; "
                   "scene files hold plain data only (mappings, lists, numbers, text)")
    else:
        context = f" {error.context}" if error.context else ""
        message = f"YAML syntax error: {problem}{context}"
    return SceneIssue(where, "", message)
