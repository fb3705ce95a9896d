"""Charges in electric and magnetic fields, and Coulomb's law, against their closed forms: the cyclotron circle, the
E × B drift of a cycloid, a ramped field, and a Coulomb pair orbiting as Kepler's two bodies do."""

from __future__ import annotations

import numpy as np
import pytest

from animbatch.errors import SceneError
from animbatch.sim.ledger import conservation_laws
from support.scenes import body, run, scene

ACCURATE = "{method: DOP853, rtol: 1.0e-11, atol: 1.0e-13}"


def cyclotron(solver: str, duration: float = 6.3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A charge q = 0.5 C of mass m = 0.5 kg sent at 1 m/s across B = 1 T: ω = qB/m = 1 rad/s, r = mv/(qB) = 1 m."""
    _, trajectory = run(f"""
        duration: {duration}
        fps: 20
        solver: {solver}
        bodies: [{{name: ion, mass: 0.5, charge: 0.5, velocity: [1, 0, 0]}}]
        fields: [{{type: electromagnetic, B: [0, 0, 1]}}]
    """)
    x, v = body(trajectory, "ion")
    return trajectory.times, x, v


def circle(t: np.ndarray) -> np.ndarray:
    """The closed form: v × B turns the charge towards -y, about the centre (0, -r, 0)."""
    return np.stack([np.sin(t), -(1 - np.cos(t)), np.zeros_like(t)], axis=1)


def test_a_charge_across_a_magnetic_field_circles_at_the_cyclotron_radius_and_period():
    t, x, v = cyclotron(ACCURATE)
    np.testing.assert_allclose(x, circle(t), atol=1e-8)
    np.testing.assert_allclose(np.linalg.norm(v, axis=1), 1.0, atol=1e-9)  # B does no work
    assert np.linalg.norm(x - [0, -1, 0], axis=1) == pytest.approx(np.ones(len(t)), abs=1e-8)  # r = m v / (q B)


@pytest.mark.slow
@pytest.mark.parametrize("solver, tolerance", [("{method: Radau, rtol: 1.0e-9, atol: 1.0e-11}", 1e-6),
                                               ("{method: midpoint, dt: 0.001}", 1e-5)])
def test_implicit_and_fixed_step_methods_follow_the_cyclotron_circle(solver, tolerance):
    t, x, _ = cyclotron(solver)
    np.testing.assert_allclose(x, circle(t), atol=tolerance)


def test_midpoint_converges_at_second_order_on_the_cyclotron_circle():
    errors = [np.abs(cyclotron(f"{{method: midpoint, dt: {dt}}}")[1][-1] - circle(np.array([6.25]))[0]).max()
              for dt in (0.01, 0.005)]
    assert 3.5 < errors[0] / errors[1] < 4.5  # 2² = 4


def test_backward_euler_turns_the_charge_on_a_shrinking_circle_never_a_growing_one():
    """Backward Euler on v' = ω v × ẑ multiplies the speed by 1/√(1 + (ωh)²) per step: it loses energy, as an
    implicit method should, instead of spiralling out."""
    h = 0.01
    t, _, v = cyclotron(f"{{method: backward_euler, dt: {h}}}")
    speed = np.linalg.norm(v, axis=1)
    np.testing.assert_allclose(speed, (1 + h**2) ** (-t / h / 2), rtol=1e-9)


def test_crossed_fields_drift_at_e_cross_b_over_b_squared_along_a_cycloid():
    """From rest in E = E₀ ŷ and B = B ẑ: x = (E₀/B)(t - sin(ωt)/ω), y = (E₀/(Bω))(1 - cos ωt), ω = qB/m; the guiding
    centre drifts at E × B / B² = (E₀/B) x̂ whatever the charge's sign or mass."""
    q, m, e0, b = 2.0, 0.5, 3.0, 1.5
    _, trajectory = run(f"""
        duration: 5
        fps: 25
        solver: {ACCURATE}
        bodies: [{{name: ion, mass: {m}, charge: {q}}}]
        fields: [{{type: electromagnetic, E: [0, {e0}, 0], B: [0, 0, {b}]}}]
    """)
    x, _ = body(trajectory, "ion")
    t, omega = trajectory.times, q * b / m
    expected = np.stack([e0 / b * (t - np.sin(omega * t) / omega), e0 / (b * omega) * (1 - np.cos(omega * t)),
                         np.zeros_like(t)], axis=1)
    np.testing.assert_allclose(x, expected, atol=1e-8)


def test_a_keyframed_field_ramps_and_then_holds():
    """E grows linearly from 0 to E₁ over the first second, then holds: v = qE₁t²/(2m), then qE₁/(2m) + qE₁(t-1)/m."""
    q, m, e1 = 0.5, 2.0, 4.0
    _, trajectory = run(f"""
        duration: 2
        fps: 10
        solver: {ACCURATE}
        bodies: [{{name: ion, mass: {m}, charge: {q}}}]
        fields: [{{type: electromagnetic, keyframes: [{{time: 0, E: [0, 0, 0]}}, {{time: 1, E: [{e1}, 0, 0]}}]}}]
    """)
    _, v = body(trajectory, "ion")
    t = trajectory.times
    a = q * e1 / m
    expected = np.where(t <= 1, a * t**2 / 2, a / 2 + a * (t - 1))
    np.testing.assert_allclose(v[:, 0], expected, atol=1e-9)


def coulomb_pair(separation: float, speed: float, fps: int = 50, duration: float = 4.5) -> tuple:
    """Charges +1 C and -1 C of 1 kg each with k = 1: the relative motion is Kepler's with GM = k|q₁q₂|(1/m₁ + 1/m₂)
    = 2 m³/s². They start ``separation`` apart on x, moving at ±``speed``/2 along y (a relative speed ``speed``)."""
    half = speed / 2
    return run(f"""
        duration: {duration}
        fps: {fps}
        solver: {ACCURATE}
        bodies:
          - {{name: plus, charge: 1, position: [{-separation / 2}, 0, 0], velocity: [0, {-half}, 0]}}
          - {{name: minus, charge: -1, position: [{separation / 2}, 0, 0], velocity: [0, {half}, 0]}}
        fields: [{{type: coulomb, k: 1}}]
    """)


def test_opposite_charges_orbit_in_a_circle_at_the_kepler_rate():
    """A circular relative orbit of radius a = 1 m needs v² = GM/a = 2: it turns at ω = √2 rad/s about the centre."""
    _, trajectory = coulomb_pair(1.0, np.sqrt(2.0))
    t = trajectory.times
    plus, _ = body(trajectory, "plus")
    minus, _ = body(trajectory, "minus")
    angle = np.sqrt(2.0) * t
    separation = minus - plus
    np.testing.assert_allclose(separation, np.stack([np.cos(angle), np.sin(angle), 0 * t], axis=1), atol=1e-8)
    np.testing.assert_allclose(plus + minus, 0.0, atol=1e-9)  # the centre of mass stays put


def test_an_eccentric_coulomb_orbit_keeps_its_energy_and_reaches_the_kepler_apoapsis():
    """From periapsis r = 0.5 m at the vis-viva speed for a = 1 m (v² = GM(2/r - 1/a) = 6), the pair separates up to
    2a - r = 1.5 m, half a period T/2 = π √(a³/GM) = π/√2 s later, and keeps E = ½ Σ m v² + k q₁ q₂ / r."""
    model, trajectory = coulomb_pair(0.5, np.sqrt(6.0), fps=200, duration=2.3)
    plus, v_plus = body(trajectory, "plus")
    minus, v_minus = body(trajectory, "minus")
    r = np.linalg.norm(minus - plus, axis=1)
    energy = 0.5 * (np.sum(v_plus**2, axis=1) + np.sum(v_minus**2, axis=1)) - 1 / r
    np.testing.assert_allclose(energy, energy[0], atol=1e-9)
    assert energy[0] == pytest.approx(-0.5)  # -k|q₁q₂|/(2a), with a = 1 m
    assert r.max() == pytest.approx(1.5, abs=1e-6)
    assert trajectory.times[np.argmax(r)] == pytest.approx(np.pi / np.sqrt(2), abs=1.5 / 200)
    laws = conservation_laws(model)
    assert laws["energy"].conserved and laws["momentum"].conserved and laws["angular_momentum"].conserved


def test_like_charges_repel():
    _, trajectory = run("""
        duration: 1
        fps: 10
        bodies: [{name: a, charge: 1.0e-5, position: [-0.5, 0, 0]}, {name: b, charge: 2.0e-5, position: [0.5, 0, 0]}]
        fields: [{type: coulomb}]
    """)
    a, v_a = body(trajectory, "a")
    b, _ = body(trajectory, "b")
    assert np.all(np.diff(b[:, 0] - a[:, 0]) > 0)
    # the first instant: a = k q₁ q₂ / (m r²) = 8.9875517923e9 · 2e-10 / 1 ≈ 1.797 m/s²
    assert v_a[1, 0] < 0


def test_constant_fields_conserve_energy_and_a_changing_one_does_work():
    model, _ = run("""
        duration: 0.1
        bodies: [{name: ion, charge: 1, velocity: [1, 0, 0]}]
        fields: [{type: electromagnetic, E: [0, 1, 0], B: [0, 0, 2]}]
    """)
    assert conservation_laws(model)["energy"].conserved
    model, _ = run("""
        duration: 0.1
        bodies: [{name: ion, charge: 1}]
        fields: [{type: electromagnetic, keyframes: [{time: 0, E: [0, 0, 0]}, {time: 1, E: [1, 0, 0]}]}]
    """)
    assert not conservation_laws(model)["energy"].conserved


def test_only_charged_bodies_feel_the_fields():
    _, trajectory = run("""
        duration: 1
        fps: 10
        bodies: [{name: ion, charge: 1}, {name: neutral, position: [0, 2, 0], velocity: [1, 0, 0]}]
        fields: [{type: electromagnetic, E: [0, 5, 0], B: [0, 0, 1]}]
    """)
    x, v = body(trajectory, "neutral")
    np.testing.assert_allclose(v, [[1, 0, 0]] * len(v), atol=1e-12)


@pytest.mark.parametrize("text, fragment", [
    ("bodies: [{name: a}]\nfields: [{type: electromagnetic, B: [0, 0, 1]}]", "needs at least 1"),
    ("bodies: [{name: a, charge: 1}, {name: b}]\nfields: [{type: coulomb}]", "only 'a' has one"),
    ("bodies: [{name: a, charge: 1}]\nfields: [{type: electromagnetic, keyframes: [{time: 1, E: [1, 0, 0]}, "
     "{time: 0.5, E: [0, 0, 0]}]}]", "key times must increase"),
    ("bodies: [{name: a, charge: 1}]\nfields: [{type: electromagnetic, b: [0, 0, 1]}]", "did you mean"),
])
def test_charged_fields_without_charges_or_with_bad_keys_are_refused_with_the_fix(text, fragment):
    with pytest.raises(SceneError) as error:
        scene("duration: 1\n" + text)
    assert fragment in str(error.value)
    assert "test.yaml:" in str(error.value)
