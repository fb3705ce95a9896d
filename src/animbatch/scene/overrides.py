"""``--set key.path=value``: change any scene value from the command line before validation.

Paths use dots and brackets: ``solver.method``, ``bodies[0].mass``, ``bodies.0.mass``, or ``bodies[ball].mass`` (a
list item chosen by its ``name``); the index one past a list's end appends an item (``fields[1]={type: drag}`` on a
scene with one field). The value is read as YAML (``1e-3``, ``[640, 360]``, ``true``, ``DOP853``), and the
result is validated exactly like the file, with errors that point at the override. In an unquoted text value, ``\n``
starts a new line, as in a double-quoted YAML string (a shell cannot easily pass a newline; a quoted value is
read as YAML reads it).
"""

from __future__ import annotations

import json
import re
from collections.abc import Mapping, Sequence
from typing import Any

import yaml

from animbatch.errors import SceneError, SceneIssue
from animbatch.scene.yaml_source import KeyPath, SourceMap, format_path, load_yaml

_TOKEN = re.compile(r"([^.\[\]]+)|\[([^\]]*)\]")


def parse_key_path(text: str) -> list[str | int]:
    """``"bodies[0].mass"`` -> ``["bodies", 0, "mass"]``; numeric parts become indices."""
    parts: list[str | int] = []
    position = 0
    for match in _TOKEN.finditer(text):
        gap = text[position:match.start()]
        if gap not in ("", "."):
            raise ValueError(f"cannot read the key path {text!r} near {gap!r}")
        name = match.group(1) if match.group(1) is not None else match.group(2)
        if name == "":
            raise ValueError(f"empty part in the key path {text!r}")
        parts.append(int(name) if name.lstrip("-").isdigit() else name)
        position = match.end()
    if not parts or text[position:] not in ("",):
        raise ValueError(f"cannot read the key path {text!r}")
    return parts


Override = str | tuple[str, str]


def as_overrides(values: Mapping[str, Any] | Sequence[Override]) -> list[Override]:
    """Changes given from Python as overrides: a mapping of key paths to Python values (numbers, text, lists,
    mappings, None, numpy arrays) becomes ``key.path=value`` with the value written as YAML, so that it is read back
    as the same value (the text ``"yes"`` stays text); a sequence of overrides is returned as it is."""
    if not isinstance(values, Mapping):
        if isinstance(values, str):  # one "key=value" text, not a sequence of its characters
            return [values]
        return list(values)
    changes: list[Override] = []
    for key, value in values.items():
        plain = _plain(value)
        if isinstance(plain, str):  # quoted, so that it is read as this text exactly (no \n rewriting either)
            text = json.dumps(plain, ensure_ascii=False)
        else:
            text = yaml.safe_dump(plain, default_flow_style=True, width=float("inf"), allow_unicode=True)
            text = text.strip().removesuffix("...").strip()  # a lone value ends its document with "..."
        changes.append((f"{key}={text}", f"{key} = {text} (set from Python)"))
    return changes


def _plain(value: Any) -> Any:
    """``value`` with numpy arrays and scalars, tuples and other mappings as the plain types YAML writes."""
    if hasattr(value, "tolist"):  # numpy arrays and scalars
        return value.tolist()
    if isinstance(value, Mapping):
        return {str(key): _plain(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(item) for item in value]
    return value


def apply_overrides(data: Any, overrides: Sequence[Override], source: SourceMap) -> Any:
    """Apply each ``key.path=value`` to the loaded data (in place where possible) and return the data.

    An override is ``"key.path=value"``, or ``("key.path=value", label)`` where ``label`` is how the user wrote it
    (``"--dt 0.01"``), used in error messages; the default label is ``"--set key.path=value"``.
    """
    issues = []
    for item in overrides:
        text, label = item if isinstance(item, tuple) else (item, f"--set {item}")
        try:
            data = _apply_one(data, text, source, label)
        except _OverrideProblem as problem:
            issues.append(SceneIssue(label, problem.path, problem.message))
    if issues:
        raise SceneError(issues)
    return data


class _OverrideProblem(Exception):
    def __init__(self, path: str, message: str) -> None:
        super().__init__(message)
        self.path = path
        self.message = message


def _apply_one(data: Any, text: str, source: SourceMap, label: str) -> Any:
    if "=" not in text:
        raise _OverrideProblem("", "expected key.path=value, e.g. --set solver.method=DOP853")
    raw_path, raw_value = text.split("=", 1)
    try:
        parts = parse_key_path(raw_path.strip())
    except ValueError as error:
        raise _OverrideProblem("", str(error)) from None
    try:  # the same reader as scene files: same limits, same number range
        value = load_yaml(raw_value, label)[0] if raw_value.strip() else None
    except SceneError as error:
        reason = "; ".join(issue.message for issue in error.issues)
        raise _OverrideProblem(raw_path, f"cannot read the value as YAML: {reason}") from None
    if isinstance(value, str) and not raw_value.strip().startswith(("'", '"')):
        value = value.replace("\\n", "\n")  # --set render.time_label=t = {t:.2f} s\nE = {E:.3f} J
    if not isinstance(data, dict):
        raise _OverrideProblem("", "the scene's top level is not a mapping")

    resolved: list[str | int] = []
    container: Any = data
    for depth, part in enumerate(parts):
        last = depth == len(parts) - 1
        here = format_path(tuple(resolved)) or "the scene"
        if isinstance(container, dict):
            if isinstance(part, int):
                raise _OverrideProblem(format_path((*resolved, part)), f"{here} is a mapping, not a list")
            if last:
                container[part] = value
            else:
                container = container.setdefault(part, {})
            resolved.append(part)
        elif isinstance(container, list):
            if part == len(container):  # one past the end appends: fields[1]=... adds a second field
                container.append(None if last else {})
            index = _list_index(container, part, here, resolved)
            resolved.append(index)
            if last:
                container[index] = value
            else:
                container = container[index]
        else:
            raise _OverrideProblem(format_path((*resolved, part)), f"{here} is a single value, not a mapping or list")
    path: KeyPath = tuple(resolved)
    source.forget_below(path)
    source.overrides[path] = label
    return data


def _list_index(items: list[Any], part: str | int, here: str, resolved: list[str | int]) -> int:
    if isinstance(part, int):
        if not -len(items) <= part < len(items):
            count = f"{len(items)} item{'' if len(items) == 1 else 's'}"
            raise _OverrideProblem(format_path((*resolved, part)), f"index {part} is out of range: {here} has {count}")
        return part % len(items)
    names = [item.get("name") for item in items if isinstance(item, dict)]
    for index, item in enumerate(items):
        if isinstance(item, dict) and item.get("name") == part:
            return index
    known = ", ".join(str(n) for n in names if n is not None) or "(no named items)"
    raise _OverrideProblem(f"{format_path(tuple(resolved))}[{part}]",
                           f"no item named {part!r} in {here}; names: {known}")
