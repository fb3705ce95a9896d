"""Dominoes (issue 22, contact between boxes): tipped over, each tile topples the next in turn, none sinks into
another, and the row ends with less energy than it was given."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from animbatch import api
from animbatch.errors import AccuracyWarning
from animbatch.stages import quantity_series
from support.scenes import scene


@pytest.mark.slow
def test_dominoes_fall_one_after_the_other_and_come_to_rest_leaning_on_each_other():
    count = 4
    tiles = "\n".join(
        f"  - {{name: d{k}, type: rigid, shape: {{type: box, size: [0.02, 0.2, 0.1]}}, density: 700, "
        f"material: wood, position: [{0.1 * k:.2f}, 0.1, 0]"
        + (", velocity: [0.25, 0, 0], angular_velocity: [0, 0, -5.0]" if k == 0 else "") + "}"
        for k in range(count))
    loaded = scene(f"duration: 1.2\nfps: 60\nsolver: {{method: symplectic_euler, dt: 1.0e-3}}\nbodies:\n{tiles}\n"
                   "colliders: [{type: plane, material: wood}]\nfields: [{type: gravity}]\n")
    model = api.compile_scene(loaded.spec)
    with warnings.catch_warnings():
        warnings.simplefilter("error", AccuracyWarning)  # a tile inside another, or one that misses a contact, would warn
        trajectory = api.simulate(loaded, model=model)
    q = trajectory.orientations
    tilt = 2 * np.arctan2(-q[..., 3], q[..., 0])  # each tile's turn about −z: falling towards +x
    passes = [trajectory.times[np.argmax(tilt[:, k] > np.radians(30))] for k in range(count)]
    assert np.all(tilt.max(axis=0) > np.radians(30)), "every tile falls"
    assert np.all(np.diff(passes) > 0), f"in order: {passes}"
    assert tilt[-1, -1] > np.radians(85)  # the last lies flat; the others lean on it
    assert np.all(tilt[-1, :-1] > np.radians(70))
    energy = quantity_series(model, trajectory).total
    assert energy[-1] < energy[0] and np.all(energy <= energy[0] + 1e-6)
