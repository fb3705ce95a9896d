"""The bundled cloth, lattice and controller scenes do what their comments say (closed forms and invariants).

Where a claim does not depend on the mesh's resolution or the scene's length, the scene is run coarser or shorter so
that the suite stays fast.
"""

from __future__ import annotations

import numpy as np
import pytest

from animbatch import api
from animbatch.sim.invariants import kinetic_energy
from animbatch.stages import load_scene
from support.paths import REPO
from support.scenes import states

SCENES = REPO / "scenes"
G = 9.81


def simulate(name: str, *overrides: str):
    """Compile and simulate a bundled scene with overrides; the model, trajectory and loaded scene."""
    loaded = load_scene(SCENES / name, list(overrides))
    model = api.compile_model(loaded)
    return model, api.simulate(loaded, model=model), loaded


def cloth_vertices(model, trajectory) -> np.ndarray:
    """Every cloth or lattice vertex (pinned ones too) at every frame, (F, V, 3) [m]."""
    vertex_map = model.deformables.vertex_map
    return np.array([vertex_map.place(x, None, model.anchors.positions(t))
                     for x, t in zip(trajectory.positions, trajectory.times)])


@pytest.mark.slow
def test_flag_streams_downwind_and_flaps_and_its_pole_costs_no_contact_pass():
    """In the wind the flag's free edge stays downwind of the pole by most of the flag's length and the cross gusts
    move it sideways by centimetres. The pole is scenery (the flag does not collide): no contact pass is compiled."""
    model, windy, _ = simulate("flag.yaml", "bodies[flag].grid.resolution=[16, 11]", "duration=2.5")
    assert model.contact_world is None
    free_edge = np.arange(15, 16 * 11, 16)  # the vertices of the right-hand column
    streaming = cloth_vertices(model, windy)[windy.times > 1.0][:, free_edge]
    assert streaming[..., 0].mean(axis=1).min() > 0.8 * 1.5  # x: the pole is at 0, the flag 1.5 m long
    assert np.ptp(streaming[..., 2].mean(axis=1)) > 0.05


@pytest.mark.slow
def test_draped_cloth_never_enters_the_sphere_and_its_cap_comes_to_rest():
    """No vertex ever comes closer to the sphere's centre than R + its radius (less the contact slop); the cap of
    the sheet that lies on the sphere comes to rest there, held by friction."""
    model, trajectory, loaded = simulate("cloth_drape.yaml", "bodies[sheet].grid.resolution=[13, 13]",
                                         "duration=2")
    radius = loaded.spec.bodies[0].radius
    distance = np.linalg.norm(trajectory.positions, axis=2)
    assert distance.min() > 0.4 + radius - 1.5e-4
    lying = distance[-1] < 0.4 + radius + 1e-3
    assert lying.sum() >= 9
    assert np.linalg.norm(trajectory.velocities[-1][lying], axis=1).max() < 0.02


@pytest.mark.slow
def test_curtain_corners_never_move_its_swing_dies_down_and_its_top_edge_sags():
    """The pinned corners stay exactly where they started; still air takes out the swing (in the last second the
    kinetic energy is below 0.1 % of its peak); the free top edge sags between the corners, lowest in the middle."""
    model, trajectory, _ = simulate("curtain.yaml", "bodies[curtain].grid.resolution=[16, 13]")
    vertices = cloth_vertices(model, trajectory)
    corners = [16 * 12, 16 * 13 - 1]  # top-left and top-right
    assert np.array_equal(vertices[:, corners], np.broadcast_to(vertices[0, corners], vertices[:, corners].shape))
    energy = kinetic_energy(model, states(model, trajectory))
    assert energy[trajectory.times > trajectory.times[-1] - 1].max() < 1e-3 * energy.max()
    top = vertices[-1, 16 * 12: 16 * 13, 1]
    assert np.all(np.diff(top[:8]) < 0) and np.all(np.diff(top[8:]) > 0)  # down to the middle, then up
    assert top[0] - top.min() > 0.02


@pytest.mark.slow
def test_jelly_falls_freely_then_lands_without_entering_the_floor_and_settles():
    """Until its lowest vertex reaches the floor the block's centre of mass falls exactly as backward Euler's free
    fall, y0 - g t (t + h) / 2 with h the step (its springs are internal forces: they and their derivatives cancel in
    the sum over vertices); no vertex ever sinks below its radius (less the slop); it ends at rest with its centre of
    mass above the floor by less than half its height (squashed by its weight) but more than 40 % of it, plus the
    contact radius of its vertices."""
    model, trajectory, loaded = simulate("jelly.yaml", "bodies[jelly].resolution=[4, 4, 4]", "duration=3")
    body = loaded.spec.bodies[0]
    mass = model.bodies.mass[: model.particle_count]
    centre = np.einsum("v,fvk->fk", mass, trajectory.positions) / mass.sum()
    lowest = trajectory.positions[..., 1].min(axis=1)
    radius = float(model.bodies.radius[0])
    falling = trajectory.times < np.sqrt(2 * (lowest[0] - radius) / G) - 1 / 30  # a frame before the first touch
    assert falling.sum() >= 5
    t, h = trajectory.times[falling], trajectory.solver_stats["dt"]
    assert h == pytest.approx(1 / 240)
    assert centre[falling, 1] == pytest.approx(centre[0, 1] - 0.5 * G * t * (t + h), abs=1e-9)
    assert lowest.min() > radius - 1.5e-4
    assert kinetic_energy(model, states(model, trajectory)[-1]) < 1e-3 * mass.sum() * G * body.size[1]
    assert 0.4 * body.size[1] + radius < centre[-1, 1] < 0.5 * body.size[1] + radius


@pytest.mark.slow
def test_bead_stays_within_its_stated_distance_of_the_wire_and_loops():
    """The bead stays within (m g + m v0²/r) / ks = 3.0 mm of the circle and comes close to that bound (at the
    bottom), loops the loop, and passes the bottom with nearly its launch speed (less than 1 % lost per loop)."""
    _, trajectory, _ = simulate("bead_on_wire.yaml", "duration=1.5")
    x, v = trajectory.positions[:, 0], trajectory.velocities[:, 0]
    distance = np.hypot(np.hypot(x[:, 0], x[:, 1]) - 0.5, x[:, 2])
    bound = (0.1 * G + 0.1 * 5.0**2 / 0.5) / 2000
    assert 0.9 * bound < distance.max() < bound
    angle = np.unwrap(np.arctan2(x[:, 1], x[:, 0]))
    assert angle[-1] - angle[0] > 2 * np.pi
    energy = 0.5 * 0.1 * np.sum(v**2, axis=1) + 0.1 * G * x[:, 1]
    loops = (angle[-1] - angle[0]) / (2 * np.pi)
    assert 0 < energy[0] - energy[-1] < 0.01 * energy[0] * loops


@pytest.mark.slow
def test_bead_under_backward_euler_never_rises_above_its_starting_energy_at_a_bounded_cost():
    """Backward Euler at one step per frame (ω dt = 2.4 for the controller's 141 rad/s): the curve's turn is left
    out of the definite derivative, so the energy guard halves a rising step at most three times. At every frame the
    energy (kinetic, gravity and the controller's ks d²/2) is at or below the start, and no step costs more than
    the 15 plain steps of three halvings (ten halvings had cost up to 1023 per step: a minute for this loop)."""
    from animbatch.sim.invariants import total_energy

    model, trajectory, _ = simulate("bead_on_wire.yaml", "solver.method=backward_euler", "solver.dt=0.0166667",
                                    "duration=2")
    energy = total_energy(model, states(model, trajectory))
    assert np.all(energy <= energy[0] * (1 + 1e-9))
    steps = len(trajectory.times) - 1
    assert steps < trajectory.solver_stats["rhs_evaluations"] <= 15 * steps  # it does halve, within its bound
