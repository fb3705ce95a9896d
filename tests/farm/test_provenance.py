"""A cached bake is reused only by the code that made it, and a frame only when drawn by this code from a bake by
this code."""

from __future__ import annotations

import dataclasses
import shutil
from pathlib import Path

from animbatch import __version__, provenance
from animbatch.farm import cache, frame_files
from animbatch.stages import load_scene, simulate

SCENE = """\
duration: 0.2
fps: 10
bodies: [{name: ball, type: particle, mass: 1, position: [0, 1, 0]}]
fields: [{type: gravity}]
"""


def test_the_fingerprints_follow_the_simulation_and_the_drawing_sources_only(tmp_path, monkeypatch):
    """Copied into another folder, the package has the same fingerprints; a changed renderer file changes the
    drawing's and not the simulation's, a changed solver file the simulation's and not the drawing's."""
    package = Path(provenance.__file__).parent
    copy = tmp_path / "animbatch"
    shutil.copytree(package, copy, ignore=shutil.ignore_patterns("__pycache__"))

    def fingerprints() -> tuple[str, str]:
        provenance.simulation_code.cache_clear()
        provenance.drawing_code.cache_clear()
        monkeypatch.setattr(provenance, "__file__", str(copy / "provenance.py"))
        return provenance.simulation_code(), provenance.drawing_code()

    simulation, drawing = fingerprints()
    for fingerprint in (simulation, drawing):
        assert fingerprint.startswith(__version__ + "+") and len(fingerprint) == len(__version__) + 13
    assert simulation != drawing
    provenance.simulation_code.cache_clear()
    provenance.drawing_code.cache_clear()
    monkeypatch.undo()
    assert (provenance.simulation_code(), provenance.drawing_code()) == (simulation, drawing)  # the same sources

    renderer = next((copy / "render").rglob("*.py"))
    renderer.write_text(renderer.read_text() + "\n# a comment\n")
    changed_simulation, changed_drawing = fingerprints()
    assert changed_simulation == simulation and changed_drawing != drawing
    solver = copy / "sim" / "integrators" / "fixed_step.py"
    solver.write_text(solver.read_text() + "\n# a comment\n")
    after_solver = fingerprints()
    assert after_solver[0] != simulation and after_solver[1] == changed_drawing
    provenance.simulation_code.cache_clear()
    provenance.drawing_code.cache_clear()


def test_a_bake_by_other_code_is_not_reused(tmp_path, monkeypatch):
    path = tmp_path / "ball.yaml"
    path.write_text(SCENE)
    scene = load_scene(path)
    bake = tmp_path / "bake.npz"
    simulate(scene).save(bake)
    assert cache.load_cached(scene, bake) is not None
    monkeypatch.setattr(cache, "simulation_code", lambda: f"{__version__}+000000000000")
    assert cache.load_cached(scene, bake) is None


def test_frames_are_kept_only_for_a_bake_by_this_code_drawn_by_this_code(tmp_path, monkeypatch):
    """A frame in the folder stays while the scene, the code that simulated its bake and the code that draws are the
    same; a bake by other simulation code (the physics changed) or other drawing code clears the folder (before, the
    key held the version alone, and a render after a change to the physics kept the old frames)."""
    path = tmp_path / "ball.yaml"
    path.write_text(SCENE)
    scene = load_scene(path)
    trajectory = simulate(scene)

    def kept(bake, drawn_by: str) -> bool:
        folder = frame_files.frames_folder(scene, tmp_path / "renders")
        folder.mkdir(parents=True, exist_ok=True)
        (folder / "frame_00000.png").write_bytes(b"drawn")
        monkeypatch.setattr(frame_files, "drawing_code", lambda: drawn_by)
        frame_files.prepare_frames(scene, bake, tmp_path / "renders")
        return (folder / "frame_00000.png").is_file()

    this = provenance.drawing_code()
    kept(trajectory, this)  # the first time the folder takes this picture's key
    assert kept(trajectory, this)
    assert not kept(dataclasses.replace(trajectory, package_version=f"{__version__}+000000000000"), this)
    kept(trajectory, this)
    assert not kept(trajectory, f"{__version__}+000000000000")
