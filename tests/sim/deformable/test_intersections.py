"""Triangle pairs that cross (cloth through itself or another cloth): counted against geometry whose crossings are
known, and reported by the run's ledger when a cloth goes through another."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from animbatch import api
from animbatch.errors import AccuracyWarning
from animbatch.sim.deformable.intersections import crossing_pairs
from animbatch.sim.deformable.topology import grid
from support.scenes import scene

SHEET = grid((1.0, 1.0), (48, 48))  # in the x-y plane, z = 0


def test_a_flat_sheet_and_one_folded_onto_itself_at_a_millimetre_do_not_cross():
    assert len(crossing_pairs(SHEET.vertices, SHEET.triangles)) == 0
    folded = SHEET.vertices.copy()
    right = folded[:, 0] > 1e-9
    folded[right, 0] *= -1  # the right half laid over the left one, a millimetre above it
    folded[right, 2] = 1e-3
    assert len(crossing_pairs(folded, SHEET.triangles)) == 0


def test_a_sheet_tilted_through_another_crosses_it_along_their_line_and_only_there():
    """Sheet B (z = 0.3 x + 0.001, shifted along y by a third of a cell so that no edge lies over another's) cuts
    sheet A (z = 0) along the line x = -0.001 / 0.3: every crossing pair holds a triangle of each sheet, both of
    whose x ranges contain that line, and every row of A's cells along it is cut."""
    cell = 1.0 / 47
    tilted = SHEET.vertices.copy()
    tilted[:, 2] = 0.3 * tilted[:, 0] + 0.001
    tilted[:, 1] += cell / 3
    vertices = np.vstack([SHEET.vertices, tilted])
    count = len(SHEET.triangles)
    triangles = np.vstack([SHEET.triangles, SHEET.triangles + len(SHEET.vertices)])
    pairs = crossing_pairs(vertices, triangles)
    assert len(pairs) and np.all(pairs[:, 0] < count) and np.all(pairs[:, 1] >= count)
    line = -0.001 / 0.3
    x = vertices[triangles][:, :, 0]  # (T, 3)
    for side in (0, 1):
        assert np.all((x[pairs[:, side]].min(axis=1) < line) & (x[pairs[:, side]].max(axis=1) > line))
    rows = np.unique(np.floor((vertices[triangles[pairs[:, 0]]][:, :, 1].mean(axis=1) + 0.5) / cell))
    np.testing.assert_array_equal(rows, np.arange(47))  # the line runs the sheet's whole height: every row is cut
    # the same sheets a centimetre apart and parallel do not cross
    apart = tilted.copy()
    apart[:, 2] = 0.01
    assert len(crossing_pairs(np.vstack([SHEET.vertices, apart]), triangles)) == 0


def test_a_piercing_triangle_crosses_and_touching_or_sharing_a_corner_does_not():
    base = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]
    through = np.array(base + [[0.2, 0.2, -0.5], [0.2, 0.2, 0.5], [0.9, 0.9, 0.0]], float)
    touching = np.array(base + [[0.2, 0.2, 0.0], [0.2, 0.2, 0.5], [0.3, 0.6, 0.5]], float)  # a corner on its face
    two = np.array([[0, 1, 2], [3, 4, 5]])
    np.testing.assert_array_equal(crossing_pairs(through, two), [[0, 1]])
    assert len(crossing_pairs(touching, two)) == 0
    sharing = np.array(base + [[0.2, 0.2, -0.5], [0.2, 0.2, 0.5]], float)  # a fan through the face, from corner 0
    assert len(crossing_pairs(sharing, np.array([[0, 1, 2], [0, 3, 4]]))) == 0


HEADER = """
duration: 0.5
fps: 30
solver: {method: backward_euler, dt: 0.002}
bodies:
"""
CURTAIN = """
  - name: curtain
    type: cloth
    grid: {size: [1.0, 1.0], resolution: [12, 12]}
    position: [0, 1, 0]
    density: 0.2
    structural: {stiffness: 200, damping: 0.2}
    pin: [{corners: [top-left, top-right, bottom-left, bottom-right]}]
    self_collision: false
"""
RAG = """
  - name: rag
    type: cloth
    grid: {size: [0.4, 0.4], resolution: [8, 8]}
    position: [0, 1, 0.6]
    orientation: {axis: [1, 0, 0], angle: 60}
    velocity: [0, 0, -3]
    density: 0.2
    structural: {stiffness: 200, damping: 0.2}
    self_collision: false
"""


def test_a_rag_thrown_through_a_curtain_is_reported_with_both_names_and_when():
    """Cloth without self-collision does not collide with cloth: a rag thrown at a pinned curtain flies through it (0.6 m at 3 m/s: at
    t = 0.2 s, tilted 60°, so that frames catch the two sheets crossing), and the run says so."""
    with pytest.warns(AccuracyWarning) as caught:
        trajectory = api.simulate(scene(HEADER + CURTAIN + RAG))
    surfaces = trajectory.ledger["surfaces"]
    assert surfaces["bodies"] == [["curtain", "rag"]] and surfaces["pairs"] > 0
    # the rag (±0.17 m deep, tilted) crosses z = 0 from t = 0.14 s to 0.26 s: the frames at 1/6 s … 1/4 s show it
    assert surfaces["first_time"] == pytest.approx(1 / 6) and 1 / 6 - 1e-9 <= surfaces["worst_time"] <= 0.25 + 1e-9
    message = " ".join(str(w.message) for w in caught)
    assert "'curtain' and 'rag' through each other from t = " in message
    assert "'curtain', 'rag' have self-collision off" in message
    # the rag alone, thrown at nothing, is not reported
    with warnings.catch_warnings():
        warnings.simplefilter("error", AccuracyWarning)
        assert api.simulate(scene(HEADER + RAG)).ledger.get("surfaces") is None
