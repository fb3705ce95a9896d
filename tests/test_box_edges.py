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
from animbatch.sim.contact.edges import edge_contact
from conftest import scene

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


@pytest.mark.parametrize("ridge_is_a_body", [False, True])
def test_a_beam_laid_across_a_ridge_rests_on_it_edge_on_edge(ridge_is_a_body):
    height = beam_on_ridge(ridge_is_a_body)
    assert height.min() > REST - 2e-3  # it never falls through (corner probes alone let it)
    np.testing.assert_allclose(height[-10:], REST, atol=2e-3)


def test_edge_contact_geometry_of_two_crossed_boxes():
    turn = orientation_matrix(OrientationSpec(axis=[1, 0, 0], angle=45))
    ridge = orientation_matrix(OrientationSpec(axis=[0, 0, 1], angle=45))
    half_beam, half_ridge = np.array([0.5, 0.1, 0.1]), np.array([0.1, 0.1, 0.5])
    reach = 0.01
    touching = 2 * 0.1 * np.sqrt(2)
    hit = edge_contact(np.array([0, touching - 0.003, 0]), turn, half_beam, np.zeros(3), ridge, half_ridge, reach)
    assert hit is not None
    point, normal, gap, edge_a, edge_b = hit
    np.testing.assert_allclose(normal, [0, 1, 0], atol=1e-12)
    assert gap == pytest.approx(-0.003, abs=1e-12)  # 3 mm into the ridge
    np.testing.assert_allclose(point, [0, 0.1 * np.sqrt(2) - 0.0015, 0], atol=1e-12)
    assert edge_a // 4 == 0 and edge_b // 4 == 2  # the beam's edge along its x, the ridge's along its z
    assert edge_contact(np.array([0, touching + 0.05, 0]), turn, half_beam, np.zeros(3), ridge, half_ridge,
                        reach) is None  # 5 cm apart: beyond reach
    flat = np.eye(3)  # face to face: a face axis wins, and the corners hold that contact
    assert edge_contact(np.array([0, 0.199, 0]), flat, half_beam, np.zeros(3), flat, half_ridge, reach) is None
