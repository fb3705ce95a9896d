"""A mixed pile (issue 22, contact between any shapes): boxes and balls dropped into a bin settle with no body inside
another or a wall, all inside the bin, and the total energy never rises (contacts only take energy away)."""

from __future__ import annotations

import warnings

import numpy as np

from animbatch import api
from animbatch.errors import AccuracyWarning
from animbatch.stages import quantity_series
from conftest import scene


def test_boxes_and_balls_dropped_in_a_bin_settle_without_overlap_or_energy_gain():
    bodies = []
    for k, (x, y, z, turn) in enumerate([(-0.2, 0.2, 0.0, 30), (0.0, 0.3, 0.04, 0), (0.2, 0.22, -0.03, 60),
                                         (-0.12, 0.5, 0.02, 45), (0.1, 0.55, 0.0, 10), (0.0, 0.8, -0.02, 75)]):
        if k % 2 == 0:
            bodies.append(f"  - {{name: box{k}, type: rigid, shape: {{type: box, size: [0.16, 0.1, 0.12]}}, "
                          f"density: 600, material: wood, position: [{x}, {y}, {z}], "
                          f"orientation: {{axis: [0.3, 1, 0.2], angle: {turn}}}}}")
        else:
            bodies.append(f"  - {{name: ball{k}, type: rigid, shape: {{type: sphere, radius: 0.06}}, density: 900, "
                          f"material: rubber, position: [{x}, {y}, {z}]}}")
    walls = "\n".join(f"  - {{type: box, position: {p}, size: {s}, material: wood}}" for p, s in [
        ("[-0.45, 0.2, 0]", "[0.1, 0.4, 0.8]"), ("[0.45, 0.2, 0]", "[0.1, 0.4, 0.8]"),
        ("[0, 0.2, -0.35]", "[0.8, 0.4, 0.1]"), ("[0, 0.2, 0.35]", "[0.8, 0.4, 0.1]")])
    loaded = scene("duration: 1.5\nfps: 30\nsolver: {method: symplectic_euler, dt: 1.0e-3}\nbodies:\n"
                   + "\n".join(bodies) + "\ncolliders:\n  - {type: plane, material: wood}\n" + walls
                   + "\nfields: [{type: gravity}]\n")
    model = api.compile_scene(loaded.spec)
    with warnings.catch_warnings():
        warnings.simplefilter("error", AccuracyWarning)  # a body inside another or a wall, or a missed contact, would warn
        trajectory = api.simulate(loaded, model=model)
    assert trajectory.ledger["contacts"] == {"starts_inside": None, "missed": None}
    energy = quantity_series(model, trajectory).total
    assert np.max(energy - np.minimum.accumulate(energy)) < 1e-9 * energy[0]  # never rises
    final = trajectory.positions[-1]
    assert np.all(np.abs(final[:, 0]) < 0.4) and np.all(np.abs(final[:, 2]) < 0.3) and np.all(final[:, 1] > 0.04)
    kinetic = quantity_series(model, trajectory).kinetic
    assert kinetic[-1] < 0.02 * (energy[0] - energy[-1])  # it has settled: what is left moving is a trifle
