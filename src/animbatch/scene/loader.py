"""Load a scene: read the file, apply overrides, validate against the schema, check cross-references.

Every problem found is collected and raised together as one :class:`~animbatch.errors.SceneError`, so that
``animbatch validate`` can list all of a file's errors at once.
"""

from __future__ import annotations

import difflib
import hashlib
import json
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from animbatch.errors import SceneError, SceneIssue
from animbatch.scene.checks import Problem, check_references
from animbatch.scene.diagnostics import issues_from_validation, sort_issues
from animbatch.scene.overrides import Override, apply_overrides, as_overrides
from animbatch.scene.schema import PRESENTATION_KEYS, SceneSpec
from animbatch.scene.yaml_source import SourceMap, format_path, load_yaml


@dataclass(frozen=True)
class LoadedScene:
    """A validated scene, where it came from, and how to point back into its file.

    It keeps its recipe (the text, the overrides applied, the checks it passed), so that :meth:`changed` can apply
    more overrides and validate again, and worker processes can rebuild it without reading the file again."""

    spec: SceneSpec
    source: SourceMap
    path: Path | None = None
    text: str = field(default="", repr=False)
    overrides: tuple[Override, ...] = ()
    geometry_checks: GeometryChecks | None = field(default=None, repr=False, compare=False)

    @property
    def name(self) -> str:
        assert self.spec.name is not None  # filled in by the loader
        return self.spec.name

    def changed(self, values: Mapping[str, Any] | Sequence[Override]) -> LoadedScene:
        """This scene with more values changed, validated again with every check it passed: ``values`` maps key
        paths, as ``--set`` writes them (``"bodies[ball].mass"``), to Python values (``{"solver.method":
        "RK45", "render.resolution": [640, 360]}``), or is a list of ``"key.path=value"`` texts. The scene itself
        is not changed. SceneError names each change that is not valid, with what is allowed."""
        return parse_scene(self.text, filename=self.source.filename, overrides=(*self.overrides, *as_overrides(values)),
                           default_name=self.name, path=self.path,
                           geometry_checks=self.geometry_checks)


#: Checks of a validated scene that need more than the file format (mesh files, pin selections): (spec, the scene's
#: folder) -> problems as (key path, message). The compiler provides them (:mod:`animbatch.compile.checks`).
GeometryChecks = Callable[[SceneSpec, Path], list[Problem]]


def load_scene(path: str | Path, overrides: Sequence[Override] = (), *,
               geometry_checks: GeometryChecks | None = None) -> LoadedScene:
    """Read and validate the scene file at ``path``, applying ``--set`` style ``overrides`` first.

    Use :func:`animbatch.stages.load_scene` (also ``animbatch.api.load_scene``), which adds the geometry checks; this
    one checks the format, names and references only, unless ``geometry_checks`` is given."""
    path = Path(path)
    text = _read(path)
    return parse_scene(text, filename=str(path), overrides=overrides, default_name=path.stem, path=path,
                       geometry_checks=geometry_checks)


def parse_scene(text: str, *, filename: str = "<scene>", overrides: Sequence[Override] = (),
                default_name: str = "scene", path: Path | None = None,
                geometry_checks: GeometryChecks | None = None) -> LoadedScene:
    """Validate scene text (YAML); ``filename`` is only used in messages, ``path``'s folder finds mesh files."""
    data, source = load_yaml(text, filename)
    if not isinstance(data, dict):
        raise SceneError([SceneIssue(source.source_of(()), "",
                                     f"the scene must be a mapping of keys (name:, bodies:, …), not a "
                                     f"{type(data).__name__}")])
    data = apply_overrides(data, overrides, source)
    issues = [SceneIssue(source.source_of(p), format_path(p), message) for p, message in check_references(data)]
    try:
        spec = SceneSpec.model_validate(data)
    except ValidationError as error:
        issues.extend(issues_from_validation(error, SceneSpec, source))
    if issues:
        raise SceneError(sort_issues(issues))
    file_problems = geometry_checks(spec, path.parent if path is not None else Path(".")) if geometry_checks else []
    if file_problems:
        raise SceneError(sort_issues([SceneIssue(source.source_of(p), format_path(p), message)
                                      for p, message in file_problems]))
    if spec.name is None:
        spec = spec.model_copy(update={"name": _as_name(default_name)})
    return LoadedScene(spec, source, path, text, tuple(overrides), geometry_checks)


def _read(path: Path) -> str:
    if not path.exists():
        raise SceneError([SceneIssue(str(path), "", "no such file" + _similar_files(path))])
    if path.is_dir():
        raise SceneError([SceneIssue(str(path), "", "is a directory; give a scene file (.yaml)")])
    try:
        return path.read_text(encoding="utf-8")
    except UnicodeDecodeError as error:
        problem = f"is not UTF-8 text ({error.reason} at byte {error.start})"
        raise SceneError([SceneIssue(str(path), "", problem)]) from None
    except OSError as error:
        raise SceneError([SceneIssue(str(path), "", f"cannot be read: {error.strerror}")]) from None


def _similar_files(path: Path) -> str:
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        return f" (the folder {str(folder)!r} does not exist either)"
    candidates = [p.name for p in folder.iterdir() if p.suffix in (".yaml", ".yml")]
    close = difflib.get_close_matches(path.name, candidates, n=1, cutoff=0.5)
    if close:
        return f"; did you mean {str(folder / close[0])!r}?"
    return ""


def _as_name(stem: str) -> str:
    """A file stem made into a valid scene name ('my scene.yaml' -> 'my-scene')."""
    name = re.sub(r"[^A-Za-z0-9_.\-]+", "-", stem).strip("-.") or "scene"
    return name if re.match(r"[A-Za-z_]", name) else f"scene-{name}"


def physics_fingerprint(spec: SceneSpec, base_dir: str | Path = ".") -> str:
    """SHA-256 of everything that determines the motion, and of nothing that only changes how it looks.

    Included: bodies, anchors, springs, fields, timeline, and the bytes of mesh files (found from ``base_dir``).
    Excluded: the name, description, solver settings (stored separately with a trajectory), render settings,
    colours, and how emitted particles look (their colours are drawn again from their serials when frames are
    drawn). Two scenes with the same fingerprint describe the same physical system over the same frame times.
    """
    data = _without_colors(spec.model_dump(mode="json", exclude=set(PRESENTATION_KEYS)))
    files = sorted(set(_mesh_files(data)))
    if files:
        data["mesh_file_digests"] = {name: _digest(Path(base_dir) / name) for name in files}
    canonical = json.dumps(data, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(canonical.encode()).hexdigest()


def mesh_files(spec: SceneSpec) -> list[str]:
    """The mesh files a scene reads (names relative to its folder), each once."""
    return sorted(set(_mesh_files(spec.model_dump(mode="json"))))


def _mesh_files(value: Any) -> list[str]:
    """File names of every mesh shape in dumped scene data."""
    if isinstance(value, dict):
        found = [value["file"]] if value.get("type") == "mesh" and isinstance(value.get("file"), str) else []
        return found + [name for item in value.values() for name in _mesh_files(item)]
    if isinstance(value, list):
        return [name for item in value for name in _mesh_files(item)]
    return []


def _digest(path: Path) -> str:
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError:
        return "missing"


#: Keys that change how a thing looks and never how it moves (``look``: an emitter's particles').
LOOK_KEYS = ("color", "look", "metallic", "roughness")


def _without_colors(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _without_colors(v) for k, v in value.items() if k not in LOOK_KEYS}
    if isinstance(value, list):
        return [_without_colors(v) for v in value]
    return value
