"""A cached bake is reused only by the code that made it."""

from __future__ import annotations

import shutil
from pathlib import Path

from animbatch import __version__, provenance
from animbatch.farm import cache
from animbatch.stages import load_scene, simulate

SCENE = """\
duration: 0.2
fps: 10
bodies: [{name: ball, type: particle, mass: 1, position: [0, 1, 0]}]
fields: [{type: gravity}]
"""


def test_the_fingerprint_follows_the_simulation_sources_only(tmp_path, monkeypatch):
    """Copied into another folder, the package has the same fingerprint; a changed solver file gives another, a
    changed renderer file does not."""
    package = Path(provenance.__file__).parent
    copy = tmp_path / "animbatch"
    shutil.copytree(package, copy, ignore=shutil.ignore_patterns("__pycache__"))

    def fingerprint() -> str:
        provenance.simulation_code.cache_clear()
        monkeypatch.setattr(provenance, "__file__", str(copy / "provenance.py"))
        return provenance.simulation_code()

    original = fingerprint()
    assert original.startswith(__version__ + "+") and len(original) == len(__version__) + 13
    provenance.simulation_code.cache_clear()
    monkeypatch.undo()
    assert provenance.simulation_code() == original  # the installed package: the same sources

    drawing = next((copy / "render").rglob("*.py"))
    drawing.write_text(drawing.read_text() + "\n# a comment\n")
    assert fingerprint() == original
    solver = copy / "sim" / "integrators" / "fixed_step.py"
    solver.write_text(solver.read_text() + "\n# a comment\n")
    assert fingerprint() != original
    provenance.simulation_code.cache_clear()


def test_a_bake_by_other_code_is_not_reused(tmp_path, monkeypatch):
    path = tmp_path / "ball.yaml"
    path.write_text(SCENE)
    scene = load_scene(path)
    bake = tmp_path / "bake.npz"
    simulate(scene).save(bake)
    assert cache.load_cached(scene, bake) is not None
    monkeypatch.setattr(cache, "simulation_code", lambda: f"{__version__}+000000000000")
    assert cache.load_cached(scene, bake) is None
