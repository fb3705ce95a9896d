"""The resting-contact forces of adaptive methods (:func:`animbatch.sim.contact.impulses.solve_forces`) against
statics and Coulomb's law in closed form: a box standing on its four bottom corners carries its weight and neither
sinks nor tips, on a level floor and held by friction on a slope; the same box pushed sideways on a level floor
slides at μk g; a crate on another crate presses on it with its own weight. Each in numpy and compiled
(:mod:`animbatch.sim.kernels.resting_forces`), and the two against each other to round-off."""

from __future__ import annotations

import functools

import numpy as np
import pytest

from animbatch.sim.contact.contacts import PLANE, STATIC, Contacts
from animbatch.sim.contact.impulses import BodyVelocities, solve_forces
from animbatch.sim.contact.jointed import BlockInverse, JointedResponse
from support.scenes import box_inverse_inertia, corners_on_floor

G = 9.81


@pytest.fixture(params=[False, True], ids=["numpy", "compiled"])
def solve(request):
    """solve_forces, in numpy or compiled."""
    if request.param:
        pytest.importorskip("numba", reason="numba is not installed: numpy solves the resting forces")
    return functools.partial(solve_forces, compiled=request.param)


def bodies_under_gravity(masses: list[float], size: tuple[float, float, float]) -> BodyVelocities:
    """Accelerations of free boxes under gravity, and the fixed body last."""
    count = len(masses)
    v = np.zeros((count + 1, 3))
    v[:count, 1] = -G
    inverse_inertia = np.zeros((count + 1, 3, 3))
    inverse_inertia[:count] = [box_inverse_inertia(m, size) for m in masses]
    return BodyVelocities(v, np.zeros((count + 1, 3)), np.append(1.0 / np.array(masses), 0.0), inverse_inertia)


def test_a_box_on_four_corners_carries_its_weight_without_sinking_or_tipping(solve):
    mass, size = 2.0, (0.4, 0.2, 0.3)
    centre = np.array([0.3, 0.1, -0.2])
    contacts = corners_on_floor(0, centre, size, mu=0.5)
    accelerations = bodies_under_gravity([mass], size)
    result = solve(contacts, accelerations, np.array([centre, np.zeros(3)]), normal_bias=np.zeros(4),
                   tangent_bias=np.zeros((4, 2)), sticking=np.ones(4, bool),
                          slide_direction=np.zeros((4, 3)), iterations=200)
    assert result.normal_impulse.sum() == pytest.approx(mass * G, rel=1e-6)
    assert np.all(result.normal_impulse >= 0)
    np.testing.assert_allclose(accelerations.v[0], 0.0, atol=1e-6)
    np.testing.assert_allclose(accelerations.omega[0], 0.0, atol=1e-5)
    np.testing.assert_allclose(accelerations.v[1], 0.0)  # the fixed body does not move


def test_a_box_held_by_friction_on_a_30_degree_slope_neither_slides_nor_tips(solve):
    """Friction up the slope (m g sin θ) acts at the contact points, below the centre: only uneven normal forces
    (the lower corners pressing harder) keep the box from tipping."""
    mass, size, theta = 2.0, (0.4, 0.2, 0.3), np.radians(30)
    turn = np.array([[np.cos(theta), -np.sin(theta), 0], [np.sin(theta), np.cos(theta), 0], [0, 0, 1]])
    centre = np.array([0.1, 0.5, 0.0])
    half = np.array(size) / 2
    corners = np.array([[sx * half[0], -half[1], sz * half[2]] for sx in (1, -1) for sz in (1, -1)])
    points = centre + corners @ turn.T
    normal = turn @ [0.0, 1.0, 0.0]
    contacts = Contacts(np.zeros(4, np.intp), np.full(4, STATIC), points, np.tile(normal, (4, 1)), np.zeros(4),
                        np.zeros(4), np.full(4, 0.8), np.full(4, 0.8), np.arange(4), np.full(4, PLANE),
                        np.zeros(4, np.intp))
    accelerations = bodies_under_gravity([mass], size)
    accelerations.inverse_inertia[0] = turn @ box_inverse_inertia(mass, size) @ turn.T
    result = solve(contacts, accelerations, np.array([centre, np.zeros(3)]), normal_bias=np.zeros(4),
                   tangent_bias=np.zeros((4, 2)), sticking=np.ones(4, bool),
                          slide_direction=np.zeros((4, 3)), iterations=500)
    assert result.normal_impulse.sum() == pytest.approx(mass * G * np.cos(theta), rel=1e-5)
    lower = points[:, 1] < centre[1] - half[1] * np.cos(theta)  # the two corners down the slope
    assert result.normal_impulse[lower].sum() > result.normal_impulse[~lower].sum() * 1.2
    np.testing.assert_allclose(accelerations.v[0], 0.0, atol=1e-5)
    np.testing.assert_allclose(accelerations.omega[0], 0.0, atol=1e-4)


def test_a_box_sliding_on_a_level_floor_slows_at_mu_k_g(solve):
    mass, size, mu = 1.5, (0.2, 0.2, 0.2), 0.3
    centre = np.array([0.0, 0.1, 0.0])
    contacts = corners_on_floor(0, centre, size, mu=mu)
    accelerations = bodies_under_gravity([mass], size)
    slide = np.tile([1.0, 0.0, 0.0], (4, 1))  # sliding along +x: friction acts along −x
    solve(contacts, accelerations, np.array([centre, np.zeros(3)]), normal_bias=np.zeros(4),
                 tangent_bias=np.zeros((4, 2)), sticking=np.zeros(4, bool), slide_direction=slide,
                 iterations=200)
    assert accelerations.v[0, 0] == pytest.approx(-mu * G, rel=1e-6)
    assert accelerations.v[0, 1] == pytest.approx(0.0, abs=1e-6)


def test_a_crate_on_a_crate_presses_it_onto_the_floor_with_its_own_weight(solve):
    """The upper crate sits off-centre (but over the lower one's middle half): the floor's contacts take the whole
    weight, unevenly, and neither crate turns."""
    size, lower, upper = (0.2, 0.2, 0.2), 3.0, 1.0
    centres = np.array([[0.0, 0.1, 0.0], [0.04, 0.3, 0.0], [0.0, 0.0, 0.0]])
    floor = corners_on_floor(0, centres[0], size, mu=0.5)
    on_top = corners_on_floor(1, centres[1], size, mu=0.5, solid_body=0)
    contacts = Contacts.concatenate([floor, on_top])
    accelerations = bodies_under_gravity([lower, upper], size)
    result = solve(contacts, accelerations, centres, normal_bias=np.zeros(8), tangent_bias=np.zeros((8, 2)),
                          sticking=np.ones(8, bool), slide_direction=np.zeros((8, 3)), iterations=500)
    assert result.normal_impulse[4:].sum() == pytest.approx(upper * G, rel=1e-5)
    assert result.normal_impulse[:4].sum() == pytest.approx((lower + upper) * G, rel=1e-5)
    np.testing.assert_allclose(accelerations.v[:2], 0.0, atol=1e-5)
    np.testing.assert_allclose(accelerations.omega[:2], 0.0, atol=1e-4)


def test_one_corner_of_a_falling_box_on_another_free_box_pushes_both_as_the_effective_mass_says(solve):
    """Two free boxes in space touch at one point off both centres, frictionless; the upper one is pulled down. The
    contact force makes the relative normal acceleration zero: f = −a·n / (w_a + w_b), w = 1/m + (r × n)ᵀ I⁻¹
    (r × n) for each end; then each box gets ±f n / m and ±I⁻¹ (r × n) f."""
    size = (0.4, 0.2, 0.3)
    masses = [2.0, 5.0]  # upper (a), lower (b)
    centres = np.array([[0.1, 0.25, 0.05], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    point, normal = np.array([0.25, 0.1, 0.12]), np.array([0.0, 1.0, 0.0])
    contacts = Contacts(np.array([0]), np.array([1]), point[None], normal[None], np.zeros(1), np.zeros(1),
                        np.zeros(1), np.zeros(1), np.zeros(1, np.intp), np.full(1, PLANE), np.zeros(1, np.intp))
    accelerations = bodies_under_gravity(masses, size)
    accelerations.v[1] = 0.0  # only the upper box is pulled
    inverse = accelerations.inverse_inertia[:2].copy()
    solve(contacts, accelerations, centres, normal_bias=np.zeros(1), tangent_bias=np.zeros((1, 2)),
                 sticking=np.zeros(1, bool), slide_direction=np.zeros((1, 3)), iterations=50)
    arm_a, arm_b = np.cross(point - centres[0], normal), np.cross(point - centres[1], normal)
    w_a, w_b = 1 / masses[0] + arm_a @ inverse[0] @ arm_a, 1 / masses[1] + arm_b @ inverse[1] @ arm_b
    force = G / (w_a + w_b)  # the upper box approaches at g
    np.testing.assert_allclose(accelerations.v[0], [0, -G, 0] + force * normal / masses[0], atol=1e-9)
    np.testing.assert_allclose(accelerations.v[1], -force * normal / masses[1], atol=1e-9)
    np.testing.assert_allclose(accelerations.omega[0], inverse[0] @ arm_a * force, atol=1e-9)
    np.testing.assert_allclose(accelerations.omega[1], -inverse[1] @ arm_b * force, atol=1e-9)


@pytest.mark.parametrize("count", [3, 20])  # rows in Python floats (a few contacts) and in numpy (more)
def test_the_compiled_forces_are_the_numpy_ones(count):
    """Random contacts between three turned bodies and the fixed one, some sticking and some sliding, from a warm
    start and stopped mid-way (30 sweeps): the compiled solve gives numpy's forces and accelerations to round-off."""
    pytest.importorskip("numba", reason="numba is not installed: numpy solves the resting forces")
    rng = np.random.default_rng(count)
    bodies = 3
    for _ in range(4):
        x = np.vstack([rng.normal(size=(bodies, 3)), np.zeros((1, 3))])
        a = rng.integers(0, bodies, count)
        b = rng.integers(0, bodies + 1, count)
        b = np.where(b == a, bodies, b)
        normal = rng.normal(size=(count, 3))
        normal /= np.linalg.norm(normal, axis=1, keepdims=True)
        contacts = Contacts(a, np.where(b == bodies, STATIC, b), rng.normal(size=(count, 3)), normal,
                            np.zeros(count), np.zeros(count), rng.uniform(0.2, 0.9, count),
                            rng.uniform(0.1, 0.5, count), np.arange(count), np.full(count, PLANE),
                            np.zeros(count, np.intp))
        root = rng.normal(size=(bodies, 3, 3))
        inverse_inertia = np.zeros((bodies + 1, 3, 3))
        inverse_inertia[:bodies] = np.linalg.inv(root @ np.transpose(root, (0, 2, 1)) + np.eye(3))
        moving = np.append(np.ones(bodies), 0.0)[:, None]
        v, w = rng.normal(size=(bodies + 1, 3)) * moving, rng.normal(size=(bodies + 1, 3)) * moving
        inverse_mass = np.append(rng.uniform(0.5, 2.0, bodies), 0.0)
        sticking = rng.random(count) < 0.6
        slide = rng.normal(size=(count, 3))
        slide /= np.linalg.norm(slide, axis=1, keepdims=True)
        options = dict(normal_bias=rng.normal(size=count), tangent_bias=rng.normal(size=(count, 2)),
                       sticking=sticking, slide_direction=slide, iterations=30,
                       warm=(rng.random(count), rng.normal(size=(count, 2))))
        answers = []
        for compiled in (False, True):
            accelerations = BodyVelocities(v.copy(), w.copy(), inverse_mass, inverse_inertia)
            result = solve_forces(contacts, accelerations, x, compiled=compiled, **options)
            answers.append((result.normal_impulse, result.tangent_impulse, accelerations.v, accelerations.omega))
        for numpy_value, compiled_value in zip(*answers):
            np.testing.assert_allclose(compiled_value, numpy_value, rtol=1e-12, atol=1e-12)


def test_a_crate_on_a_plank_a_joint_holds_loads_the_joint_and_nothing_gives_way():
    """A plank welded to the world (a fixed joint: its six velocity rows), a crate resting off-centre on it. With the
    joint's rows, the contacts carry the crate's whole weight and neither body accelerates, the plank passing the
    load and its moment on to the joint; taken as free, the plank gives way under the crate (which sinks faster
    than m_c g / (m_c + m_p), the plank tipping away under the off-centre load)."""
    plank_size, crate_size, plank, crate = (1.0, 0.1, 0.3), (0.2, 0.2, 0.2), 2.0, 5.0
    centres = np.array([[0.0, 0.05, 0.0], [0.3, 0.2, 0.0], [0.0, 0.0, 0.0]])
    contacts = corners_on_floor(1, centres[1], crate_size, mu=0.5, solid_body=0)

    def loaded(jointed: JointedResponse | None) -> tuple[BodyVelocities, np.ndarray]:
        accelerations = bodies_under_gravity([plank, crate], crate_size)
        accelerations.inverse_inertia[0] = box_inverse_inertia(plank, plank_size)
        accelerations.v[0] = 0.0  # the joint holds the plank up against its own weight
        result = solve_forces(contacts, accelerations, centres, normal_bias=np.zeros(4), tangent_bias=np.zeros((4, 2)),
                              sticking=np.ones(4, bool), slide_direction=np.zeros((4, 3)), iterations=500,
                              jointed=jointed)
        return accelerations, result.normal_impulse

    weld = np.zeros((6, 18))  # rows over [v of the 3 slots, then ω of them]: the plank's (slot 0) v and ω are zero
    weld[:3, :3] = weld[3:, 9:12] = np.eye(3)
    accelerations = bodies_under_gravity([plank, crate], crate_size)
    accelerations.inverse_inertia[0] = box_inverse_inertia(plank, plank_size)
    held, pressing = loaded(JointedResponse(weld, BlockInverse(accelerations.inverse_mass,
                                                               accelerations.inverse_inertia)))
    assert pressing.sum() == pytest.approx(crate * G, rel=1e-6)
    np.testing.assert_allclose(held.v[:2], 0.0, atol=1e-6)
    np.testing.assert_allclose(held.omega[:2], 0.0, atol=1e-6)
    free, _ = loaded(None)
    assert free.v[1, 1] < -G * crate / (crate + plank)  # the crate sinks with the plank, which tips away under it
    assert abs(free.omega[0, 2]) > 1.0
