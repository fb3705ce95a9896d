"""Scene files: YAML with positions, the schema, overrides, validation and cross-reference checks."""

from animbatch.scene.loader import LoadedScene, load_scene, parse_scene, physics_fingerprint
from animbatch.scene.schema import SceneSpec

__all__ = ["LoadedScene", "SceneSpec", "load_scene", "parse_scene", "physics_fingerprint"]
