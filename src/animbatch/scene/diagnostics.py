"""Turn pydantic validation errors into scene issues: position, key path, what is allowed, what was given, a fix.

Pydantic reports an error location such as ``("fields", 0, "drag", "coefficient")``, in which ``"drag"`` is the
discriminated-union tag, not a key. :func:`locate` walks the schema along that location to recover the key path in the
file (``fields[0].coefficient``), the model that owns the key (for the list of allowed keys) and the key's declared
unit, so that every message can say what would have been accepted.
"""

from __future__ import annotations

import difflib
import typing
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from pydantic import BaseModel, ValidationError
from pydantic.fields import FieldInfo

from animbatch.errors import SceneIssue
from animbatch.scene.annotations import length_limits, model_members, strip_annotated, tag_of, union_members
from animbatch.scene.yaml_source import KeyPath, SourceMap, format_path

#: What one item of a top-level list is called in messages ("unknown field type 'gravty'").
ITEM_WORDS = {"bodies": "body", "fields": "field", "springs": "spring", "anchors": "anchor", "shape": "shape"}


@dataclass(frozen=True)
class Located:
    """Where a pydantic error location points in the scene data and schema."""

    path: KeyPath
    owner: type[BaseModel] | None  # the model that owns the last key of ``path``
    field: FieldInfo | None  # the last named field on the way (gives the unit of list items too)
    union_members: tuple[type[BaseModel], ...] = ()  # set when the location ends at a discriminated union
    branch: str | None = None  # the member of a plain union (``number | list``) the error came from, if any


def locate(root: type[BaseModel], loc: tuple[str | int, ...]) -> Located:
    """Follow ``loc`` through the schema rooted at ``root``."""
    annotation: Any = root
    path: list[str | int] = []
    owner: type[BaseModel] | None = None
    field: FieldInfo | None = None
    branch = None
    for part in loc:
        models = model_members(annotation)
        inner = union_members(strip_annotated(annotation))
        if len(models) <= 1 and len(inner) > 1 and isinstance(part, str) and not (
                models and part in models[0].model_fields):
            # a plain union (number | list): pydantic names the member it tried ('float', 'list[...]'); not a key
            listed = [a for a in inner if typing.get_origin(strip_annotated(a)) in (list, tuple)]
            is_list = "list[" in part or "tuple[" in part
            branch = "list" if is_list else "single"
            annotation = (listed[0] if is_list and listed else
                          next((a for a in inner if a not in listed), inner[0]))
            continue
        if len(models) > 1:  # discriminated union: this part is the tag, not a key
            chosen = next((m for m in models if tag_of(m) == part), None)
            if chosen is not None:
                annotation = chosen
                continue
            return Located(tuple(path), owner, field, models)
        if len(models) == 1 and isinstance(part, str):
            owner = models[0]
            path.append(part)
            field = owner.model_fields.get(part)
            annotation = field.annotation if field is not None else None
            if field is not None:
                annotation = typing.Annotated[annotation, *field.metadata] if field.metadata else annotation
            continue
        path.append(part)
        sequence = next((a for a in inner if typing.get_origin(strip_annotated(a)) in (list, tuple)), None)
        args = typing.get_args(strip_annotated(sequence)) if sequence is not None else ()
        annotation = args[0] if args else None
    models = model_members(annotation)
    return Located(tuple(path), owner, field, models if len(models) > 1 else (), branch)


def unit_of(field: FieldInfo | None) -> str:
    extra = field.json_schema_extra if field is not None and isinstance(field.json_schema_extra, dict) else {}
    unit = extra.get("unit")
    return f" {unit}" if unit and unit != "1" else ""


def show(value: Any) -> str:
    """A value as the user wrote it, shortened."""
    if isinstance(value, str):
        text = repr(value)
    elif isinstance(value, bool):
        text = "true" if value else "false"
    elif value is None:
        text = "null (empty)"
    elif isinstance(value, dict):
        text = "a mapping {" + ", ".join(map(str, value)) + "}"
    else:
        text = str(value)
    return text if len(text) <= 80 else text[:77] + "..."


def did_you_mean(word: Any, choices: typing.Iterable[str]) -> str:
    """``"; did you mean 'x'?"`` for the closest choice, or ``""``."""
    if not isinstance(word, str):
        return ""
    choices = list(choices)
    folded = {c.lower(): c for c in choices}
    close = difflib.get_close_matches(word.lower(), folded, n=1, cutoff=0.6)
    return f"; did you mean '{folded[close[0]]}'?" if close else ""


def _allowed_keys(model: type[BaseModel] | None) -> list[str]:
    return list(model.model_fields) if model is not None else []


def _literal_choices(error_ctx: dict[str, Any]) -> list[str]:
    expected = error_ctx.get("expected", "")
    return [part.strip().strip("'") for part in expected.replace(" or ", ", ").split(",") if part.strip()]


def describe(error: dict[str, Any], located: Located) -> tuple[KeyPath, str, bool]:
    """Message for one pydantic error: ``(key path, message, point at the key rather than the value)``."""
    kind = error["type"]
    ctx = error.get("ctx") or {}
    given = error.get("input")
    unit = unit_of(located.field)
    path = located.path

    if kind == "extra_forbidden":
        allowed = _allowed_keys(located.owner)
        return path, (f"unknown key {show(path[-1])}{did_you_mean(path[-1], allowed)} "
                      f"Allowed keys here: {', '.join(allowed)}"), True
    if kind == "missing":
        field = located.owner.model_fields.get(str(path[-1])) if located.owner else None
        about = f" ({field.description.rstrip('.')}{unit_of(field)})" if field and field.description else ""
        return path, f"required key missing: add '{path[-1]}'{about}", False
    if kind in ("union_tag_invalid", "union_tag_not_found"):
        word = ITEM_WORDS.get(next((p for p in reversed(path) if isinstance(p, str)), ""), "item")
        tags = [t for t in (tag_of(m) for m in located.union_members) if t]
        if kind == "union_tag_not_found":
            return (*path, "type"), f"missing key 'type': say which kind of {word} this is ({', '.join(tags)})", False
        tag = ctx.get("tag")
        return (*path, "type"), (f"unknown {word} type {show(tag)}{did_you_mean(tag, tags)} "
                                 f"Allowed: {', '.join(tags)}"), False
    if kind == "literal_error":
        choices = _literal_choices(ctx)
        return path, f"must be one of {', '.join(choices)} (got {show(given)}){did_you_mean(given, choices)}", False
    bounds = {"greater_than": ">", "greater_than_equal": ">=", "less_than": "<", "less_than_equal": "<="}
    if kind in bounds:
        limit = next(iter(v for k, v in ctx.items() if k in ("gt", "ge", "lt", "le")), "?")
        limit = f"{limit:g}" if isinstance(limit, int | float) else limit
        return path, f"must be {bounds[kind]} {limit}{unit} (got {show(given)})", False
    if kind in ("float_type", "float_parsing"):
        return path, f"must be a number{unit and ' in' + unit} (got {show(given)})", False
    if kind in ("int_type", "int_parsing", "int_from_float"):
        return path, f"must be a whole number{unit and ' in' + unit} (got {show(given)})", False
    if kind == "finite_number":
        return path, f"must be a finite number (got {show(given)})", False
    if kind == "bool_type":
        return path, f"must be true or false (got {show(given)})", False
    if kind == "string_type":
        return path, f"must be text (got {show(given)})", False
    if kind == "string_pattern_mismatch":
        return path, ("names start with a letter or '_' and contain only letters, digits, '_', '-' and '.' "
                      f"(got {show(given)})"), False
    if kind == "string_too_long":
        return path, f"must be at most {ctx.get('max_length')} characters (got {len(str(given))})", False
    if kind in ("list_type", "tuple_type"):
        shape = " of 3 numbers [x, y, z]" if length_limits(located.field) == (3, 3) else ""
        return path, f"must be a list{shape} (got {show(given)})", False
    if kind in ("too_short", "too_long"):
        low, high = length_limits(located.field)
        actual = ctx.get("actual_length")
        if (low, high) == (3, 3):
            return path, f"must be a list of 3 numbers [x, y, z]{unit and ' in' + unit} (got {show(given)})", False
        if low is not None and low == high:
            return path, f"must have exactly {low} items (got {actual}: {show(given)})", False
        which = "at least" if kind == "too_short" else "at most"
        count = ctx.get("min_length") if kind == "too_short" else ctx.get("max_length")
        return path, f"must have {which} {count} items (got {actual})", False
    if kind in ("model_type", "dict_type", "model_attributes_type"):
        allowed = _allowed_keys(model_members(located.field.annotation)[0]) if located.field and model_members(
            located.field.annotation) else []
        keys = f" with keys {', '.join(allowed)}" if allowed else ""
        return path, f"must be a mapping{keys} (got {show(given)})", False
    if kind == "scene_rule":  # raised by the schema's own validators (see schema.rule_error)
        extra = ctx.get("key")
        return (*path, extra) if extra is not None else path, ctx["message"], False
    message = error["msg"].removeprefix("Value error, ")
    return path, f"{message} (got {show(given)})", False


def issues_from_validation(error: ValidationError, root: type[BaseModel], source: SourceMap) -> list[SceneIssue]:
    """One SceneIssue per pydantic error, in file order."""
    found: dict[KeyPath, list[tuple[str, bool, bool]]] = {}  # path -> (message, at key, a type mismatch)
    for item in error.errors(include_url=False):
        located = locate(root, tuple(item["loc"]))
        path, message, at_key = describe(dict(item), located)
        mismatch = located.branch is not None and str(item["type"]).endswith("_type")
        found.setdefault(path, []).append((message, at_key, mismatch))
    issues = []
    for path, messages in found.items():
        # A value of the right kind for one member of 'number | list' that breaks a rule there gets that rule only,
        # not "must be a number" from the member it was never meant for; a value that fits no member gets one
        # message naming them all.
        deeper = any(len(other) > len(path) and other[:len(path)] == path for other in found)
        kept = [m for m in messages if not m[2]]
        if not kept and not deeper:
            kept = [(_either(m[0] for m in messages), messages[0][1], True)]
        issues += [SceneIssue(source.source_of(path, key=at_key), format_path(path), message)
                   for message, at_key, _ in kept]
    return sort_issues(issues)


def _either(messages: Iterable[str]) -> str:
    """'must be a number (got 'x')' and 'must be a list (got 'x')' -> 'must be a number, or a list (got 'x')'."""
    wanted, got = [], ""
    for message in messages:
        head, _, tail = message.partition(" (got ")
        wanted.append(head.removeprefix("must be "))
        got = got or (f" (got {tail}" if tail else "")
    return "must be " + ", or ".join(dict.fromkeys(wanted)) + got


def sort_issues(issues: list[SceneIssue]) -> list[SceneIssue]:
    """File order (line, column); issues from overrides and without position come last, in their given order."""

    def order(issue: SceneIssue) -> tuple[int, int, int]:
        parts = issue.source.rsplit(":", 2)
        if len(parts) == 3 and parts[1].isdigit() and parts[2].isdigit():
            return (0, int(parts[1]), int(parts[2]))
        return (1, 0, 0)

    return sorted(issues, key=order)
