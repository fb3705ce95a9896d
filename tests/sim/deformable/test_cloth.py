"""Cloth, spring lattices and their implicit integration, against equilibrium, invariants and closed forms."""

from __future__ import annotations

import numpy as np
import pytest

from animbatch.compile.model import compile_scene
from animbatch.errors import SimulationError
from animbatch.sim.deformable import topology
from animbatch.sim.forces.dihedral import hinge_angles, hinge_gradients
from animbatch.sim.invariants import kinetic_energy, linear_momentum, total_energy
from animbatch.sim.model import Dynamics
from support.scenarios import cloth
from support.scenes import run, scene, states

G = 9.81





# ------------------------------------------------------------------------------------------------ topology


def test_grid_topology_counts_and_masses():
    """An nx × ny grid has (nx-1) ny + nx (ny-1) edges, 2 (nx-1)(ny-1) diagonals and triangles, bend springs two
    apart, one hinge per interior edge; the lumped areas add up to the sheet's area."""
    grid = topology.grid((2.0, 1.0), (5, 3))
    assert len(grid.springs["structural"]) == 4 * 3 + 5 * 2
    assert len(grid.springs["shear"]) == 2 * 4 * 2 == len(grid.triangles)
    assert len(grid.springs["bend"]) == 3 * 3 + 5 * 1
    edges = topology.unique_edges(grid.triangles)
    boundary = 2 * (4 + 2)
    assert len(grid.hinges) == len(edges) - boundary
    assert grid.weights.sum() == pytest.approx(2.0)
    assert np.all(np.cross(*(grid.vertices[grid.triangles[:, k]] - grid.vertices[grid.triangles[:, 0]]
                             for k in (1, 2)))[:, 2] > 0)  # every triangle faces +z


def test_lattice_topology_faces_outward_and_weighs_its_volume():
    """A lattice's boundary triangles face outwards, its vertex volumes add up to the block's, and every vertex
    has its axis neighbours as structural springs."""
    block = topology.lattice((0.4, 0.2, 0.3), (3, 4, 5))
    v, t = block.vertices, block.triangles
    normals = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
    assert np.all(np.einsum("ij,ij->i", normals, v[t].mean(axis=1)) > 0)
    assert block.weights.sum() == pytest.approx(0.4 * 0.2 * 0.3)
    assert len(block.springs["structural"]) == 2 * 4 * 5 + 3 * 3 * 5 + 3 * 4 * 4
    lengths = np.linalg.norm(v[block.springs["structural"][:, 0]] - v[block.springs["structural"][:, 1]], axis=1)
    assert np.allclose(np.sort(np.unique(np.round(lengths, 12))), [0.2 / 3, 0.075, 0.2])


def test_mesh_cloth_has_edge_and_flip_springs():
    """From a triangle mesh: structural springs on its edges and a bend spring across each interior edge."""
    square = topology.triangle_mesh(np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.0]]),
                                    np.array([[0, 1, 2], [0, 2, 3]]))
    assert len(square.springs["structural"]) == 5 and len(square.springs["shear"]) == 0
    assert sorted(square.springs["bend"][0].tolist()) == [1, 3]
    assert square.hinges.tolist() == [[2, 0, 1, 3]]


# ------------------------------------------------------------------------------------------------ dihedral


def test_dihedral_angle_of_a_known_fold_and_its_balanced_forces():
    """Two unit right triangles folded by 30° about their shared edge measure θ = ±30°; the bending forces
    -k (θ - θ₀) ∂θ/∂x sum to zero and exert no torque."""
    fold = np.radians(30)
    a, b = np.array([0.0, 0, 0]), np.array([1.0, 0, 0])
    c = np.array([0.5, 1.0, 0])
    d = np.array([0.5, -np.cos(fold), np.sin(fold)])
    x = np.array([[a, b, c, d]])
    assert abs(hinge_angles(x)[0]) == pytest.approx(fold, abs=1e-12)
    forces = -0.3 * hinge_angles(x)[:, None, None] * hinge_gradients(x)
    assert np.allclose(forces.sum(axis=1), 0, atol=1e-14)
    assert np.allclose(np.cross(x[0], forces[0]).sum(axis=0), 0, atol=1e-14)


@pytest.mark.slow
def test_dihedral_springs_unfold_a_folded_cloth_and_conserve_energy_undamped():
    """A free 3 × 3 cloth with structural and dihedral springs, its top row folded up by 40° about the middle row
    (a rigid fold: no spring is stretched, only the hinges bend): it unfolds and swings through flat, with total
    energy constant (DOP853 at tight tolerance) and momentum zero."""
    from animbatch.sim.integrators import ScipyIntegrator

    model = compile_scene(scene("""
        duration: 0.5
        fps: 50
        bodies:
          - {name: sheet, type: cloth, grid: {size: [0.2, 0.2], resolution: [3, 3]}, mass: 0.09,
             structural: {stiffness: 500}, dihedral: {stiffness: 0.05}}
    """).spec)
    y0 = model.y0.copy()
    fold = np.radians(40)
    y0[3 * 6 + 1: 3 * 9: 3] = 0.1 * np.cos(fold)  # y and z of the top row, 0.1 m from the middle row
    y0[3 * 6 + 2: 3 * 9: 3] = 0.1 * np.sin(fold)
    result = ScipyIntegrator("DOP853", rtol=1e-10, atol=1e-12).integrate(Dynamics(model), y0, model.frame_times)
    energy = total_energy(model, result.states)
    bending = next(term for term in model.force_terms if term.kind == "dihedral")
    dynamics = Dynamics(model)
    assert bending.potential_energy(dynamics.kinematics(*dynamics.split(y0))) > 1e-4  # really folded at the start
    assert np.abs(energy - energy[0]).max() < 1e-9
    assert np.allclose(linear_momentum(model, result.states), 0, atol=1e-12)
    angles = np.array([hinge_angles(model.positions(y)[bending.hinges]) for y in result.states])
    folded = np.abs(angles[0]) > np.radians(30)  # the hinges along the middle row
    assert folded.sum() >= 2
    assert np.all(np.sign(angles[:, folded]).min(axis=0) != np.sign(angles[:, folded]).max(axis=0))  # through flat


# ------------------------------------------------------------------------------------------------ statics


def test_hanging_cloth_settles_where_the_net_force_on_every_free_vertex_is_zero():
    """After 8 s of backward Euler at one step per frame, every free vertex is in equilibrium: the sum of spring,
    damper and gravity forces is below 0.1 % of the vertex's weight, while the springs alone pull with forces of
    the order of the whole cloth's weight."""
    model, trajectory = run(cloth("{method: backward_euler, dt: 0.0333333}", damping=0.5, duration=8))
    dynamics = Dynamics(model)
    y = states(model, trajectory)[-1].copy()
    config, motion = dynamics.split(y)
    motion[:] = 0.0  # the forces of the resting shape, without the last tiny velocities
    state = dynamics.kinematics(config, motion)
    force, _ = dynamics.loads(8.0, state)
    weight = model.bodies.mass * G
    assert np.abs(kinetic_energy(model, states(model, trajectory)[-1])) < 1e-6
    assert np.max(np.linalg.norm(force, axis=1) / weight) < 1e-3
    spring = next(term for term in model.force_terms if term.kind == "spring")
    tension = np.linalg.norm(spring.spring_forces(state)[0], axis=1)
    assert tension.max() > 0.1 * weight.sum()


# ------------------------------------------------------------------------------------------------ stiffness


STIFF_CLOTH = dict(stiffness=2.0e4, damping=0.0, size="[12, 9]", duration=3.0, fps=60)


@pytest.mark.slow
def test_stiff_cloth_under_backward_euler_is_bounded_and_never_gains_energy():
    """A stiff undamped cloth (ω dt ≈ 60 for its fastest mode) dropped from horizontal, pinned at two corners:
    backward Euler at dt = 1/60 keeps it bounded, its total energy (kinetic, elastic, gravitational) never rises
    from one frame to the next, and no spring stretches by more than 5 %."""
    model, trajectory = run(cloth("{method: backward_euler, dt: 0.0166667}", **STIFF_CLOTH),
                            "bodies[sheet].orientation={axis: [1, 0, 0], angle: -90}")
    y = states(model, trajectory)
    energy = total_energy(model, y)
    assert np.all(np.diff(energy) <= 1e-9 * np.abs(energy).max())
    assert energy[-1] < energy[0]
    assert np.isfinite(trajectory.positions).all() and np.abs(trajectory.positions).max() < 3
    springs = model.springs
    ends = trajectory.positions[:, springs.first]
    anchored = springs.second_is_anchor
    other = np.where(anchored[None, :, None], model.anchor_position[np.where(anchored, springs.second, 0)][None],
                     trajectory.positions[:, np.where(anchored, 0, springs.second)])
    stretch = np.linalg.norm(ends - other, axis=2) / springs.rest_length - 1
    assert stretch.max() < 0.05


def test_newton_corrections_solve_the_backward_euler_equations():
    """A stiff cloth (ω dt ≈ 30) whose free vertices are all thrown sideways at 3 m/s while two corners stay
    pinned, so that its springs turn fast within one step of 1/30 s. Baraff & Witkin's linearised step leaves a
    residual in the backward-Euler equations ``M (v₁ − v₀) = h f(x₀ + h v₁, v₁)``, ``x₁ = x₀ + h v₁``; each
    Newton correction (derivatives at the iterate) shrinks it, and eight of them cut it a thousandfold, while the
    positions always follow the new velocities exactly."""
    from animbatch.sim.integrators.implicit import BackwardEuler

    model = compile_scene(scene(cloth("{method: backward_euler, dt: 0.0333333}", stiffness=4000)).spec)
    system = Dynamics(model)
    scheme = BackwardEuler(system)
    start = model.y0.copy()
    system.split(start)[1][2::3] = 3.0  # every free vertex thrown along z
    h = 1 / 30
    mass = np.repeat(model.bodies.mass[: system.particles], 3)

    def residual(y: np.ndarray) -> tuple[float, float]:
        (config, motion), (config0, motion0) = system.split(y), system.split(start)
        rate = system.motion_rate(h, config, motion)
        return (float(np.linalg.norm(mass * (motion - motion0 - h * rate))),
                float(np.abs(config - config0 - h * motion).max()))

    y = start.copy()
    scheme._plain_step(0.0, y, h)
    norms = [residual(y)]
    for _ in range(8):
        scheme._correct(0.0, start, y, h)
        norms.append(residual(y))
    force_residual = np.array([norm for norm, _ in norms])
    assert force_residual[0] > 1.0  # the linearised step is far from solving them here
    assert force_residual[1] < 0.25 * force_residual[0]
    assert force_residual[-1] < 1e-3 * force_residual[0]
    assert max(drift for _, drift in norms) < 1e-14
    assert scheme.factorisations == 9


def test_explicit_euler_at_the_same_step_is_refused_naming_the_stiffest_spring():
    """The same cloth with explicit Euler at dt = 1/60 is stopped before any step, naming the stiffest spring
    (a structural spring at a pinned corner, where the masses are smallest)."""
    with pytest.raises(SimulationError) as caught:
        run(cloth("{method: euler, dt: 0.0166667}", **STIFF_CLOTH))
    message = str(caught.value)
    assert "euler at dt = 0.0167 s cannot hold this scene's springs: the stiffest spring 'sheet.structural[" in message
    assert "backward_euler (stable at any dt)" in message
    spring = caught.value.details["spring"]
    model = compile_scene(scene(cloth("{method: backward_euler}", **STIFF_CLOTH)).spec)
    index = model.springs.names.index(spring)
    mass = model.bodies.mass
    other = np.inf if model.springs.second_is_anchor[index] else mass[model.springs.second[index]]
    omega = np.sqrt(model.springs.stiffness * (1 / mass[model.springs.first]
                                                + 1 / np.where(model.springs.second_is_anchor, np.inf,
                                                               mass[np.where(model.springs.second_is_anchor, 0,
                                                                             model.springs.second)])))
    assert np.sqrt(2.0e4 * (1 / mass[model.springs.first[index]] + 1 / other)) == pytest.approx(omega.max())


def stiff_oscillator_chain(method: str) -> str:
    """Two 0.5 kg beads in a line joined by springs (k = 2e5 N/m to the wall, 1e5 N/m between them, ω up to about
    850 rad/s, damped at ζ ≈ 0.05): a linear system whose exact motion is the matrix exponential."""
    return f"""
        duration: 0.2
        fps: 50
        solver: {{method: {method}, rtol: 1.0e-6, atol: 1.0e-9}}
        anchors: [{{name: wall, position: [0, 0, 0]}}]
        bodies:
          - {{name: a, mass: 0.5, position: [1.001, 0, 0]}}
          - {{name: b, mass: 0.5, position: [2.003, 0, 0]}}
        springs:
          - {{between: [wall, a], stiffness: 2.0e5, damping: 20, rest_length: 1.0}}
          - {{between: [a, b], stiffness: 1.0e5, damping: 10, rest_length: 1.0}}
    """


@pytest.mark.slow
@pytest.mark.parametrize("method", ["Radau", "BDF"])
def test_implicit_adaptive_methods_with_the_sparse_jacobian_follow_the_exact_linear_motion(method):
    """Radau and BDF, given the analytic sparse Jacobian (and reusing their Newton factors across small step
    changes), reproduce x(t) = expm(A t) x0 of a stiff two-spring chain to within their tolerance."""
    from scipy.linalg import expm

    from animbatch.compile.integrator import make_integrator

    loaded = scene(stiff_oscillator_chain(method))
    model = compile_scene(loaded.spec)
    result = make_integrator(loaded.spec.solver, model).integrate(Dynamics(model), model.y0, model.frame_times)
    assert result.stats.jacobian_evaluations > 0 and result.stats.lu_decompositions < result.stats.steps
    mass, k1, k2, c1, c2 = 0.5, 2.0e5, 1.0e5, 20.0, 10.0
    stiffness = np.array([[-(k1 + k2), k2], [k2, -k2]]) / mass
    damping = np.array([[-(c1 + c2), c2], [c2, -c2]]) / mass
    system = np.block([[np.zeros((2, 2)), np.eye(2)], [stiffness, damping]])
    start = np.array([0.001, 0.003, 0.0, 0.0])  # displacements from rest and velocities along x
    exact = np.array([expm(system * t) @ start for t in model.frame_times])
    positions = result.states[:, :6].reshape(-1, 2, 3)
    assert np.abs(positions[:, :, 0] - np.array([1.0, 2.0]) - exact[:, :2]).max() < 1e-3 * np.abs(start).max()
    assert np.abs(positions[:, :, 1:]).max() < 1e-12


@pytest.mark.slow
def test_implicit_adaptive_methods_reuse_newton_factors_without_losing_accuracy(monkeypatch):
    """On a stiff falling cloth, BDF factors its Newton matrix far less often when factors are reused across small
    step changes, and lands where it lands when it refactors at every change (both within tolerance of each other)."""
    from animbatch.compile.integrator import make_integrator
    from animbatch.scene.schema import SolverSpec
    from animbatch.sim.integrators import linear_algebra

    model = compile_scene(scene(cloth("{}", **{**STIFF_CLOTH, "duration": 0.1}),
                                "bodies[sheet].orientation={axis: [1, 0, 0], angle: -90}").spec)
    solver = SolverSpec(method="BDF", rtol=1e-4, atol=1e-6)

    def integrate() -> tuple[np.ndarray, int, int]:
        result = make_integrator(solver, model).integrate(Dynamics(model), model.y0, model.frame_times)
        return result.states, result.stats.lu_decompositions, result.stats.steps

    reused, reused_factorisations, steps = integrate()
    monkeypatch.setattr(linear_algebra, "FACTOR_REUSE_CHANGE", 0.0)
    fresh, fresh_factorisations, _ = integrate()
    assert reused_factorisations < 0.6 * fresh_factorisations
    assert reused_factorisations < 0.25 * steps
    size = model.y0.size // 2
    assert np.abs(reused[:, :size] - fresh[:, :size]).max() < 1e-3  # metres, on a 0.8 m cloth


# ------------------------------------------------------------------------------------------------ pins


def test_fixed_pins_never_move_and_keyframed_pins_follow_their_path():
    """Pinned corners are anchors: exactly where they started, or where their linear keyframes put them."""
    model, trajectory = run(cloth("{method: backward_euler, dt: 0.0333333}",
                                  pin="[{corners: [top-left]}, {corners: [top-right], keyframes: "
                                      "[{time: 0, offset: [0, 0, 0]}, {time: 1, offset: [0.3, 0, 0]}]}]"))
    anchors = model.anchors
    left, right = model.anchor_names.index("sheet[40]"), model.anchor_names.index("sheet[47]")
    for t in trajectory.times:
        assert np.array_equal(anchors.positions(t)[left], [-0.4, 1.3, 0])
        assert anchors.positions(t)[right] == pytest.approx([0.4 + 0.3 * min(t, 1.0), 1.3, 0])
    assert anchors.velocities(0.5)[right] == pytest.approx([0.3, 0, 0])
    assert np.array_equal(anchors.velocities(1.5)[right], [0, 0, 0])


@pytest.mark.slow
def test_vertices_pinned_to_a_rigid_body_move_with_it_and_pull_on_it():
    """A cloth hanging from a spinning, thrown box: the attached corners stay at their body points, and the whole
    system's momentum changes at exactly (M_box + m_free_vertices) g, so the cloth's springs pull on the box."""
    from animbatch import quaternion

    model, trajectory = run("""
        duration: 0.5
        fps: 20
        solver: {method: RK45, rtol: 1.0e-9, atol: 1.0e-11}
        bodies:
          - {name: box, type: rigid, shape: {type: box, size: [1, 0.1, 0.1]}, density: 200, position: [0, 1.35, 0],
             velocity: [0, 1, 0], angular_velocity: [0, 0, 2]}
          - {name: sheet, type: cloth, grid: {size: [0.8, 0.6], resolution: [5, 4]}, position: [0, 1, 0],
             density: 0.2, structural: {stiffness: 400, damping: 0.05}, shear: {stiffness: 100},
             pin: [{corners: [top-left, top-right], to: box}]}
        fields: [{type: gravity}]
    """)
    y = states(model, trajectory)
    momentum = linear_momentum(model, y)
    t = trajectory.times
    assert np.allclose(momentum - momentum[0], np.outer(t, [0, -G * model.bodies.mass.sum(), 0]), atol=1e-7)
    box = model.body_names.index("box")
    start_offset = np.array([-0.4, -0.05, 0.0])  # the top-left corner from the box's centre, in its axes
    for frame in range(len(t)):
        rotation = quaternion.to_matrix(trajectory.orientations[frame, model.particle_count:])
        vertices = model.deformables.vertex_map.place(trajectory.positions[frame], rotation,
                                                      model.anchors.positions(t[frame]))
        assert vertices[15] == pytest.approx(trajectory.positions[frame, box] + rotation[0] @ start_offset,
                                             abs=1e-12)
    assert trajectory.angular_velocities[-1, box, 2] != pytest.approx(2.0, abs=1e-3)  # the cloth turns it too


# ------------------------------------------------------------------------------------------------ air


def test_aerodynamic_force_on_a_plate_facing_and_edge_on_to_the_wind():
    """A resting 0.5 × 0.4 m sheet in the x–y plane: wind along its normal pushes with ½ ρ C_n A |w|², wind along
    the sheet drags with ½ ρ C_t A |w|² only."""
    for wind, coefficient in (([0, 0, 6.0], 1.3), ([6.0, 0, 0], 0.05)):
        model = compile_scene(scene(f"""
            bodies: [{{name: plate, type: cloth, grid: {{size: [0.5, 0.4], resolution: [6, 5]}}, mass: 0.1}}]
            fields: [{{type: aerodynamics, wind: {wind}, density: 1.2, drag: 1.3, friction: 0.05}}]
        """).spec)
        dynamics = Dynamics(model)
        force, _ = dynamics.loads(0.0, dynamics.kinematics(*dynamics.split(model.y0.copy())))
        expected = 0.5 * 1.2 * coefficient * 0.5 * 0.4 * 36.0
        assert force.sum(axis=0) == pytest.approx(np.array(wind) / 6.0 * expected, abs=1e-12)


def test_gusts_stay_within_their_amplitude_and_repeat():
    """The gust signal is bounded by its amplitude and the same at the same time in every run."""
    from animbatch.sim.forces.aerodynamics import gust_signal

    t = np.linspace(0, 60, 6001)
    signal = np.array([gust_signal(x, 2.0) for x in t])
    assert np.abs(signal).max() <= 1.0 and np.abs(signal).max() > 0.8
    assert gust_signal(12.34, 2.0) == gust_signal(12.34, 2.0)


# ------------------------------------------------------------------------------------------------ contact


@pytest.mark.slow
def test_cloth_draped_over_a_sphere_never_passes_through_it():
    """A cloth dropped on a sphere collider: no vertex ever comes closer to the centre than R + its radius (less
    the slop), and the part of the cloth lying on the sphere comes to rest there (its hanging corners still
    swing). Cloth vertices do not bounce, whatever their material's restitution (rubber: 0.8)."""
    model, trajectory = run("""
        duration: 1.5
        fps: 30
        solver: {method: backward_euler, dt: 0.0041666667}
        bodies:
          - {name: sheet, type: cloth, grid: {size: [1.0, 1.0], resolution: [11, 11]}, position: [0, 0.6, 0],
             orientation: {axis: [1, 0, 0], angle: -90}, density: 0.2, radius: 0.02,
             structural: {stiffness: 300, damping: 0.1}, shear: {stiffness: 50}, bend: {stiffness: 5},
             material: rubber}
        colliders: [{type: sphere, position: [0, 0, 0], radius: 0.4, material: rubber}]
        fields: [{type: gravity}]
    """)
    distance = np.linalg.norm(trajectory.positions, axis=2)
    assert distance.min() > 0.4 + 0.02 - 2e-4
    lying = distance[-1] < 0.42 + 1e-3
    assert lying.sum() > 20
    assert np.linalg.norm(trajectory.velocities[-1][lying], axis=1).max() < 0.02


@pytest.mark.parametrize("friction", [0.5, 0.1])
def test_cloth_on_a_box_sticks_or_slides_as_its_friction_says(friction):
    """A small sheet lying on a box collider, with gravity tilted 20° along x: with μs = 0.5 > tan 20° it stays put;
    with μs = μk = 0.1 it slides with a = g (sin 20° - μk cos 20°), never sinking into the box."""
    angle = np.radians(20)
    model, trajectory = run(f"""
        duration: 0.5
        fps: 20
        solver: {{method: backward_euler, dt: 0.0041667}}
        materials:
          felt: {{restitution: 0, static_friction: {friction}, kinetic_friction: {friction}}}
        bodies:
          - {{name: mat, type: cloth, grid: {{size: [0.4, 0.4], resolution: [5, 5]}}, position: [0, 0.025, 0],
             orientation: {{axis: [1, 0, 0], angle: -90}}, density: 0.3, radius: 0.025, material: felt,
             structural: {{stiffness: 200, damping: 0.05}}, shear: {{stiffness: 50}}}}
        colliders:
          - {{type: box, size: [2, 0.2, 1], position: [0, -0.1, 0], material: felt}}
        fields: [{{type: gravity, g: [{G * np.sin(angle)}, {-G * np.cos(angle)}, 0]}}]
    """)
    shift = trajectory.positions[:, :, 0].mean(axis=1) - trajectory.positions[0, :, 0].mean()
    assert trajectory.positions[..., 1].min() > 0.025 - 1.5e-4  # the vertex spheres stay on the top face
    if friction > np.tan(angle):
        assert np.abs(shift).max() < 1e-3
    else:
        t = trajectory.times
        expected = 0.5 * G * (np.sin(angle) - friction * np.cos(angle)) * t**2
        assert shift[-1] == pytest.approx(expected[-1], rel=0.05)


def test_cloth_from_a_mesh_file_weighs_its_area_and_falls_freely(tmp_path):
    """A cloth read from an OBJ file (a 0.5 m square of 4 × 4 cells, scaled ×2 by the scene): one vertex per file
    vertex, a structural spring per edge, vertex masses lumped by area, and, with nothing pinned, its centre of mass
    moves as x0 + v0 t + g t² / 2 however its springs vibrate."""
    from animbatch import api

    n = 5
    grid = np.linspace(0, 0.5, n)
    vertices = [(x, y, 0.0) for y in grid for x in grid]
    faces = []
    for j in range(n - 1):
        for i in range(n - 1):
            a, b, c, d = j * n + i, j * n + i + 1, (j + 1) * n + i + 1, (j + 1) * n + i
            faces += [(a, b, c), (a, c, d)]
    (tmp_path / "square.obj").write_text("".join(f"v {x} {y} {z}\n" for x, y, z in vertices)
                                         + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in faces))
    (tmp_path / "scene.yaml").write_text("""
duration: 0.5
fps: 10
solver: {method: RK45, rtol: 1.0e-9, atol: 1.0e-12}
bodies:
  - {name: sheet, type: cloth, mesh: {file: square.obj, scale: 2}, position: [0, 2, 0], mass: 0.4,
     velocity: [0.3, 0, 0.1], structural: {stiffness: 300, damping: 0.2}, bend: {stiffness: 5}}
fields: [{type: gravity}]
""")
    loaded = api.load_scene(tmp_path / "scene.yaml")
    model = api.compile_model(loaded)
    mass = model.bodies.mass
    assert model.particle_count == n * n and mass.sum() == pytest.approx(0.4)
    cell = 0.4 / (n - 1) ** 2
    # each triangle gives a third of its area to each of its vertices
    assert mass[0] == pytest.approx(cell / 3)  # a corner in both triangles of its cell
    assert mass[n - 1] == pytest.approx(cell / 6)  # a corner in one of them
    assert mass[n + 1] == pytest.approx(cell)  # interior: in six triangles
    families = [name.split(".")[1].split("[")[0] for name in model.springs.names]
    edges = 2 * n * (n - 1) + (n - 1) ** 2  # rows, columns and one diagonal per cell
    assert families.count("structural") == edges and families.count("shear") == 0
    trajectory = api.simulate(loaded, model=model)
    centre = np.einsum("p,fpk->fk", mass, trajectory.positions) / mass.sum()
    t = trajectory.times
    expected = centre[0] + np.outer(t, [0.3, 0, 0.1]) + np.outer(0.5 * t**2, [0, -G, 0])
    assert centre == pytest.approx(expected, abs=1e-8)
    assert np.ptp(trajectory.positions[:, :, 0], axis=1).max() == pytest.approx(1.0, rel=0.05)  # scaled ×2
