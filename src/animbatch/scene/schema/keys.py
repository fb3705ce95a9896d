"""The building blocks of the scene format: :func:`key`, the strict base model, and the value types (names,
vectors, colours)."""

from __future__ import annotations

import difflib
from typing import Annotated, Any

import annotated_types as at
from pydantic import AfterValidator, BaseModel, ConfigDict, Field, PlainValidator, WithJsonSchema
from pydantic_core import PydanticCustomError, PydanticUndefined

NAME_PATTERN = r"^[A-Za-z_][A-Za-z0-9_.\-]*$"


def key(default: Any = PydanticUndefined, description: str = "", unit: str | None = None, *,
        example: Any = None, **constraints: Any) -> Any:
    """Declare a scene key: default, one-line description, SI unit (``None`` when it has none) and limits."""
    extra: dict[str, Any] = {}
    if unit is not None:
        extra["unit"] = unit
    if example is not None:
        extra["example"] = example
    return Field(default, description=description, json_schema_extra=extra or None, **constraints)


def rule_error(message: str, key: str | int | None = None) -> PydanticCustomError:
    """An error from a validator that breaks a rule between keys; ``key`` names the key it points at."""
    return PydanticCustomError("scene_rule", "{message}", {"message": message, "key": key})


class SceneModel(BaseModel):
    """Base of every scene section: unknown keys are errors, no silent type coercion, values are immutable."""

    model_config = ConfigDict(extra="forbid", strict=True, frozen=True, allow_inf_nan=False, validate_default=True)


# Value types

Vec3 = Annotated[list[float], at.Len(3, 3)]
PositiveVec3 = Annotated[list[Annotated[float, Field(gt=0)]], at.Len(3, 3)]
Name = Annotated[str, Field(pattern=NAME_PATTERN, max_length=64)]


def _nonzero_vector(vector: list[float]) -> list[float]:
    if not any(vector):
        raise rule_error("must not be the zero vector")
    return vector


#: A direction: three numbers, not all zero (need not be unit length).
NonZeroVec3 = Annotated[Vec3, AfterValidator(_nonzero_vector)]


def _check_color(value: Any) -> str:
    """Accept a CSS colour name, ``#rgb``/``#rrggbb``, or ``[r, g, b]`` in 0…1; return ``#rrggbb``."""
    from PIL import ImageColor  # light import; knows the CSS colour names

    if isinstance(value, str):
        try:
            rgb = ImageColor.getrgb(value)[:3]
        except ValueError:
            close = difflib.get_close_matches(value.lower(), ImageColor.colormap.keys(), n=1)
            hint = f"; did you mean '{close[0]}'?" if close else "."
            raise rule_error(f"unknown colour {value!r}{hint} Use a CSS name (e.g. 'tomato'), '#rrggbb' or "
                             "[r, g, b] in 0..1") from None
        return "#{:02x}{:02x}{:02x}".format(*rgb)
    if (isinstance(value, list | tuple) and len(value) == 3
            and all(isinstance(c, int | float) and not isinstance(c, bool) and 0 <= c <= 1 for c in value)):
        return "#{:02x}{:02x}{:02x}".format(*(round(255 * c) for c in value))
    raise rule_error(f"must be a colour: a CSS name, '#rrggbb' or [r, g, b] in 0..1 (got {value!r})")


Color = Annotated[
    str,
    PlainValidator(_check_color),
    WithJsonSchema({"anyOf": [{"type": "string"},
                              {"type": "array", "items": {"type": "number", "minimum": 0, "maximum": 1},
                               "minItems": 3, "maxItems": 3}]}),
]


def metallic_key() -> Any:
    """The ``metallic`` key of a body or collider (display only)."""
    return key(None, "Physically based look: 0 a dielectric (plastic, paint, wood), 1 a metal (default: its "
                     "material's, else plain shading).", "1", ge=0, le=1)


def roughness_key() -> Any:
    """The ``roughness`` key of a body or collider (display only)."""
    return key(None, "Physically based look: 0 mirror-smooth, 1 fully matte (default: its material's, else plain "
                     "shading).", "1", ge=0, le=1)


def charge_key() -> Any:
    """The ``charge`` key of a particle or rigid body."""
    return key(0.0, "Electric charge, felt by electromagnetic and coulomb fields (a rigid body's sits at its centre "
                    "of mass).", "C")
