"""The bundled contact scenes do what their comments promise, checked against closed forms."""

from __future__ import annotations

import numpy as np
import pytest

from animbatch import api
from animbatch.stages import load_scene
from support.paths import REPO

SCENES = REPO / "scenes"
G = 9.81


def simulate(name: str, *overrides: str):
    return api.simulate(load_scene(SCENES / name, list(overrides)))


@pytest.mark.slow
def test_bouncing_balls_apexes_fall_as_e_to_the_2n_and_the_softest_ball_comes_to_rest():
    """Apex n of a ball dropped from h0 onto a floor with restitution e is e^(2n) h0; the ball stops at
    t0 (1 + e)/(1 - e), t0 = sqrt(2 h0 / g), once the bounces (a geometric series) have added up."""
    trajectory = simulate("bouncing_balls.yaml", "fps=240", "duration=1.2")
    radius, h0 = 0.1, 1.5
    for index, e in enumerate([0.9, 0.7, 0.5, 0.3]):
        height = trajectory.positions[:, index, 1] - radius
        vy = trajectory.velocities[:, index, 1]
        # the first frame after each bounce: the apex of the flight it starts follows from energy, exactly
        after_bounce = np.flatnonzero((vy[:-1] < 0) & (vy[1:] > 0)) + 1
        apexes = height[after_bounce] + vy[after_bounce] ** 2 / (2 * G)
        expected = h0 * e ** (2 * np.arange(1, len(apexes) + 1))
        assert len(apexes) >= 1
        assert np.allclose(apexes, expected, rtol=1e-4, atol=1e-6), (e, apexes, expected)
    rest_time = np.sqrt(2 * h0 / G) * (1 + 0.3) / (1 - 0.3)
    assert rest_time == pytest.approx(1.027, abs=1e-3)
    at_rest = trajectory.times > rest_time + 0.02
    assert np.allclose(trajectory.positions[at_rest, 3, 1], radius, atol=1e-6)
    assert np.allclose(trajectory.velocities[at_rest, 3], 0.0, atol=1e-6)
    # the e = 0.5 ball still bounces then (it stops at 1.66 s)
    assert np.abs(trajectory.velocities[at_rest, 2, 1]).max() > 0.1


@pytest.mark.slow
def test_newtons_cradle_passes_the_swing_to_the_last_ball():
    """Elastic impacts of equal masses in a row exchange velocities: ball 5 swings up to ball 1's start height
    while balls 2-4 barely move (their springs stretch a little: 20 kN/m strings are stiff, not rigid)."""
    trajectory = simulate("newtons_cradle.yaml", "fps=120", "duration=0.8")
    heights = trajectory.positions[:, :, 1]
    start_rise = heights[0, 0] - 0.2
    assert heights[:, 4].max() - 0.2 == pytest.approx(start_rise, rel=5e-3)
    peak_speed = np.linalg.norm(trajectory.velocities, axis=2).max(axis=0)
    assert peak_speed[4] == pytest.approx(np.sqrt(2 * G * start_rise), rel=5e-3)
    assert np.all(peak_speed[1:4] < 0.05 * peak_speed[4])
    # ball 1 stops at the bottom once it has handed its momentum on
    assert heights[-1, 0] == pytest.approx(0.2, abs=2e-3)


@pytest.mark.slow
def test_slope_materials_hold_or_slide_as_their_friction_coefficients_say():
    """On a 20° ramp, tan 20° = 0.36: wood (μs 0.38), steel (0.78) and rubber (0.55) hold; Teflon and ice slide
    from rest with s = ½ g (sin θ − μk cos θ) t²."""
    trajectory = simulate("slope_materials.yaml", "fps=50", "duration=1.0")
    theta = np.radians(20)
    downhill = np.array([np.cos(theta), -np.sin(theta), 0.0])
    travelled = (trajectory.positions - trajectory.positions[0]) @ downhill
    names = list(trajectory.body_names)
    t = trajectory.times
    for name, mu_kinetic in [("teflon", 0.04), ("ice", 0.03)]:
        acceleration = G * (np.sin(theta) - mu_kinetic * np.cos(theta))
        assert np.allclose(travelled[:, names.index(name)], 0.5 * acceleration * t**2, rtol=5e-3, atol=2e-3), name
    for name in ["wood", "steel", "rubber"]:
        assert np.abs(trajectory.positions[:, names.index(name)] - trajectory.positions[0, names.index(name)]
                      ).max() < 1e-4, name


def test_collision_lab_meets_its_comment():
    """The pucks touch at 0.6 s and leave at the textbook velocities (-2, 0 for e = 1; -1.25, -0.25 for e = 0.5, the
    latter losing ½ μ (1 - e²) Δv² = 1.125 J); the thrown balls touch at (3 - 0.3) / 8 = 0.3375 s and, equal and
    elastic, swap velocities. No floor anywhere, and RK45 finds every impact."""
    trajectory = simulate("collision_lab.yaml")
    names = trajectory.body_names
    v = {name: trajectory.velocities[-1, names.index(name)] for name in names}
    assert [v[name][0] for name in ("a1", "b1", "a2", "b2")] == pytest.approx([-2, 0, -1.25, -0.25], abs=1e-9)
    before = 0.5 * 1 * 1**2 + 0.5 * 3 * 1**2
    after = 0.5 * 1 * 1.25**2 + 0.5 * 3 * 0.25**2
    assert before - after == pytest.approx(1.125)
    impacts = sorted(trajectory.solver_stats["impacts"])
    assert [t for t, _ in impacts] == pytest.approx([0.3375, 0.6, 0.6], abs=1e-9)
    t = trajectory.times[-1]
    assert v["ball1"] == pytest.approx([-4, 4 - G * t, 0], abs=1e-7)  # ball2's velocity, now ball1's
    assert v["ball2"] == pytest.approx([4, 4 - G * t, 0], abs=1e-7)


@pytest.mark.slow
def test_energy_drift_scene_warns_as_its_comment_says():
    """Explicit Euler over ten orbits: the energy drifts by about 30 % of its 2.04 J binding energy, the angular
    momentum by about 12 %, and the run warns; verlet at the same step does not."""
    import warnings

    from animbatch.errors import AccuracyWarning

    with pytest.warns(AccuracyWarning, match="the energy drifted by"):
        ledger = simulate("energy_drift.yaml").ledger
    assert ledger["conservation"]["energy"]["drift"] == pytest.approx(0.30, abs=0.02)
    assert ledger["conservation"]["angular_momentum"]["drift"] == pytest.approx(0.12, abs=0.01)
    with warnings.catch_warnings():
        warnings.simplefilter("error", AccuracyWarning)
        assert simulate("energy_drift.yaml", "solver.method=verlet").ledger["warnings"] == []
