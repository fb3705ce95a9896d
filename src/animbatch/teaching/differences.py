"""What a submission changed from the reference scene, key path by key path, and whether the assignment lets it.

An assignment names what the student may change (``assignment.edit``: key paths in ``--set``'s syntax, e.g.
``bodies[bob].position``, ``springs[*].stiffness``); everything else a check depends on (a stopwatch's definition,
a field's strength, the frame rate, the solver, a body's name or mass) must stay as the reference has it. Both
scenes are compared as validated data, defaults filled in, so that writing a default out is not a change. Left out:
the scene's name and description, how it is drawn (``render``, colours), studies and sweeps, and the assignment
itself (the reference's is the one that counts).

List items that have a ``name`` are matched by name (``bodies[bob]``), others by position (``springs[0]``).
"""

from __future__ import annotations

import json
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any

from animbatch.scene.loader import LOOK_KEYS
from animbatch.scene.overrides import parse_key_path

#: Top-level keys that never change what a check measures.
NOT_COMPARED = ("name", "description", "render", "study", "sweep", "assignment")
#: In an ``edit`` path, any item of a list (``springs[*].stiffness``).
ANY = "*"


@dataclass(frozen=True)
class Named:
    """A list item chosen by its name, as a part of a key path (``bodies[bob]``)."""

    name: str


Part = str | int | Named
Path = tuple[Part, ...]


class _Absent:
    def __repr__(self) -> str:
        return "absent"


#: What one side has where the other has a value (an item or a key the other lacks).
ABSENT: Any = _Absent()


@dataclass(frozen=True)
class Difference:
    """One value that differs: where (key path parts), the reference's value and the submission's (ABSENT where
    one side has nothing there)."""

    path: Path
    reference: Any
    submission: Any

    @property
    def where(self) -> str:
        """The key path as ``--set`` writes it: ``bodies[bob].position``, ``springs[0].damping``."""
        text = ""
        for part in self.path:
            if isinstance(part, Named):
                text += f"[{part.name}]"
            elif isinstance(part, int):
                text += f"[{part}]"
            else:
                text += f".{part}" if text else part
        return text

    def describe(self) -> str:
        """``bodies[bob].mass: 0.8 (the reference: 0.5)``."""
        return f"{self.where}: {_shown(self.submission)} (the reference: {_shown(self.reference)})"


def _shown(value: Any) -> str:
    if value is ABSENT:
        return "absent"
    return json.dumps(value, ensure_ascii=False, separators=(", ", ": "))


def scene_differences(reference: dict[str, Any], submission: dict[str, Any]) -> list[Difference]:
    """Every value of ``submission`` (a scene's validated data, ``model_dump(mode="json")``) that differs from
    ``reference``'s, in the reference's order, without :data:`NOT_COMPARED` and colours."""
    found: list[Difference] = []
    for key in dict.fromkeys([*reference, *submission]):
        if key not in NOT_COMPARED:
            found += [Difference(path, a, b) for path, a, b in
                      _walk((key,), reference.get(key, ABSENT), submission.get(key, ABSENT))]
    return found


def _walk(path: Path, a: Any, b: Any) -> Iterator[tuple[Path, Any, Any]]:
    if isinstance(a, dict) and isinstance(b, dict):
        for key in dict.fromkeys([*a, *b]):
            if key not in LOOK_KEYS:
                yield from _walk((*path, key), a.get(key, ABSENT), b.get(key, ABSENT))
    elif isinstance(a, list) and isinstance(b, list) and not (_scalars(a) and _scalars(b)):
        named_a, named_b = _by_name(a), _by_name(b)
        if named_a is not None and named_b is not None:
            for name in dict.fromkeys([*named_a, *named_b]):
                yield from _walk((*path, Named(name)), named_a.get(name, ABSENT), named_b.get(name, ABSENT))
        else:
            for index in range(max(len(a), len(b))):
                yield from _walk((*path, index), a[index] if index < len(a) else ABSENT,
                                 b[index] if index < len(b) else ABSENT)
    elif a != b:
        yield path, a, b


def _scalars(items: list[Any]) -> bool:
    """A list of plain values (a vector, a list of names): compared and shown whole."""
    return not any(isinstance(item, (dict, list)) for item in items)


def _by_name(items: list[Any]) -> dict[str, Any] | None:
    """The items by their names, when every item is a mapping with a distinct name; else None."""
    if not all(isinstance(item, dict) and isinstance(item.get("name"), str) for item in items):
        return None
    named = {item["name"]: item for item in items}
    return named if len(named) == len(items) else None


def allowed(difference: Difference, edit: Sequence[str], reference: dict[str, Any]) -> bool:
    """Whether the assignment's ``edit`` paths cover ``difference``: one of them leads to it or to what holds it
    (``bodies[bob]`` covers ``bodies[bob].mass``; ``[*]`` stands for any item). Numbers in brackets are read against
    the reference's lists: ``bodies[0]`` is the reference's first body, by its name where it has one."""
    for text in edit:
        wanted = editable_path(text, reference)
        if len(wanted) <= len(difference.path) and all(
                want == ANY and not isinstance(have, str) or want == have
                for want, have in zip(wanted, difference.path)):
            return True
    return False


def editable_path(text: str, reference: dict[str, Any]) -> Path:
    """An ``edit`` entry as the path parts of :func:`scene_differences`: ``bodies[0].position`` -> (``bodies``,
    the first body by its name, ``position``)."""
    parts: list[Part] = []
    here: Any = reference
    for part in parse_key_path(text):
        named = _by_name(here) if isinstance(here, list) else None
        if part == ANY:
            parts.append(ANY)
            here = None
        elif named is not None and isinstance(part, int) and -len(here) <= part < len(here):
            parts.append(Named(here[part]["name"]))
            here = here[part]
        elif named is not None and isinstance(part, str):
            parts.append(Named(part))
            here = named.get(part)
        elif isinstance(here, list) and isinstance(part, int):
            parts.append(part)
            here = here[part] if -len(here) <= part < len(here) else None
        else:
            parts.append(part)
            here = here.get(part) if isinstance(here, dict) and isinstance(part, str) else None
    return tuple(parts)
