"""Two moving bodies collide under every method, with no floor to cap the step: textbook velocities, impact times
from the closed-form gap equation, and no tunnelling through a moving slab.

The adaptive methods take long steps in free flight (a straight line or a parabola is exact for them), so each step
can carry both bodies a long way towards each other; an impact search that only looks as far as one body travels
lets them pass through each other. These scenes have no collider at all, so nothing else shortens the steps.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from animbatch.errors import AccuracyWarning
from animbatch.sim.invariants import kinetic_energy, linear_momentum
from support.scenes import ADAPTIVE, counting, run, states

FIXED = ["symplectic_euler", "verlet"]


def pucks(method: str, e: float) -> tuple:
    """Head-on pucks of 1 and 3 kg on a frictionless line, 1.8 m apart, closing at 2 m/s."""
    model, trajectory = run(f"""
        duration: 2
        fps: 30
        solver: {{method: {method}, rtol: 1.0e-6, atol: 1.0e-9}}
        materials: {{puck: {{restitution: {e}, static_friction: 0, kinetic_friction: 0}}}}
        contacts: {{}}
        bodies:
          - {{name: a, mass: 1, radius: 0.1, position: [-1, 0, 0], velocity: [1, 0, 0], material: puck}}
          - {{name: b, mass: 3, radius: 0.1, position: [1, 0, 0], velocity: [-1, 0, 0], material: puck}}
    """)
    return model, trajectory, states(model, trajectory)


@pytest.mark.slow
@pytest.mark.parametrize("e", [1.0, 0.5])
@pytest.mark.parametrize("method", ADAPTIVE + FIXED)
def test_head_on_pucks_leave_with_the_textbook_velocities(method, e):
    """v₁' = (m₁v₁ + m₂v₂ - m₂e(v₁ - v₂))/(m₁ + m₂) and likewise v₂'; momentum conserved to round-off; the kinetic
    energy lost is ½ μ (1 - e²) Δv²; the impact is at t = 1.8 m / 2 m/s."""
    model, trajectory, y = pucks(method, e)
    m1, m2, v1, v2 = 1.0, 3.0, 1.0, -1.0
    after1 = (m1 * v1 + m2 * v2 - m2 * e * (v1 - v2)) / (m1 + m2)
    after2 = (m1 * v1 + m2 * v2 + m1 * e * (v1 - v2)) / (m1 + m2)
    assert trajectory.velocities[-1, :, 0] == pytest.approx([after1, after2], abs=1e-9)
    momentum = linear_momentum(model, y)
    assert np.abs(momentum - momentum[0]).max() < 1e-12
    reduced = m1 * m2 / (m1 + m2)
    lost = kinetic_energy(model, y[0]) - kinetic_energy(model, y[-1])
    assert lost == pytest.approx(0.5 * reduced * (1 - e**2) * (v1 - v2) ** 2, abs=1e-9)
    times = [t for t, _ in trajectory.solver_stats["impacts"]]
    step = 0.0 if method in ADAPTIVE else 1e-3  # fixed steps put impacts on step boundaries
    assert len(times) == 1 and times[0] == pytest.approx(0.9, abs=1e-9 + step)


def gap_closes_at(x_a, v_a, x_b, v_b, touching):
    """First time [s] at which |x_b - x_a + (v_b - v_a) t| = touching: under one uniform gravity both balls fall
    alike, so their relative motion is a straight line at constant speed (a quadratic in t)."""
    d, w = np.subtract(x_b, x_a), np.subtract(v_b, v_a)
    a, b, c = w @ w, 2 * d @ w, d @ d - touching**2
    return (-b - np.sqrt(b * b - 4 * a * c)) / (2 * a)


@pytest.mark.parametrize("method", ADAPTIVE)
def test_balls_thrown_at_each_other_under_gravity_collide_when_the_gap_equation_says(method):
    """Two balls thrown towards each other on crossing parabolas meet at the root of the closed-form gap equation,
    and momentum changes only by what gravity gives (M g t), also across the impact."""
    x_a, v_a, x_b, v_b = [-3, 0, 0], [6, 5, 0.3], [3, 0.4, 0], [-4, 4.5, 0]
    model, trajectory = run(f"""
        duration: 1.2
        fps: 30
        solver: {{method: {method}, rtol: 1.0e-8, atol: 1.0e-10}}
        contacts: {{}}
        fields: [{{type: gravity}}]
        bodies:
          - {{name: a, mass: 0.5, radius: 0.12, position: {x_a}, velocity: {v_a}}}
          - {{name: b, mass: 0.8, radius: 0.1, position: {x_b}, velocity: {v_b}}}
    """)
    expected = gap_closes_at(x_a, v_a, x_b, v_b, 0.22)
    assert 0.2 < expected < 1.0  # they do meet in flight, in the middle of the run
    times = [t for t, _ in trajectory.solver_stats["impacts"]]
    assert len(times) == 1 and times[0] == pytest.approx(expected, abs=1e-7)
    y = states(model, trajectory)
    gravity_given = np.outer(trajectory.times, [0, -9.81 * 1.3, 0])
    assert np.abs(linear_momentum(model, y) - gravity_given - linear_momentum(model, y[0])).max() < 1e-7
    separation = np.linalg.norm(trajectory.positions[:, 0] - trajectory.positions[:, 1], axis=1)
    assert separation.min() > 0.22 - 1e-6  # they never overlap


@pytest.mark.parametrize("method", ADAPTIVE + FIXED)
def test_a_fast_small_sphere_never_passes_a_moving_slab(method):
    """A 5 mm pellet at 100 m/s and a 1 cm slab at 100 m/s towards it (each moves 3.3 m per frame): the pellet
    bounces off the slab's face at t = (gap) / (closing speed) with Newton's impact law, and stays on its side."""
    model, trajectory = run(f"""
        duration: 0.3
        fps: 30
        solver: {{method: {method}, rtol: 1.0e-6, atol: 1.0e-9}}
        materials: {{hard: {{restitution: 0.8, static_friction: 0, kinetic_friction: 0}}}}
        contacts: {{}}
        bodies:
          - {{name: pellet, mass: 0.01, radius: 0.005, position: [-2, 0, 0], velocity: [100, 0, 0], material: hard}}
          - {{name: slab, type: rigid, shape: {{type: box, size: [0.01, 1, 1]}}, density: 1000, position: [2, 0, 0],
              velocity: [-100, 0, 0], material: hard}}
    """)
    pellet, slab = trajectory.positions[:, 0, 0], trajectory.positions[:, 1, 0]
    assert np.all(pellet < slab - 0.005)  # on its own side at every frame
    m1, m2, e, closing = 0.01, 10.0, 0.8, 200.0
    after1 = 100 - (1 + e) * m2 / (m1 + m2) * closing
    after2 = -100 + (1 + e) * m1 / (m1 + m2) * closing
    assert trajectory.velocities[-1, :, 0] == pytest.approx([after1, after2], rel=1e-9)
    times = [t for t, _ in trajectory.solver_stats["impacts"]]
    step = 0.0 if method in ADAPTIVE else 1e-3
    assert times and times[0] == pytest.approx((4 - 0.005 - 0.005) / closing, abs=1e-9 + step)


@pytest.mark.parametrize("method", FIXED)
def test_fixed_steps_look_for_an_impact_as_far_as_both_bodies_close(method):
    """Two 1 mm beads at 60 m/s each close 0.12 m per 1 ms step, far more than their size: speculative contacts
    sized for one body's travel (1.5 × 0.06 m) can leave them 0.09–0.12 m apart at a step's start and let them pass
    through each other within the step; sized for both, they bounce (e = 1: the velocities swap)."""
    _, trajectory = run("""
        duration: 0.2
        fps: 50
        solver: {method: %s, dt: 1.0e-3}
        materials: {bead: {restitution: 1, static_friction: 0, kinetic_friction: 0}}
        contacts: {}
        bodies:
          - {name: a, mass: 0.01, radius: 0.001, position: [-3.0005, 0, 0], velocity: [60, 0, 0], material: bead}
          - {name: b, mass: 0.01, radius: 0.001, position: [3.1032, 0, 0], velocity: [-60, 0, 0], material: bead}
    """ % method)
    assert trajectory.velocities[-1, :, 0] == pytest.approx([-60, 60], rel=1e-9)
    assert np.all(trajectory.positions[:, 0, 0] < trajectory.positions[:, 1, 0])


# ------------------------------------------------------------------------------------------------ the safety net


def audit_warnings(text: str) -> tuple:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        _, trajectory = run(text)
    return trajectory, [str(w.message) for w in caught if issubclass(w.category, AccuracyWarning)]


@pytest.fixture
def impact_search_off(monkeypatch):
    """Adaptive runs whose impact search finds nothing: a method that misses every collision."""
    from animbatch.sim.contact import impact_events
    from animbatch.sim.contact.contacts import Contacts

    monkeypatch.setattr(impact_events.ContactEvents, "_impact_candidates",
                        lambda self, y0, y1, h, t1=0.0: (Contacts.concatenate([]), np.zeros(0)))


@pytest.fixture(params=["numpy", "numba"])
def audit_search(request, monkeypatch) -> tuple[bool, list[int]]:
    """The overlap audit searching the frames with numpy, or with the compiled probe search (which it takes where
    numba is loaded already, as after any compiled run): both must find the same overlap. Returns whether the
    compiled search is expected, and a list that grows by one per compiled search."""
    from animbatch.sim.contact import detection

    if request.param == "numba":
        pytest.importorskip("numba")
    else:
        monkeypatch.setenv("ANIMBATCH_KERNELS", "numpy")
    return request.param == "numba", counting(monkeypatch, detection, "_compiled_probe_contacts")


def test_a_collision_the_method_misses_is_reported_with_both_bodies_and_the_time(impact_search_off, audit_search):
    """Should the impact search ever miss (here it is switched off), the run does not pass silently: the ledger
    finds the pucks deepest inside each other at t = 1 s, when their centres meet (closed form: centres 2 - 2t apart,
    overlap 0.2 - |2 - 2t|, so 0.2 m), and warns, naming both bodies, the method and what to change."""
    trajectory, warned = audit_warnings("""
        duration: 1.2
        fps: 10
        solver: {method: RK45}
        contacts: {}
        bodies:
          - {name: a, radius: 0.1, position: [-1, 0, 0], velocity: [1, 0, 0]}
          - {name: b, radius: 0.1, position: [1, 0, 0], velocity: [-1, 0, 0]}
    """)
    missed = trajectory.ledger["contacts"]["missed"]
    assert (missed["body"], missed["solid"]) in (("a", "body 'b'"), ("b", "body 'a'"))
    assert missed["depth"] == pytest.approx(0.2, abs=1e-9) and missed["time"] == pytest.approx(1.0)
    assert len(warned) == 1 and "RK45 missed a collision" in warned[0] and "solver.max_step" in warned[0]
    compiled, searches = audit_search
    assert bool(searches) == compiled


def test_a_small_body_crossing_a_thin_slab_between_two_frames_is_seen(impact_search_off, audit_search):
    """A 5 mm pellet passing a 1 cm slab within one frame (each moves 3.3 m per frame) is inside it for 0.1 ms only:
    the audit looks where the two come closest between the frames, and finds the pellet's centre on the slab's
    mid-plane at t = 4 m / 200 m/s = 0.02 s, 5 mm + 5 mm deep."""
    trajectory, warned = audit_warnings("""
        duration: 0.1
        fps: 30
        solver: {method: RK45}
        contacts: {}
        bodies:
          - {name: pellet, mass: 0.01, radius: 0.005, position: [-2, 0, 0], velocity: [100, 0, 0]}
          - {name: slab, type: rigid, shape: {type: box, size: [0.01, 1, 1]}, density: 1000, position: [2, 0, 0],
             velocity: [-100, 0, 0]}
    """)
    missed = trajectory.ledger["contacts"]["missed"]
    assert missed["between_frames"] and missed["body"] in ("pellet", "slab")
    assert missed["time"] == pytest.approx(0.02, abs=1e-9) and missed["depth"] == pytest.approx(0.01, abs=1e-9)
    assert len(warned) == 1 and "between two frames" in warned[0] and "'slab'" in warned[0]
    compiled, searches = audit_search
    assert bool(searches) == compiled


@pytest.mark.slow
def test_bodies_placed_inside_each_other_are_named_with_the_overlap():
    """Two balls of radius 0.1 m whose centres start 0.15 m apart overlap by 0.05 m: the warning says the scene
    placed them so, by how much, and to move them apart; it is not called a missed collision."""
    trajectory, warned = audit_warnings("""
        duration: 0.5
        solver: {method: symplectic_euler}
        contacts: {}
        bodies:
          - {name: left, radius: 0.1, position: [-0.075, 0, 0]}
          - {name: right, radius: 0.1, position: [0.075, 0, 0]}
    """)
    contacts = trajectory.ledger["contacts"]
    assert contacts["missed"] is None
    assert contacts["starts_inside"]["depth"] == pytest.approx(0.05)
    assert len(warned) == 1 and "starts 0.05 m inside body" in warned[0] and "0.05 m further apart" in warned[0]


def test_runs_that_collide_correctly_raise_no_contact_warning():
    """The pellet and the slab, with the impact found, leave nothing for the audit."""
    trajectory, warned = audit_warnings("""
        duration: 0.3
        solver: {method: DOP853, rtol: 1.0e-6}
        materials: {hard: {restitution: 0.8, static_friction: 0, kinetic_friction: 0}}
        contacts: {}
        bodies:
          - {name: pellet, mass: 0.01, radius: 0.005, position: [-2, 0, 0], velocity: [100, 0, 0], material: hard}
          - {name: slab, type: rigid, shape: {type: box, size: [0.01, 1, 1]}, density: 1000, position: [2, 0, 0],
             velocity: [-100, 0, 0], material: hard}
    """)
    assert not warned and trajectory.ledger["contacts"] == {"starts_inside": None, "missed": None}


@pytest.mark.parametrize("table", ["collider", "welded body"])
@pytest.mark.parametrize("method", ["RK45", "DOP853"])
def test_a_box_dropped_onto_a_table_strikes_its_top_face_at_the_free_fall_time_and_rests_there(method, table):
    """A 0.3 m cube dropped from 0.15 m above a slab, a box collider or a body welded to the world by a fixed joint:
    an adaptive method's first long step of free flight carries the cube through the slab (a third of a second,
    half a metre down), where its corners are nearest the slab's bottom face. Named as they came in, against the top
    face, they strike it at √(2h/g), and the cube lands on it (before: they were measured to the bottom face, and it
    fell through). The welded slab passes the cube's weight on to its joint and does not move (before: its contact
    forces took it as a free body, and it sank under the load until the joint's stabilisation held it, 1 cm down)."""
    g, drop = 9.81, 0.15
    slab = "shape: {type: box, size: [1, 0.2, 1]}, position: [0, 0, 0], material: dead"
    solid = ("colliders: [{type: box, size: [1, 0.2, 1], position: [0, 0, 0], material: dead}]"
             if table == "collider" else
             f"  - {{name: table, type: rigid, density: 2000, {slab}}}\n"
             "        joints: [{type: fixed, between: [table]}]\n        contacts: {}")
    model, trajectory = run(f"""
        duration: 0.5
        fps: 100
        solver: {{method: {method}}}
        materials: {{dead: {{restitution: 0, static_friction: 0.5, kinetic_friction: 0.5}}}}
        fields: [{{type: gravity, g: [0, {-g}, 0]}}]
        bodies:
          - {{name: cube, type: rigid, shape: {{type: box, size: [0.3, 0.3, 0.3]}}, density: 2000,
             position: [0, {0.25 + drop}, 0], material: dead}}
        {solid}
    """)
    height, t = trajectory.positions[:, 0, 1], trajectory.times
    strike = np.sqrt(2 * drop / g)
    before = t < strike
    np.testing.assert_allclose(height[before], 0.25 + drop - 0.5 * g * t[before] ** 2, atol=1e-6)
    np.testing.assert_allclose(height[~before], 0.25, atol=1e-4)  # on the slab's top (0.1) from the strike on
    if table != "collider":
        np.testing.assert_allclose(trajectory.positions[:, 1], 0.0, atol=1e-6)
