"""Rigid-body motion against closed forms and invariants: torque-free motion, precession, torque from off-centre
forces, buoyancy, and every integrator."""

from __future__ import annotations

import numpy as np
import pytest

from animbatch import api
from animbatch import quaternion as Q
from animbatch.sim.invariants import angular_momentum, kinetic_energy, total_energy
from animbatch.sim.model import Dynamics
from animbatch.stages import load_scene
from support.paths import REPO
from support.scenes import ADAPTIVE, FIXED_STEP, run, states

TUMBLING = """
    duration: 30
    fps: 10
    solver: {method: DOP853, rtol: 1.0e-11, atol: 1.0e-13}
    bodies:
      - {name: box, type: rigid, shape: {type: box, size: [0.2, 0.4, 0.6]}, density: 700,
         angular_velocity: [0.15, 6.0, 0.15]}
"""


def axis_in_world(trajectory, body: int, axis: int) -> np.ndarray:
    """A body axis (0 x, 1 y, 2 z) in world coordinates at every frame, (F, 3)."""
    return Q.rotate(trajectory.orientations[:, body], np.eye(3)[axis])


@pytest.mark.slow
def test_torque_free_asymmetric_body_conserves_angular_momentum_and_energy():
    """Over 30 s of tumbling (several flips), L (world) and kinetic energy drift less than 1e-8 with DOP853."""
    model, trajectory = run(TUMBLING)
    y = states(model, trajectory)
    momentum, energy = angular_momentum(model, y), kinetic_energy(model, y)
    assert np.abs(momentum - momentum[0]).max() < 1e-8 * np.linalg.norm(momentum[0])
    assert np.abs(energy / energy[0] - 1).max() < 1e-8
    flips = np.sum(np.diff(np.sign(axis_in_world(trajectory, 0, 1)[:, 1])) != 0)
    assert flips >= 5  # the intermediate axis keeps flipping over


@pytest.mark.slow
def test_spin_about_the_largest_or_smallest_axis_is_stable():
    """The same perturbation about the largest (x) or smallest (z) principal axis does not flip the body."""
    for spin, axis in (("[6.0, 0.15, 0.15]", 0), ("[0.15, 0.15, 6.0]", 2)):
        _, trajectory = run(TUMBLING, f"bodies[box].angular_velocity={spin}", "duration=10")
        alignment = axis_in_world(trajectory, 0, axis)[:, axis]
        assert alignment.min() > 0.9


@pytest.mark.slow
@pytest.mark.parametrize("method", FIXED_STEP)
def test_fixed_step_methods_keep_torque_free_angular_momentum(method):
    """Without torque, kicks leave L untouched and Runge-Kutta steps keep it to round-off; energy stays close."""
    model, trajectory = run(TUMBLING, f"solver.method={method}", "solver.dt=2e-3", "duration=10")
    y = states(model, trajectory)
    momentum, energy = angular_momentum(model, y), kinetic_energy(model, y)
    assert np.abs(momentum - momentum[0]).max() < 1e-9 * np.linalg.norm(momentum[0])
    tolerance = {"euler": 0.5, "symplectic_euler": 0.5, "backward_euler": 0.5, "midpoint": 1e-3, "verlet": 1e-3}[method]
    assert np.abs(energy / energy[0] - 1).max() < tolerance


def test_free_symmetric_top_precesses_about_l_at_l_over_i1():
    """A torque-free symmetric body: its symmetry axis turns about the fixed L at the rate |L| / I₁."""
    model, trajectory = run("""
        duration: 4
        fps: 50
        solver: {method: DOP853, rtol: 1.0e-11, atol: 1.0e-13}
        bodies:
          - {name: coin, type: rigid, shape: {type: cylinder, radius: 0.2, length: 0.05}, density: 8000,
             angular_velocity: [1.5, 0.0, 4.0]}
    """)
    y = states(model, trajectory)
    momentum = angular_momentum(model, y)[0]
    axis = axis_in_world(trajectory, 0, 2)
    unit = momentum / np.linalg.norm(momentum)
    across = np.cross(unit, [0.0, 1.0, 0.0])
    across /= np.linalg.norm(across)
    around = np.unwrap(np.arctan2(axis @ np.cross(unit, across), axis @ across))
    rate = np.polyfit(trajectory.times, around, 1)[0]
    assert abs(rate) == pytest.approx(np.linalg.norm(momentum) / model.rigid.inertia[0][0, 0], rel=1e-6)
    assert np.ptp(axis @ unit) < 1e-8  # the cone angle stays fixed


@pytest.mark.slow
def test_heavy_top_precesses_at_the_analytic_rate():
    """The bundled top's axis turns about the vertical at the steady rate of a heavy symmetric top,
    Ω = (I₃ω₃ - sqrt((I₃ω₃)² - 4 I₁' m g d cos θ)) / (2 I₁' cos θ) (I₁' about the pivot), ≈ m g d / (I₃ ω₃)."""
    loaded = load_scene(REPO / "scenes" / "spinning_top.yaml", ["duration=2.5"])
    model = api.compile_model(loaded)
    trajectory = api.simulate(loaded, model=model)
    axis = axis_in_world(trajectory, 0, 2)
    azimuth = np.unwrap(np.arctan2(axis[:, 0], axis[:, 2]))
    measured = np.polyfit(trajectory.times, azimuth, 1)[0]
    mass, inertia = model.rigid.mass[0], model.rigid.inertia[0]
    distance = np.linalg.norm(model.rigid.centre[0])  # from the tip (shape origin, at the pivot)
    spin_momentum = inertia[2, 2] * 400.0
    mgd, tilt = mass * 9.81 * distance, np.radians(25)
    transverse = inertia[0, 0] + mass * distance**2
    steady = (spin_momentum - np.sqrt(spin_momentum**2 - 4 * transverse * mgd * np.cos(tilt))) / (
        2 * transverse * np.cos(tilt))
    assert measured == pytest.approx(steady, rel=5e-3)
    assert measured == pytest.approx(mgd / spin_momentum, rel=0.03)
    assert np.degrees(np.arccos(axis[:, 1])).max() < 26  # nutation stays small for a fast top


OFF_CENTRE = """
    duration: 0.2
    fps: 50
    solver: {method: DOP853, rtol: 1.0e-11, atol: 1.0e-13}
    bodies: [{name: plate, type: rigid, shape: {type: box, size: [1.0, 0.1, 1.0]}, mass: 2}]
    fields: [{type: force, force: [0, 3, 0], at: [0.5, 0, 0]}]
"""


def test_off_centre_force_spins_the_body_as_r_cross_f_predicts():
    """A force f = 3 ŷ at r = 0.5 x̂ gives τ = r × f = 1.5 ẑ: the body turns about +z, L_z grows as τ t
    (while the turn is small), and its centre accelerates at f / M as if the force acted there."""
    model, trajectory = run(OFF_CENTRE)
    y = states(model, trajectory)
    t = trajectory.times
    omega = trajectory.angular_velocities[:, 0]
    assert np.all(omega[1:, 2] > 0) and np.abs(omega[:, :2]).max() < 1e-9
    # the lever turns with the plate (by α t²/2, α = τ/I = 4.5 rad/s²), so L_z = τ t only while that is small
    early = t <= 0.1
    assert np.allclose(model.layout.view(y, "rigid_angular_momentum")[early, 0, 2], 1.5 * t[early], rtol=1e-3)
    assert np.allclose(trajectory.positions[:, 0, 1], 0.5 * 1.5 * t**2, rtol=1e-6, atol=1e-12)
    _, central = run(OFF_CENTRE.replace("at: [0.5, 0, 0]", "at: [0, 0, 0]"))
    assert np.abs(central.angular_velocities).max() < 1e-12


def test_constant_torque_gives_l_equal_tau_t():
    """dL/dt = τ: a constant world torque makes L = τ t exactly, whatever the body does meanwhile."""
    model, trajectory = run("""
        duration: 2
        fps: 10
        solver: {method: RK45, rtol: 1.0e-10, atol: 1.0e-12}
        bodies: [{name: b, type: rigid, shape: {type: box, size: [1, 2, 3]}, mass: 3, angular_velocity: [1, 0, 0]}]
        fields: [{type: torque, torque: [0.2, -0.5, 0.3]}]
    """)
    momentum = model.layout.view(states(model, trajectory), "rigid_angular_momentum")[:, 0]
    l0 = np.array([3 / 12 * 13, 0, 0])
    assert np.allclose(momentum, l0 + np.outer(trajectory.times, [0.2, -0.5, 0.3]), atol=1e-9)


def test_angular_drag_decays_spin_exponentially():
    """τ = -c ω on a sphere (I = 2/5 m r²): ω(t) = ω₀ exp(-c t / I)."""
    _, trajectory = run("""
        duration: 2
        fps: 10
        solver: {method: DOP853, rtol: 1.0e-11, atol: 1.0e-13}
        bodies: [{name: ball, type: rigid, shape: {type: sphere, radius: 0.5}, mass: 4, angular_velocity: [0, 3, 0]}]
        fields: [{type: angular_drag, coefficient: 0.2}]
    """)
    inertia = 0.4 * 4 * 0.25
    assert np.allclose(trajectory.angular_velocities[:, 0, 1], 3 * np.exp(-0.2 * trajectory.times / inertia),
                       atol=1e-9)


def test_drag_at_a_point_turns_the_body():
    """Linear drag at a point off the centre of mass of a translating body gives torque r × (-C v)."""
    model, _ = run("""
        duration: 0.1
        bodies: [{name: b, type: rigid, shape: {type: sphere, radius: 0.5}, mass: 1, velocity: [0, 0, 2]}]
        fields: [{type: drag, model: linear, coefficient: 0.3, at: [0.5, 0, 0]}]
    """)
    dynamics = Dynamics(model)
    force, torque = dynamics.loads(0.0, dynamics.kinematics(*dynamics.split(model.y0.copy())))
    assert np.allclose(force[0], [0, 0, -0.6])
    assert np.allclose(torque[0], np.cross([0.5, 0, 0], [0, 0, -0.6]))


HANGING = """
    duration: 3
    fps: 10
    solver: {method: DOP853, rtol: 1.0e-11, atol: 1.0e-13}
    anchors: [{name: hook, position: [0, 2, 0]}]
    bodies:
      - {name: box, type: rigid, shape: {type: box, size: [0.4, 0.3, 0.2]}, density: 500, position: [0.2, 1.2, 0.1],
         angular_velocity: [0.3, 0.5, -0.2]}
    springs: [{between: [hook, box], stiffness: 150, rest_length: 0.4, attach: [null, [0.2, 0.15, 0.1]]}]
    fields: [{type: gravity}]
"""


@pytest.mark.slow
def test_spring_at_a_body_point_conserves_energy():
    """An undamped spring hooked to a corner: translation and rotation exchange energy, the total is conserved."""
    model, trajectory = run(HANGING)
    energy = total_energy(model, states(model, trajectory))
    rotational = trajectory.angular_velocities[:, 0]
    assert np.ptp(np.linalg.norm(rotational, axis=1)) > 0.5  # the spring really turns the box
    assert np.abs(energy - energy[0]).max() < 1e-8 * np.abs(energy).max()


def orientation_error(method: str, dt: float, reference) -> float:
    _, trajectory = run(HANGING, f"solver.method={method}", f"solver.dt={dt}", "duration=1")
    positions = np.abs(trajectory.positions - reference.positions[: len(trajectory.times)]).max()
    turns = np.abs(np.abs(np.einsum("fbi,fbi->fb", trajectory.orientations,
                                    reference.orientations[: len(trajectory.times)])) - 1).max()
    return max(positions, np.sqrt(2 * turns))


@pytest.mark.slow
@pytest.mark.parametrize("method, order", [("euler", 1), ("midpoint", 2), ("symplectic_euler", 1), ("verlet", 2)])
def test_fixed_step_methods_converge_at_their_order_on_a_rigid_body(method, order):
    """On a box swinging and turning on a spring (configuration-dependent torque), halving dt divides the error
    by 2^order: the rotation update keeps each method's order."""
    _, reference = run(HANGING, "duration=1")
    steps = [0.1 / 2**k for k in range(5, 8)]
    errors = [orientation_error(method, dt, reference) for dt in steps]
    observed = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(np.abs(observed - order) < 0.25), f"{method}: observed {observed}"


@pytest.mark.slow
@pytest.mark.parametrize("method", ADAPTIVE + FIXED_STEP)
def test_quaternions_stay_unit_at_every_frame(method):
    """Every method, adaptive or fixed-step, delivers unit quaternions at every frame."""
    _, trajectory = run(HANGING, f"solver.method={method}", "solver.dt=2e-3", "solver.rtol=1e-6")
    norms = np.linalg.norm(trajectory.orientations[:, 0], axis=1)
    assert np.abs(norms - 1).max() < 1e-12


# ---------------------------------------------------------------------------------------------------------------
# buoyancy

# Damping near critical for the 480 kg raft: heave stiffness ρ g A = 39 kN/m, roll stiffness ρ g V GM ≈ 12 kN·m/rad
# (damping is scaled by the submerged fraction, 0.3 here).
WATER = "{type: buoyancy, density: 1000, level: 0, linear_damping: 8000, angular_damping: 3000}"


@pytest.mark.slow
def test_floating_box_settles_at_archimedes_depth():
    """A 2 × 0.4 × 2 m box of density 300 floats with 0.3 of its height under water: centre at 0.2 - 0.12 m."""
    _, trajectory = run(f"""
        duration: 15
        fps: 5
        bodies: [{{name: raft, type: rigid, shape: {{type: box, size: [2, 0.4, 2]}}, density: 300,
                   position: [0, 0.5, 0]}}]
        fields: [{{type: gravity}}, {WATER}]
    """)
    assert trajectory.positions[-1, 0, 1] == pytest.approx(0.2 - 0.3 * 0.4, abs=1e-4)
    assert np.abs(trajectory.velocities[-1]).max() < 1e-3


@pytest.mark.slow
def test_tilted_floating_box_rights_itself():
    """Tilted by 25°, a stable raft turns back upright under the buoyant torque (damped, it settles)."""
    _, trajectory = run(f"""
        duration: 15
        fps: 5
        bodies: [{{name: raft, type: rigid, shape: {{type: box, size: [2, 0.4, 2]}}, density: 300,
                   position: [0, 0.08, 0], orientation: {{axis: [0, 0, 1], angle: 25}}}}]
        fields: [{{type: gravity}}, {WATER}]
    """)
    up = axis_in_world(trajectory, 0, 1)
    tilt = np.degrees(np.arccos(np.clip(up[:, 1], -1, 1)))
    assert tilt[0] == pytest.approx(25, abs=1e-9) and tilt[-1] < 0.1
    assert np.all(up[:, 1] > 0)  # it never capsized


def test_a_sphere_s_submerged_cap_has_the_volume_and_centroid_of_the_sliced_ball(recwarn):
    """The cap under the surface against the ball sliced into thin discs (volume and centroid), dry, half and fully
    wet; tilted 'up' too; a sphere of no size (a particle of radius 0) is dry and warns of nothing."""
    from animbatch.sim.forces.buoyancy import spherical_caps

    up = np.array([0.0, 0.6, 0.8])
    radius, centre_height = 0.3, 1.0
    levels = [0.5, 0.8, 0.95, 1.0, 1.2, 1.5]  # under the bottom, wet up to 0.1 … 0.7 m, and over the top
    centres = np.tile(centre_height * up + np.array([0.0, -0.8, 0.6]) * 2.0, (len(levels), 1))  # off-axis centres
    radii = np.full(len(levels), radius)
    for k, level in enumerate(levels):
        volume, centroid = spherical_caps(centres[k:k + 1], radii[k:k + 1], level, up)
        z = np.linspace(-radius, radius, 200_001)[:-1] + radius / 200_000  # disc centres along up, from the centre
        area = np.pi * (radius**2 - z**2)
        wet = z + centre_height <= level
        expected = np.sum(area[wet]) * (2 * radius / 200_000)
        assert volume[0] == pytest.approx(expected, rel=1e-4, abs=1e-12)
        if expected > 0:
            height = np.sum((area * z)[wet]) / np.sum(area[wet])
            np.testing.assert_allclose(centroid[0], centres[k] + height * up, rtol=0, atol=1e-5)
    volume, centroid = spherical_caps(np.zeros((1, 3)), np.zeros(1), 1.0, up)
    assert volume[0] == 0 and np.all(np.isfinite(centroid))
    assert not [w for w in recwarn.list if issubclass(w.category, RuntimeWarning)]


def test_spheres_and_particles_float_at_the_depth_of_their_density():
    """A rigid sphere and a particle of half the water's density float with their centres at the surface; a
    sphere of 0.1 times its density sits with a cap of volume 0.1 V under water."""
    _, trajectory = run(f"""
        duration: 20
        fps: 5
        bodies:
          - {{name: half, type: rigid, shape: {{type: sphere, radius: 0.2}}, density: 500, position: [0, 0.3, 0]}}
          - {{name: bead, radius: 0.1, mass: {500 * 4 / 3 * np.pi * 0.001!r}, position: [1, 0.2, 0]}}
          - {{name: light, type: rigid, shape: {{type: sphere, radius: 0.2}}, density: 100, position: [2, 0.3, 0]}}
        fields:
          - {{type: gravity}}
          - {{type: buoyancy, density: 1000, level: 0, linear_damping: 600, bodies: [half, light]}}
          - {{type: buoyancy, density: 1000, level: 0, linear_damping: 100, bodies: [bead]}}
    """)
    names = list(trajectory.body_names)
    assert trajectory.positions[-1, names.index("half"), 1] == pytest.approx(0.0, abs=1e-4)
    assert trajectory.positions[-1, names.index("bead"), 1] == pytest.approx(0.0, abs=1e-4)
    # cap of depth h: π h² (3r - h) / 3 = 0.1 · 4/3 π r³
    r = 0.2
    depth = next(h for h in np.linspace(0, 2 * r, 200001) if np.pi * h * h * (3 * r - h) / 3 >= 0.4 / 3 * np.pi * r**3)
    assert trajectory.positions[-1, names.index("light"), 1] == pytest.approx(r - depth, abs=1e-4)


def test_a_dumbbell_of_two_spheres_floats_level_with_both_centres_at_the_surface():
    """Two spheres 0.6 m apart on one rigid body (a compound: off-centre sphere pieces, summed per body), of half
    the water's density and dropped tilted by 20°, float with both centres on the surface: each sinks by its own
    cap, so the lower one is pushed up harder and the dumbbell rights itself to level."""
    _, trajectory = run("""
        duration: 5
        fps: 10
        bodies:
          - name: dumbbell
            type: rigid
            density: 500
            shape:
              type: compound
              parts:
                - {shape: {type: sphere, radius: 0.1}, offset: [-0.3, 0, 0]}
                - {shape: {type: sphere, radius: 0.1}, offset: [0.3, 0, 0]}
            position: [0, 0.15, 0]
            orientation: {axis: [0, 0, 1], angle: 20}
        fields:
          - {type: gravity}
          - {type: buoyancy, density: 1000, level: 0, linear_damping: 200, angular_damping: 20}
    """)
    assert trajectory.positions[-1, 0, 1] == pytest.approx(0.0, abs=1e-4)
    along = axis_in_world(trajectory, 0, 0)
    assert np.degrees(np.arcsin(abs(along[0, 1]))) == pytest.approx(20, abs=1e-9)
    assert abs(along[-1, 1]) < 1e-4  # level: its axis horizontal


@pytest.mark.slow
def test_bundled_floating_scene_settles_as_its_comment_says():
    """The log floats with its centre 0.024 m under water, and the balsa cube upright with 15 % submerged: settled
    by 6 s of the scene's 10 (the log's bobbing is down to 0.1 mm by then)."""
    loaded = load_scene(REPO / "scenes" / "floating.yaml", ["duration=6"])
    trajectory = api.simulate(loaded)
    names = list(trajectory.body_names)
    assert trajectory.positions[-1, names.index("log"), 1] == pytest.approx(-0.0237, abs=5e-4)
    assert trajectory.positions[-1, names.index("cube"), 1] == pytest.approx(0.2 - 0.15 * 0.4, abs=1e-3)
    up = axis_in_world(trajectory, names.index("cube"), 1)
    assert abs(up[-1, 1]) > np.cos(np.radians(1))


def test_bundled_dumbbell_centre_follows_the_parabola_and_spins_steadily():
    """Gravity has no torque about the centre of mass: it flies on the parabola of its launch and ω stays 14 ẑ."""
    loaded = load_scene(REPO / "scenes" / "dumbbell.yaml")
    model = api.compile_model(loaded)
    trajectory = api.simulate(loaded, model=model)
    t = trajectory.times
    start = trajectory.positions[0, 0]
    expected = start + np.outer(t, [1.0, 4.6, 0]) + np.outer(0.5 * t**2, [0, -9.81, 0])
    assert np.allclose(trajectory.positions[:, 0], expected, atol=1e-7)
    assert np.allclose(trajectory.angular_velocities[:, 0], [0, 0, 14.0], atol=1e-7)
    assert start[0] > 0.05  # the centre of mass sits towards the heavier ball (+x), not at the shape origin


@pytest.mark.slow
def test_bundled_hanging_box_settles_with_its_centre_under_the_hook():
    """The box hung from a corner comes to rest with hook, corner and centre of mass on one vertical line (within
    5 mm, for a 40 cm box, by the end of the 12 s scene)."""
    loaded = load_scene(REPO / "scenes" / "hanging_box.yaml", ["fps=2"])
    model = api.compile_model(loaded)
    trajectory = api.simulate(loaded, model=model)
    centre = trajectory.positions[-1, 0]
    corner = centre + Q.rotate(trajectory.orientations[-1, 0], np.array([0.2, 0.2, 0.2]))
    hook = np.array([0.0, 2.5, 0.0])
    assert np.allclose(centre[[0, 2]], 0.0, atol=5e-3) and np.allclose(corner[[0, 2]], 0.0, atol=5e-3)
    assert hook[1] > corner[1] > centre[1]
    assert np.abs(trajectory.velocities[-1]).max() < 1e-2
