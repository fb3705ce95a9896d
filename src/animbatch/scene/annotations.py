"""Reading the schema's type annotations: shared by error messages (diagnostics) and the docs generator (reference).

Schema fields are declared as ``Annotated[...]``, ``X | None`` and discriminated unions; these helpers look through
those wrappers to the parts that matter (member types, constraints, list lengths, union tags).
"""

from __future__ import annotations

import types
import typing
from typing import Any

import annotated_types as at
from pydantic import BaseModel
from pydantic.fields import FieldInfo


def strip_annotated(annotation: Any) -> Any:
    """``Annotated[X, ...]`` -> ``X`` (repeatedly)."""
    while typing.get_origin(annotation) is typing.Annotated:
        annotation = annotation.__origin__
    return annotation


def union_members(annotation: Any, *, keep_none: bool = False) -> tuple[Any, ...]:
    """The members of a union (``X | Y | None``), or the annotation itself; ``None`` is left out unless asked."""
    if typing.get_origin(annotation) in (typing.Union, types.UnionType):
        return tuple(a for a in typing.get_args(annotation) if keep_none or a is not type(None))
    return (annotation,)


def model_members(annotation: Any) -> tuple[type[BaseModel], ...]:
    """The model classes an annotation can hold, looking through Annotated, Optional and unions."""
    members = (strip_annotated(m) for m in union_members(strip_annotated(annotation)))
    return tuple(m for m in members if isinstance(m, type) and issubclass(m, BaseModel))


def tag_of(model: type[BaseModel]) -> str | None:
    """The ``type`` tag of a union member model (``Literal["gravity"]`` -> ``"gravity"``), if it has one."""
    field = model.model_fields.get("type")
    args = typing.get_args(strip_annotated(field.annotation)) if field is not None else ()
    return args[0] if args else None


def field_metadata(field: FieldInfo) -> list[Any]:
    """Constraints of a field, including those inside an optional member (``Annotated[...] | None``)."""
    items = list(field.metadata)
    for member in union_members(field.annotation):
        items.extend(getattr(member, "__metadata__", ()))
    return items


def length_limits(field: FieldInfo | None) -> tuple[int | None, int | None]:
    """Declared (min, max) item count of a list field."""
    if field is None:
        return None, None
    for item in field_metadata(field):
        if isinstance(item, at.Len):
            return item.min_length, item.max_length
    return None, None
