"""PD controllers (virtual springs), the curves they follow, and keyframed anchors (the bead on its wire is tested
with the bundled scene, in test_cloth_scenes.py)."""

from __future__ import annotations

import numpy as np
import pytest

from animbatch.curves import (
    ExpressionError,
    ParametricCurve,
    Polyline,
    compile_expression,
    compile_tree,
    differentiate,
    parse_expression,
)
from animbatch.sim.motion import KeyframePath
from support.scenes import body, run, scene

G = 9.81


def test_keyframed_target_is_followed_without_lag_and_sags_by_mg_over_ks():
    """The damper acts on the velocity relative to the target's, so a particle following a target that moves at
    constant velocity does not trail behind it; under gravity it hangs m g / ks below it (0.5 kg, ks = 100)."""
    _, trajectory = run("""
        duration: 4
        fps: 20
        solver: {method: DOP853, rtol: 1.0e-10, atol: 1.0e-12}
        bodies: [{name: puppet, mass: 0.5, position: [0, 1, 0]}]
        controllers:
          - {body: puppet, stiffness: 100, damping: 14.14,
             target: {type: keyframes, keyframes: [{time: 0, position: [0, 1, 0]}, {time: 10, position: [5, 1, 0]}]}}
        fields: [{type: gravity}]
    """)
    x, v = body(trajectory, "puppet")
    t = trajectory.times
    late = t > 3
    target = np.stack([0.5 * t, np.ones_like(t), np.zeros_like(t)], axis=1)
    assert np.allclose(x[late] - target[late], [0, -0.5 * G / 100, 0], atol=1e-5)
    assert np.allclose(v[late], [0.5, 0, 0], atol=1e-5)


def test_polyline_closest_points_and_tangents():
    """Closest points on an L-shaped polyline: on a segment's interior (with its tangent, and ∂c/∂p = t tᵀ) and at
    the corner (where the closest point does not move with p)."""
    line = Polyline.through(np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0.0]]), closed=False)
    points = np.array([[0.3, 0.2, 0.1], [1.4, 0.5, 0], [2.0, -1.0, 0]])
    found = line.closest(points)
    assert found.position == pytest.approx(np.array([[0.3, 0, 0], [1, 0.5, 0], [1, 0, 0]]))
    assert found.tangent[0] == pytest.approx([1, 0, 0]) and found.tangent[1] == pytest.approx([0, 1, 0])
    assert found.position_gradient[1] == pytest.approx(np.diag([0, 1, 0]))
    assert np.array_equal(found.position_gradient[2], np.zeros((3, 3)))
    assert line.length == pytest.approx(2.0)


def test_polyline_closest_point_is_exact_against_brute_force():
    """The k-d tree search finds the same closest points as testing every segment, for points near and far from
    a wiggly 3D polyline of 500 segments."""
    rng = np.random.default_rng(3)
    s = np.linspace(0, 6, 501)
    line = Polyline.through(np.stack([np.cos(3 * s), np.sin(2 * s), 0.2 * s], axis=1), closed=False)
    points = rng.uniform(-1.5, 1.5, (400, 3))
    offset = points[:, None, :] - line.start[None]
    fraction = np.clip(np.einsum("ksj,sj->ks", offset, line.direction)
                       / np.einsum("sj,sj->s", line.direction, line.direction), 0, 1)
    distance = np.linalg.norm(offset - fraction[..., None] * line.direction[None], axis=2).min(axis=1)
    assert np.linalg.norm(line.closest(points).position - points, axis=1) == pytest.approx(distance, abs=1e-14)


def test_parametric_circle_closest_point_is_exact_with_exact_derivatives():
    """On the circle of radius 0.5 the closest point to p is 0.5 p_xy / |p_xy| (to rounding, not to the sampling's
    sagitta), and its derivatives with respect to p match central differences."""
    curve = ParametricCurve(("0.5*cos(s)", "0.5*sin(s)", "0"), 0, 2 * np.pi, closed=True, samples=64)
    rng = np.random.default_rng(4)
    angle = rng.uniform(0, 2 * np.pi, 200)
    points = np.stack([0.5 * np.cos(angle), 0.5 * np.sin(angle), np.zeros(200)], 1) + rng.normal(0, 0.1, (200, 3))
    found = curve.closest(points)
    planar = points[:, :2] / np.linalg.norm(points[:, :2], axis=1)[:, None]
    assert found.position[:, :2] == pytest.approx(0.5 * planar, abs=1e-14)
    assert np.abs(np.einsum("kj,kj->k", found.tangent[:, :2], planar)).max() < 1e-14
    h = 1e-6
    for axis in range(3):
        step = np.zeros(3)
        step[axis] = h
        ahead, behind = curve.closest(points + step), curve.closest(points - step)
        assert found.position_gradient[:, :, axis] == pytest.approx((ahead.position - behind.position) / (2 * h),
                                                                    abs=1e-7)
        assert found.tangent_gradient[:, :, axis] == pytest.approx((ahead.tangent - behind.tangent) / (2 * h),
                                                                   abs=1e-6)


def test_open_parametric_curve_clamps_to_its_ends():
    """Beyond the end of an open curve the closest point is the end itself, and it does not move with p."""
    curve = ParametricCurve(("s", "s**2", "0"), 0, 1, closed=False)
    found = curve.closest(np.array([[3.0, 1.0, 0.0], [-1.0, -0.5, 0.0]]))
    assert found.position == pytest.approx(np.array([[1, 1, 0], [0, 0, 0.0]]))
    assert np.array_equal(found.position_gradient, np.zeros((2, 3, 3)))


@pytest.mark.parametrize("formula", ["3*s**2 - 2/s", "sin(2*s)*exp(-s)", "sqrt(1 + s**2)", "atan2(s, 2 - s)",
                                     "log(s) + tanh(s)", "s**s", "abs(s - 1.3) * cosh(s)", "asin(s / 4)",
                                     "-acos(s / 4) + tan(s / 3)", "atan(s) * sinh(s)"])
def test_symbolic_derivatives_match_finite_differences(formula):
    """d/ds of every operator and function, against central differences at several s."""
    function = compile_expression(formula)
    derivative = compile_tree(differentiate(parse_expression(formula)))
    s = np.array([0.4, 0.9, 1.7, 2.5])
    h = 1e-6
    assert derivative(s) == pytest.approx((function(s + h) - function(s - h)) / (2 * h), rel=1e-6)


@pytest.mark.parametrize("text", ["__import__('os')", "s.real", "open('x')", "lambda: 1", "[s]", "foo(s)"])
def test_formulas_cannot_run_code(text):
    """Only arithmetic, s, pi, e and a fixed list of functions are accepted."""
    with pytest.raises(ExpressionError):
        compile_expression(text)


def test_formula_errors_are_scene_errors_with_their_position():
    """A bad formula in a scene is reported at its key, with what is allowed."""
    with pytest.raises(Exception) as caught:
        scene("""
            bodies: [{name: bead}]
            controllers:
              - {body: bead, stiffness: 1, target: {type: parametric, x: "cos(s)", y: "sin(t)", range: [0, 1]}}
        """)
    message = str(caught.value)
    assert "controllers[0].target.y: unknown name 't' in 'sin(t)': use s, numbers" in message


def test_cubic_keyframes_pass_through_the_keys_and_start_and_end_at_rest():
    """A cubic path goes through every key, with zero velocity at the first and last key and beyond."""
    path = KeyframePath(np.array([0.0, 1.0, 3.0]), np.array([[0, 0, 0], [1, 2, 0], [0, 1, 1.0]]), "cubic")
    for t, position in zip(path.times, path.positions):
        assert path.position(t) == pytest.approx(position)
    assert path.velocity(0.0) == pytest.approx([0, 0, 0]) and path.velocity(3.0) == pytest.approx([0, 0, 0])
    assert path.position(5.0) == pytest.approx([0, 1, 1]) and np.array_equal(path.velocity(5.0), [0, 0, 0])
    t, h = 1.7, 1e-6
    assert path.velocity(t) == pytest.approx((path.position(t + h) - path.position(t - h)) / (2 * h), rel=1e-6)


def test_linear_keyframes_move_at_constant_speed_between_keys_and_hold_outside_them():
    path = KeyframePath(np.array([0.0, 1.0, 3.0]), np.array([[0, 0, 0], [1, 2, 0], [0, 1, 1.0]]))
    assert path.position(0.25) == pytest.approx([0.25, 0.5, 0]) and path.position(2.0) == pytest.approx([0.5, 1.5, 0.5])
    assert path.position(-1.0) == pytest.approx([0, 0, 0]) and path.position(9.0) == pytest.approx([0, 1, 1])
    assert path.velocity(2.0) == pytest.approx([-0.5, -0.5, 0.5]) and np.array_equal(path.velocity(9.0), [0, 0, 0])


def test_a_piecewise_cubic_reads_as_scipy_at_keys_between_and_beyond_them():
    """Paths read SciPy's splines through PiecewiseCubic: the same values and first and second derivatives as the
    spline's own call, at keys, between them and extended beyond the first and last."""
    from scipy.interpolate import CubicHermiteSpline, CubicSpline
    from scipy.spatial.transform import Rotation, RotationSpline

    from animbatch.sim.motion import PiecewiseCubic

    times, rng = np.array([0.0, 0.4, 1.0, 1.7]), np.random.default_rng(1)
    for spline in (CubicSpline(times, rng.normal(size=(4, 3)), bc_type="clamped"),
                   CubicHermiteSpline(times, times, np.array([0.0, 1.0, 1.0, 0.0])),
                   RotationSpline(times, Rotation.random(4, random_state=2)).interpolator):
        ours = PiecewiseCubic(spline)
        for t in (-0.3, 0.0, 0.2, 0.4, 0.99, 1.0, 1.7, 2.5):
            for derivative in (0, 1, 2):
                assert np.allclose(ours(t, derivative), spline(t, derivative), rtol=1e-12, atol=1e-12), (t, derivative)


def test_spring_to_a_moving_anchor_drags_its_body_along():
    """A particle hanging on a nearly critically damped spring from an anchor that rises at 1 m/s ends up rising
    with it, hanging r + m g / ks below it: the damper sees the anchor's true velocity (were it taken as zero, the
    damper would hold the particle a further kd v / ks = 6 cm behind)."""
    _, trajectory = run("""
        duration: 3
        fps: 10
        solver: {method: DOP853, rtol: 1.0e-10, atol: 1.0e-12}
        anchors: [{name: hand, keyframes: [{time: 0, position: [0, 1, 0]}, {time: 5, position: [0, 6, 0]}]}]
        bodies: [{name: yoyo, mass: 0.2, position: [0, 0.5, 0]}]
        springs: [{between: [hand, yoyo], stiffness: 200, damping: 12, rest_length: 0.5}]
        fields: [{type: gravity}]
    """)
    x, v = body(trajectory, "yoyo")
    assert v[-1] == pytest.approx([0, 1, 0], abs=1e-6)
    hand = 1 + trajectory.times[-1]
    assert x[-1] == pytest.approx([0, hand - 0.5 - 0.2 * G / 200, 0], abs=1e-6)


@pytest.mark.slow
def test_controller_on_a_rigid_body_point_holds_it_like_a_pendulum_pivot():
    """A 1 kg box held at a corner by a damped PD controller to a fixed point, with some air drag on its turning:
    it comes to rest with the corner m g / ks below the target and its centre of mass straight below the corner
    (no torque), whatever way it started."""
    model, trajectory = run("""
        duration: 12
        fps: 10
        solver: {method: RK45, rtol: 1.0e-8, atol: 1.0e-10}
        bodies:
          - {name: crate, type: rigid, shape: {type: box, size: [0.2, 0.2, 0.2]}, mass: 1, position: [0.2, 1, 0],
             angular_velocity: [0, 0, 1]}
        controllers:
          - {body: crate, point: [0.1, 0.1, 0.1], stiffness: 400, damping: 40,
             target: {type: point, position: [0.3, 1.1, 0.1]}}
        fields: [{type: gravity}, {type: angular_drag, coefficient: 0.2, bodies: [crate]}]
    """)
    from animbatch import quaternion

    x, v = body(trajectory, "crate")
    rotation = quaternion.to_matrix(trajectory.orientations[-1, 0])
    corner = x[-1] + rotation @ np.array([0.1, 0.1, 0.1])
    assert corner == pytest.approx([0.3, 1.1 - G / 400, 0.1], abs=1e-5)
    hanging = x[-1] - corner
    assert hanging[[0, 2]] == pytest.approx([0, 0], abs=1e-5) and hanging[1] == pytest.approx(-0.1 * np.sqrt(3))
    assert np.abs(v[-1]).max() < 1e-4
