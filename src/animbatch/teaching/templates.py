"""Assignment templates, shipped inside the package (so that they work from an installed wheel): list them, and
copy one to start an assignment."""

from __future__ import annotations

import shutil
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import yaml

from animbatch.errors import AnimbatchError


@dataclass(frozen=True)
class Template:
    """A template: its ``name`` (the file name without .yaml), one line saying what it teaches, its task."""

    name: str
    description: str
    title: str
    task: str
    text: str


def _folder() -> resources.abc.Traversable:
    return resources.files("animbatch.teaching") / "templates"


def templates() -> list[Template]:
    """Every template, by name."""
    found = []
    for entry in sorted(_folder().iterdir(), key=lambda item: item.name):
        if not entry.name.endswith(".yaml"):
            continue
        text = entry.read_text(encoding="utf-8")
        data = yaml.safe_load(text) or {}
        assignment = data.get("assignment") or {}
        found.append(Template(entry.name[: -len(".yaml")], str(data.get("description", "")),
                              str(assignment.get("title", "")), str(assignment.get("task", "")), text))
    return found


def find(name: str) -> Template:
    """The template called ``name`` (a file name without .yaml, as ``animbatch new --list`` shows)."""
    known = templates()
    for template in known:
        if template.name == name or template.name == name.removesuffix(".yaml"):
            return template
    from difflib import get_close_matches

    close = get_close_matches(name, [t.name for t in known], n=1)
    hint = f"; did you mean {close[0]!r}?" if close else "."
    raise AnimbatchError(f"no template {name!r}{hint} Templates: {', '.join(t.name for t in known)} "
                         "('animbatch new --list' describes them)")


def start(name: str, destination: str | Path | None = None, *, force: bool = False) -> Path:
    """Copy template ``name`` to ``destination`` (a file, or a folder to put ``<name>.yaml`` in; default the current
    folder) and return the new file. An existing file is kept unless ``force``."""
    template = find(name)
    target = Path(destination) if destination is not None else Path(f"{template.name}.yaml")
    if target.is_dir():
        target = target / f"{template.name}.yaml"
    if target.exists() and not force:
        raise AnimbatchError(f"{target} exists; choose another name, or pass --force to replace it")
    target.parent.mkdir(parents=True, exist_ok=True)
    with resources.as_file(_folder() / f"{template.name}.yaml") as source:
        shutil.copyfile(source, target)
    return target
