"""Safe YAML loading that remembers where every key and value came from.

PyYAML's ``safe_load`` returns plain data and forgets positions, so errors found later (by the schema) could not say
``file:line:column``. Here the document is composed into nodes, and the nodes are turned into plain Python data while
the position of each key and value is recorded under its *key path* (``("bodies", 2, "mass")``).

Scalars follow YAML 1.2 (core schema) rather than PyYAML's YAML 1.1 defaults, because the 1.1 rules surprise scene
authors: ``1e-6`` would be a string (1.1 floats need a dot), ``no``/``on`` would be booleans, ``012`` would be octal 10.
Only ``true``/``false`` are booleans here, and ``1e-6`` is a float. No tag that constructs Python objects is accepted
(the loader derives from ``SafeLoader``). Duplicate keys are errors instead of silently keeping the last one.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any

import yaml

from animbatch.errors import SceneError, SceneIssue

KeyPath = tuple[str | int, ...]

#: More nodes than this (after expanding aliases) is refused, so that an alias bomb cannot exhaust memory.
MAX_NODES = 2_000_000


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


class SceneYamlLoader(yaml.SafeLoader):
    """``SafeLoader`` with YAML 1.2 core-schema booleans, integers and floats."""


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
    """Turns composed YAML nodes into plain data while filling a SourceMap."""

    def __init__(self, loader: SceneYamlLoader, source: SourceMap) -> None:
        self.loader = loader
        self.source = source
        self.issues: list[SceneIssue] = []
        self.node_count = 0

    def build(self, node: yaml.Node, path: KeyPath) -> Any:
        self.node_count += 1
        if self.node_count > MAX_NODES:
            raise SceneError([SceneIssue(self.source.filename, "",
                                         f"the document expands to more than {MAX_NODES} nodes (alias loop?)")])
        self.source.values.setdefault(path, _position(node.start_mark))
        if not isinstance(node, yaml.ScalarNode) and node.tag not in _PLAIN_COLLECTION_TAGS:
            # SafeLoader would refuse these too, but only when constructing; we build collections ourselves.
            where = _position(node.start_mark)
            raise SceneError([SceneIssue(f"{self.source.filename}:{where.line}:{where.column}", format_path(path),
                                         f"YAML tag not allowed: {node.tag!r}; scene files hold plain data only "
                                         "(mappings, lists, numbers, text)")])
        if isinstance(node, yaml.MappingNode):
            return self._mapping(node, path)
        if isinstance(node, yaml.SequenceNode):
            return [self.build(item, (*path, index)) for index, item in enumerate(node.value)]
        return self.loader.construct_object(node, deep=True)

    def _mapping(self, node: yaml.MappingNode, path: KeyPath) -> dict[Any, Any]:
        # Keys written in this mapping (as opposed to merged in with '<<: *anchor'); only these can be duplicates.
        own_keys = {id(key) for key, _ in node.value if key.tag != "tag:yaml.org,2002:merge"}
        self.loader.flatten_mapping(node)  # merged pairs first, then own pairs, so own values override merged ones
        result: dict[Any, Any] = {}
        own_seen: dict[Any, Position] = {}
        for key_node, value_node in node.value:
            key = self.loader.construct_object(key_node, deep=True)
            where = _position(key_node.start_mark)
            if not isinstance(key, str):
                self.issues.append(SceneIssue(f"{self.source.filename}:{where.line}:{where.column}",
                                              format_path(path),
                                              f"keys must be text, got {key!r} ({type(key).__name__})"))
                continue
            if id(key_node) in own_keys:
                if key in own_seen:
                    self.issues.append(SceneIssue(
                        f"{self.source.filename}:{where.line}:{where.column}", format_path((*path, key)),
                        f"duplicate key (first given at line {own_seen[key].line}); keep only one"))
                    continue
                own_seen[key] = where
            if key in result:  # replacing a merged value: positions must point at the new one
                self.source.forget_below((*path, key))
            self.source.keys[(*path, key)] = where
            result[key] = self.build(value_node, (*path, key))
        return result


def load_yaml(text: str, filename: str) -> tuple[Any, SourceMap]:
    """Parse one YAML document into plain data and a SourceMap; raise SceneError on any problem."""
    source = SourceMap(filename)
    loader = SceneYamlLoader(text)
    try:
        node = loader.get_single_node()
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


def _syntax_issue(error: yaml.MarkedYAMLError, filename: str) -> SceneIssue:
    mark = error.problem_mark or error.context_mark
    where = f"{filename}:{mark.line + 1}:{mark.column + 1}" if mark else filename
    problem = error.problem or "invalid YAML"
    if isinstance(error, yaml.constructor.ConstructorError) and "tag" in problem:
        message = (f"YAML tag not allowed: {problem.replace('could not determine a constructor for the tag ', '')}; "
                   "scene files hold plain data only (mappings, lists, numbers, text)")
    elif isinstance(error, yaml.composer.ComposerError) and "single document" in (error.context or ""):
        message = "the file holds more than one YAML document (---); a scene file holds exactly one"
    else:
        context = f" {error.context}" if error.context else ""
        message = f"YAML syntax error: {problem}{context}"
    return SceneIssue(where, "", message)
