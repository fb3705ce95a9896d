"""Boxes touching edge to edge (issue 22): a beam laid crosswise on a ridge rests on it, whether the ridge is a fixed
collider or a body, where corner probes alone let it fall through; and the edge contact's geometry."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from animbatch import api
from animbatch.errors import AccuracyWarning
from animbatch.scene.orientation import orientation_matrix
from animbatch.scene.schema import OrientationSpec
from animbatch.sim.contact.hulls import BodyHull, hull_edge_contact
from support.scenes import scene

TURNED = "{axis: [0, 0, 1], angle: 45}"
REST = 2 * 0.1 * np.sqrt(2)  # the beam's lowest edge on the ridge's highest: half-diagonals of both


def beam_on_ridge(ridge_is_a_body: bool) -> np.ndarray:
    """A 1 m beam turned 45° about its length, dropped crosswise onto a ridge (a box turned 45° the other way): the
    beam's height over time."""
    ridge = (f"bodies: [{{name: ridge, type: rigid, shape: {{type: box, size: [0.2, 0.2, 1.0]}}, density: 500, "
             f"material: wood, orientation: {TURNED}}}]\njoints: [{{type: fixed, between: [ridge]}}]\ncontacts: {{}}"
             if ridge_is_a_body else
             f"colliders: [{{type: box, position: [0, 0, 0], size: [0.2, 0.2, 1.0], orientation: {TURNED}, "
             "material: wood}]")
    beam = ("{name: beam, type: rigid, shape: {type: box, size: [1.0, 0.2, 0.2]}, density: 500, material: wood, "
            "position: [0, 0.5, 0], orientation: {axis: [1, 0, 0], angle: 45}}")
    text = (f"duration: 1.5\nfps: 50\nsolver: {{method: symplectic_euler, dt: 1.0e-3}}\n{ridge}\n"
            "fields: [{type: gravity}]\n")
    text = (text.replace("bodies: [", f"bodies: [{beam}, ") if ridge_is_a_body
            else text + f"bodies: [{beam}]\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error", AccuracyWarning)  # an overlap or a missed contact would warn
        return api.simulate(scene(text)).positions[:, 0, 1]


@pytest.mark.slow
@pytest.mark.parametrize("ridge_is_a_body", [False, True])
def test_a_beam_laid_across_a_ridge_rests_on_it_edge_on_edge(ridge_is_a_body):
    height = beam_on_ridge(ridge_is_a_body)
    assert height.min() > REST - 2e-3  # it never falls through (corner probes alone let it)
    np.testing.assert_allclose(height[-10:], REST, atol=2e-3)


def box(half: np.ndarray) -> BodyHull:
    return BodyHull.of_box(0, np.zeros(3), np.eye(3), half)


def test_edge_contact_geometry_of_two_crossed_boxes():
    turn = orientation_matrix(OrientationSpec(axis=[1, 0, 0], angle=45))
    ridge = orientation_matrix(OrientationSpec(axis=[0, 0, 1], angle=45))
    beam, ridge_box = box(np.array([0.5, 0.1, 0.1])), box(np.array([0.1, 0.1, 0.5]))
    reach = 0.01
    touching = 2 * 0.1 * np.sqrt(2)
    found = hull_edge_contact(beam, np.array([0, touching - 0.003, 0]), turn, ridge_box, np.zeros(3), ridge, reach)
    assert len(found) == 1
    point, normal, gap, edge_a, edge_b = found[0]
    np.testing.assert_allclose(normal, [0, 1, 0], atol=1e-12)
    assert gap == pytest.approx(-0.003, abs=1e-12)  # 3 mm into the ridge
    np.testing.assert_allclose(point, [0, 0.1 * np.sqrt(2) - 0.0015, 0], atol=1e-12)
    np.testing.assert_allclose(np.abs(beam.directions[edge_a]), [1, 0, 0], atol=1e-12)  # the beam's edge along x
    np.testing.assert_allclose(np.abs(ridge_box.directions[edge_b]), [0, 0, 1], atol=1e-12)  # the ridge's along z
    assert hull_edge_contact(beam, np.array([0, touching + 0.05, 0]), turn, ridge_box, np.zeros(3), ridge,
                             reach) == []  # 5 cm apart: beyond reach
    # face to face, one inside the other's footprint: a face axis wins, and the corners hold that contact
    small = box(np.array([0.05, 0.1, 0.05]))
    assert hull_edge_contact(small, np.array([0, 0.199, 0]), np.eye(3), ridge_box, np.zeros(3), np.eye(3),
                             reach) == []


@pytest.mark.slow
def test_a_plank_laid_across_another_face_on_face_rests_on_it():
    """No corner of either plank lies on the other: the four crossings of their edges hold the upper one (before
    polyhedra met edge to edge at face ties, it fell through the lower plank to the floor)."""
    loaded = scene("""
        duration: 1
        fps: 30
        solver: {method: symplectic_euler, dt: 1.0e-3}
        bodies:
          - {name: lower, type: rigid, shape: {type: box, size: [0.2, 0.1, 1.0]}, density: 500, position: [0, 0.05, 0]}
          - {name: upper, type: rigid, shape: {type: box, size: [1.0, 0.1, 0.2]}, density: 500, position: [0, 0.2, 0]}
        colliders: [{type: plane}]
        fields: [{type: gravity}]
    """)
    with warnings.catch_warnings():
        warnings.simplefilter("error", AccuracyWarning)
        trajectory = api.simulate(loaded)
    assert trajectory.positions[:, 1, 1].min() > 0.15 - 1e-3
    assert trajectory.positions[-1, 1, 1] == pytest.approx(0.15, abs=5e-4)
    np.testing.assert_allclose(trajectory.orientations[-1, 1], [1, 0, 0, 0], atol=1e-6)  # level, not tipped
