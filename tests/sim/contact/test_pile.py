"""A mixed pile (issue 22, contact between any shapes): boxes, balls, cylinders, capsules and convex meshes dropped
into a bin settle with no body inside another or a wall, all inside the bin, and the total energy never rises
(contacts only take energy away)."""

from __future__ import annotations

import shutil
import warnings

import numpy as np
import pytest

from animbatch import api
from animbatch.errors import AccuracyWarning
from animbatch.stages import quantity_series
from support.paths import REPO

SHAPES = ["{type: box, size: [0.16, 0.1, 0.12]}", "{type: sphere, radius: 0.06}",
          "{type: cylinder, radius: 0.05, length: 0.2}", "{type: capsule, radius: 0.045, length: 0.22}",
          "{type: mesh, file: gem.obj}"]


@pytest.mark.slow
def test_a_mixed_pile_dropped_in_a_bin_settles_without_overlap_or_energy_gain(tmp_path):
    shutil.copy(REPO / "scenes" / "meshes" / "gem.obj", tmp_path)
    bodies = []
    for k, (x, y, z, turn) in enumerate([(-0.2, 0.2, 0.0, 30), (0.0, 0.3, 0.04, 0), (0.2, 0.22, -0.03, 60),
                                         (-0.12, 0.5, 0.02, 45), (0.1, 0.55, 0.0, 10), (0.0, 0.8, -0.02, 75),
                                         (-0.2, 0.85, 0.05, 20), (0.2, 0.9, -0.05, 50)]):
        bodies.append(f"  - {{name: body{k}, type: rigid, shape: {SHAPES[k % len(SHAPES)]}, density: 600, "
                      f"material: {'rubber' if k % len(SHAPES) == 1 else 'wood'}, position: [{x}, {y}, {z}], "
                      f"orientation: {{axis: [0.3, 1, 0.2], angle: {turn}}}}}")
    walls = "\n".join(f"  - {{type: box, position: {p}, size: {s}, material: wood}}" for p, s in [
        ("[-0.45, 0.2, 0]", "[0.1, 0.4, 0.8]"), ("[0.45, 0.2, 0]", "[0.1, 0.4, 0.8]"),
        ("[0, 0.2, -0.35]", "[0.8, 0.4, 0.1]"), ("[0, 0.2, 0.35]", "[0.8, 0.4, 0.1]")])
    (tmp_path / "pile.yaml").write_text("duration: 1.5\nfps: 30\nsolver: {method: symplectic_euler, dt: 1.0e-3}\n"
                                        "bodies:\n" + "\n".join(bodies) + "\ncolliders:\n  - {type: plane, "
                                        "material: wood}\n" + walls + "\nfields: [{type: gravity}]\n")
    loaded = api.load_scene(tmp_path / "pile.yaml")
    model = api.compile_scene(loaded.spec, tmp_path)
    with warnings.catch_warnings():
        warnings.simplefilter("error", AccuracyWarning)  # a body inside another or a wall, or a missed contact, would warn
        trajectory = api.simulate(loaded, model=model)
    assert trajectory.ledger["contacts"] == {"starts_inside": None, "missed": None}
    energy = quantity_series(model, trajectory).total
    # never rises, beyond what correcting overlaps can lift: pushing bodies out of overlap deeper than the slop raises
    # them by at most that much (rims meet other bodies as 16-gons, so a cylinder resting on its rim rocks a little)
    pushed = float(np.sum(model.bodies.mass)) * 9.81 * float(model.contact_settings.slop)
    assert np.max(energy - np.minimum.accumulate(energy)) < pushed
    final = trajectory.positions[-1]
    assert np.all(np.abs(final[:, 0]) < 0.4) and np.all(np.abs(final[:, 2]) < 0.3) and np.all(final[:, 1] > 0.035)  # a gem on a face: 0.038
    kinetic = quantity_series(model, trajectory).kinetic
    assert kinetic[-1] < 0.02 * (energy[0] - energy[-1])  # it has settled: what is left moving is a trifle
