"""Boxes touching edge to edge (issue 22): a beam laid crosswise on a ridge rests on it, whether the ridge is a fixed
collider or a body, where corner probes alone let it fall through; the edge contact's geometry; and the adaptive
methods' events following an edge pair from state to state (issue 41) as the search finds it, and beyond."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from animbatch import api
from animbatch.errors import AccuracyWarning
from animbatch.scene.orientation import orientation_matrix
from animbatch.scene.schema import OrientationSpec
from animbatch.sim.contact import hulls
from animbatch.sim.contact.detection import body_box_poses
from animbatch.sim.contact.hulls import EDGE_GONE, BodyHull, edge_pairs, hull_edge_contact
from animbatch.sim.model.dynamics import Dynamics
from support.polyhedra import jittered_states, polyhedra_model, searched
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


def test_edge_pairs_followed_between_events_are_the_contacts_the_search_finds(tmp_path):
    """Every kind of edge pair (a beam across a fixed ridge and across a ridge body, planks face on face, prisms ridge
    on ridge, a box on a gem), at 30 states near touching: named as the search names them, the followed pairs have
    the search's bodies, gaps, normals and points, to round-off."""
    model = polyhedra_model(tmp_path)
    system, world = Dynamics(model), model.contact_world
    kinds = set()
    for y in jittered_states(model, 30, 0.004):
        found = searched(model, y, hulls.edge_contacts)
        state = system.kinematics(*system.split(y), t=0.0, copy=True)
        followed = edge_pairs(world, state, *body_box_poses(world, state), found.probe, found.solid_kind,
                              found.solid_index)
        for name in ("probe_body", "solid_body", "gap", "normal", "point", "kinetic_friction"):
            np.testing.assert_allclose(getattr(followed, name), getattr(found, name), rtol=0, atol=1e-12,
                                       err_msg=name)
        kinds |= set(found.solid_kind.tolist())
    assert kinds == {hulls.STATIC_EDGE, hulls.BODY_EDGE, hulls.HULL_EDGE}


def test_an_edge_pair_is_followed_deep_into_the_ridge_and_is_gone_past_an_edge_s_end(tmp_path):
    """The beam on the fixed ridge, lowered by d: the followed pair's gap is its start's less d all the way down to
    the ridge's middle (the lines' distance, closed form), so an event sees where a beam that went into the ridge
    within one step struck; slid along until the crossing leaves the ridge's edge, the pair is gone (a corner probe
    holds the contact there)."""
    model = polyhedra_model(tmp_path)
    system, world = Dynamics(model), model.contact_world
    start = searched(model, model.y0, hulls.edge_contacts)
    pair = start.select(start.solid_kind == hulls.STATIC_EDGE)
    assert pair.count == 1
    lifted = pair.gap[0]  # the beam starts 2 mm into the ridge
    assert lifted == pytest.approx(-0.002, abs=1e-12)

    def followed(shift: np.ndarray) -> float:
        y = model.y0.copy()
        y[0:3] += shift  # the beam is body 0: its position comes first
        state = system.kinematics(*system.split(y), t=0.0, copy=True)
        return edge_pairs(world, state, *body_box_poses(world, state), pair.probe, pair.solid_kind,
                          pair.solid_index).gap[0]

    for depth in (0.01, 0.1, 0.28):
        assert followed(np.array([0.0, -depth, 0.0])) == pytest.approx(lifted - depth, abs=1e-12)
    assert followed(np.array([0.0, 0.0, 0.49])) == pytest.approx(lifted)  # the ridge is 1 m long along z
    assert followed(np.array([0.0, 0.0, 0.51])) == EDGE_GONE
