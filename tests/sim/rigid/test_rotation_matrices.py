"""``solver.orientation: matrix``: the notes' rotation matrix integrated as ``dR/dt = [ω]× R``. A box spinning
steadily about a principal axis makes every explicit step multiply R by ``I + h [ω]×``, whose singular values are
1 and √(1 + (h ω)²): unrenormalised, ‖RᵀR − I‖ follows √2 ((1 + (h ω)²)ⁿ − 1) exactly; renormalised every step, R
turns by atan(h ω) a step and stays a rotation to round-off; the ledger reports the largest ‖RᵀR − I‖."""

from __future__ import annotations

import math

import numpy as np
import pytest

from animbatch import api
from animbatch.errors import SceneError
from animbatch.sim.ledger import summary

OMEGA, H = 5.0, 0.01  # [rad/s] about the box's z axis (a principal axis), [s]
SPIN = f"""name: spin
duration: 2
fps: 10
solver: {{method: symplectic_euler, dt: {H}, orientation: matrix}}
bodies:
  - {{name: box, type: rigid, shape: {{type: box, size: [0.4, 0.2, 0.1]}}, density: 500,
     angular_velocity: [0, 0, {OMEGA}]}}
"""


def spin(*overrides):
    plan = api.plan(api.parse_scene(SPIN, filename="spin.yaml", overrides=list(overrides)))
    return plan, api.simulate(plan)


def steps_at(times):
    return np.rint(np.asarray(times) / H)


def test_unrenormalised_matrices_drift_from_rotations_as_the_explicit_step_says():
    plan, trajectory = spin("solver.renormalise=never")
    n = steps_at(trajectory.times)
    expected = math.sqrt(2) * ((1 + (H * OMEGA) ** 2) ** n - 1)
    states = plan.model.states_from(trajectory.positions, trajectory.velocities, trajectory.orientations,
                                    trajectory.angular_velocities)  # (the drawn rotations: no drift)
    assert plan.model.orientation_errors(states).max() < 1e-12
    orientation = trajectory.ledger["orientation"]
    assert orientation["renormalise"] == "never"
    assert orientation["largest"] == pytest.approx(expected[-1], rel=1e-9)
    assert orientation["largest"] > 0.5  # 200 steps at h ω = 0.05: far from a rotation


def test_renormalised_every_step_they_stay_rotations_and_turn_by_atan_h_omega_a_step():
    _, trajectory = spin()  # every step: the default for fixed-step methods
    assert trajectory.ledger["orientation"]["renormalise"] == "every step"
    assert trajectory.ledger["orientation"]["largest"] < 1e-13
    w, z = trajectory.orientations[:, 0, 0], trajectory.orientations[:, 0, 3]
    turned = np.unwrap(2 * np.arctan2(z, w))
    np.testing.assert_allclose(turned, steps_at(trajectory.times) * math.atan(H * OMEGA), atol=1e-10)


def test_every_few_steps_the_drift_is_held_to_what_that_many_steps_make():
    """Renormalised at steps 3, 6, 9, …: a frame k steps after the last one shows k steps' growth, exactly."""
    _, every = spin("solver.renormalise=3")
    _, never = spin("solver.renormalise=never")
    largest = every.ledger["orientation"]["largest"]
    assert 1e-4 < largest <= math.sqrt(2) * ((1 + (H * OMEGA) ** 2) ** 3 - 1) * (1 + 1e-9)
    assert largest < never.ledger["orientation"]["largest"] / 100
    since = steps_at(every.times) % 3
    np.testing.assert_allclose(every.orientation_errors, math.sqrt(2) * ((1 + (H * OMEGA) ** 2) ** since - 1),
                               rtol=1e-6, atol=1e-13)
    assert f"rotation matrices: ‖RᵀR − I‖ ≤ {largest:.2g} (every 3 steps)" in summary(every.ledger)


def test_an_adaptive_method_integrates_the_matrix_closely_without_renormalising():
    _, trajectory = spin("solver.method=DOP853", "solver.rtol=1e-10", "solver.atol=1e-12")
    assert trajectory.ledger["orientation"]["renormalise"] == "never"
    assert trajectory.ledger["orientation"]["largest"] < 1e-7
    w, z = trajectory.orientations[:, 0, 0], trajectory.orientations[:, 0, 3]
    np.testing.assert_allclose(np.unwrap(2 * np.arctan2(z, w)), OMEGA * trajectory.times, atol=1e-7)


def test_matrices_are_refused_where_their_solvers_keep_quaternions_and_renormalise_only_with_them():
    with pytest.raises(SceneError, match=r"solver\.orientation: orientation: matrix is for rigid bodies that move "
                                         r"freely under forces, and it has joints"):
        api.parse_scene(SPIN + "joints: [{type: ball, between: [box]}]\n", filename="j.yaml")
    with pytest.raises(SceneError, match="renormalise is for solver.orientation: matrix"):
        api.parse_scene(SPIN, filename="q.yaml", overrides=["solver.orientation=quaternion",
                                                             "solver.renormalise=never"])
    with pytest.raises(SceneError, match="RK45 integrates on between frames, so it cannot renormalise"):
        api.parse_scene(SPIN, filename="a.yaml", overrides=["solver.method=RK45", "solver.renormalise=5"])


def test_the_drift_at_each_frame_is_kept_in_the_trajectory_and_shown_by_the_label(tmp_path):
    """{R_error} in the text overlay shows the closed form's value at each frame; the trajectory file keeps it."""
    from animbatch.stages import label_values
    from animbatch.trajectory import Trajectory

    plan, trajectory = spin("solver.renormalise=never", "render.time_label=‖RᵀR − I‖ = {R_error:.3g}")
    expected = math.sqrt(2) * ((1 + (H * OMEGA) ** 2) ** steps_at(trajectory.times) - 1)
    np.testing.assert_allclose(trajectory.orientation_errors, expected, rtol=1e-9, atol=1e-14)
    shown = label_values(plan.scene, plan.model, trajectory).series["R_error"]
    np.testing.assert_array_equal(shown, trajectory.orientation_errors)
    again = Trajectory.load(trajectory.save(tmp_path / "spin.npz"))
    np.testing.assert_array_equal(again.orientation_errors, trajectory.orientation_errors)
    _, quaternions = spin("solver.orientation=quaternion", "render.time_label='{R_error}'")
    assert quaternions.orientation_errors is None
