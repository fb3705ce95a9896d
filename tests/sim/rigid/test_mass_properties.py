"""Mass properties against the lecture notes' formulas: solids, shells, cuboid, rod/cylinder; meshes by the
divergence theorem; parallel axes, rotations and compounds."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from animbatch import api
from animbatch.compile.bodies import body_geometry
from animbatch.sim.rigid import mass_properties as mp
from animbatch.sim.rigid.polyhedra import (
    box_mesh,
    cylinder_mesh,
    icosphere,
    mesh_mass_properties,
    submerged_volume_and_moment,
)
from support.scenes import scene

DENSITY = 800.0


def rigid(shape: str, mass_or_density: str = f"density: {DENSITY}", extra: str = "") -> tuple[float, np.ndarray]:
    """Mass and body inertia tensor of a one-body scene, as compiled."""
    loaded = scene(f"""
        bodies: [{{name: b, type: rigid, shape: {shape}, {mass_or_density}{extra}}}]
    """)
    model = api.compile_model(loaded)
    return float(model.rigid.mass[0]), model.rigid.inertia[0]


def test_solid_sphere():
    """m = ρ 4/3 π r³ and I = 2/5 m r² about every axis."""
    mass, inertia = rigid("{type: sphere, radius: 0.3}")
    assert mass == pytest.approx(DENSITY * 4 / 3 * np.pi * 0.3**3)
    assert np.allclose(inertia, 2 / 5 * mass * 0.3**2 * np.eye(3))


def test_thin_spherical_shell_and_hollow_sphere():
    """Thin shell I = 2/3 m r²; a thick one I = 2/5 m (R⁵ - r⁵)/(R³ - r³), tending to the thin value."""
    mass, inertia = rigid("{type: shell, radius: 0.5}", "mass: 3")
    assert np.allclose(inertia, 2 / 3 * 3 * 0.25 * np.eye(3))
    mass, inertia = rigid("{type: shell, radius: 0.5, thickness: 0.1}")
    assert mass == pytest.approx(DENSITY * 4 / 3 * np.pi * (0.5**3 - 0.4**3))
    assert inertia[0, 0] == pytest.approx(2 / 5 * mass * (0.5**5 - 0.4**5) / (0.5**3 - 0.4**3))
    thin = mp.spherical_shell(1.0, 1.0, 1e-6).inertia[0, 0]
    assert thin == pytest.approx(2 / 3, rel=1e-5)


def test_cuboid():
    """I = m/12 diag(b² + c², a² + c², a² + b²) for sides a, b, c."""
    mass, inertia = rigid("{type: box, size: [0.2, 0.4, 0.6]}")
    assert mass == pytest.approx(DENSITY * 0.048)
    assert np.allclose(inertia, mass / 12 * np.diag([0.16 + 0.36, 0.04 + 0.36, 0.04 + 0.16]))


def test_cylinder_and_rod():
    """Cylinder along z: I_xx = I_yy = ¼ m r² + 1/12 m l², I_zz = ½ m r²; a thin rod tends to I = 1/12 m l²."""
    mass, inertia = rigid("{type: cylinder, radius: 0.1, length: 0.8}")
    assert mass == pytest.approx(DENSITY * np.pi * 0.01 * 0.8)
    side = mass * (0.01 / 4 + 0.64 / 12)
    assert np.allclose(inertia, np.diag([side, side, mass * 0.01 / 2]))
    mass, inertia = rigid("{type: rod, length: 2.0}", "mass: 3")
    assert inertia[0, 0] == pytest.approx(3 * 4 / 12, rel=1e-3) and inertia[2, 2] < 1e-3 * inertia[0, 0]


def test_mass_instead_of_density_scales_the_same_shape():
    """Giving a mass keeps the distribution: the box of mass 5 has inertia 5/12 diag(...)."""
    mass, inertia = rigid("{type: box, size: [1, 2, 3]}", "mass: 5")
    assert mass == 5 and np.allclose(inertia, 5 / 12 * np.diag([13, 10, 5]))


def test_box_mesh_is_exact():
    """The divergence theorem gives the box's volume, centre and inertia exactly."""
    properties = mesh_mass_properties(box_mesh([1.0, 2.0, 3.0]).transformed(np.eye(3), np.array([1.0, 2.0, 3.0])),
                                      density=2.0)
    assert properties.mass == pytest.approx(12.0)
    assert np.allclose(properties.centre, [1, 2, 3])
    assert np.allclose(properties.inertia, mp.cuboid(12.0, [1, 2, 3]).inertia)


def test_sphere_mesh_converges_to_the_analytic_sphere_at_second_order():
    """Each icosphere subdivision (h halves) divides the volume and inertia errors by about 4."""
    errors = []
    for subdivisions in range(1, 6):
        properties = mesh_mass_properties(icosphere(1.0, subdivisions))
        exact = mp.solid_sphere(4 / 3 * np.pi, 1.0)
        errors.append((abs(properties.volume / exact.volume - 1),
                       abs(properties.inertia[0, 0] / exact.inertia[0, 0] - 1)))
    errors = np.array(errors)
    ratios = errors[:-1] / errors[1:]
    assert np.all((ratios[1:] > 3.5) & (ratios[1:] < 4.5))
    assert errors[-1, 0] < 1e-3 and errors[-1, 1] < 1e-3


def test_cylinder_mesh_converges():
    """A regular n-gon prism tends to the cylinder; doubling n divides the error by about 4."""
    exact = mp.cylinder(1.0, 0.5, 2.0)
    errors = [abs(mesh_mass_properties(cylinder_mesh(0.5, 2.0, n)).inertia[2, 2]
                  / (mesh_mass_properties(cylinder_mesh(0.5, 2.0, n)).mass * exact.inertia[2, 2]) - 1)
              for n in (16, 32, 64, 128)]
    assert all(3.5 < errors[k] / errors[k + 1] < 4.5 for k in range(3))


def test_mesh_file_matches_the_primitive(tmp_path):
    """A box read from an STL file (in millimetres, scaled) has the primitive box's mass properties."""
    trimesh.creation.box((200.0, 400.0, 600.0)).export(tmp_path / "box.stl")
    path = tmp_path / "s.yaml"
    path.write_text(f"bodies: [{{name: b, type: rigid, shape: {{type: mesh, file: box.stl, scale: 0.001}}, "
                    f"density: {DENSITY}}}]")
    model = api.compile_model(api.load_scene(path))
    mass, inertia = rigid("{type: box, size: [0.2, 0.4, 0.6]}")
    assert model.rigid.mass[0] == pytest.approx(mass)
    assert np.allclose(model.rigid.inertia[0], inertia)


def test_off_centre_mesh_has_its_centre_of_mass_and_parallel_axis(tmp_path):
    """A mesh whose solid is not centred on the file origin: the centre of mass is found, and the body turns
    about it (inertia about the centre, not the origin)."""
    mesh = trimesh.creation.box((1.0, 1.0, 1.0))
    mesh.apply_translation((2.0, 0.0, 0.0))
    mesh.export(tmp_path / "shifted.stl")
    path = tmp_path / "s.yaml"
    path.write_text("bodies: [{name: b, type: rigid, shape: {type: mesh, file: shifted.stl}, mass: 6}]")
    model = api.compile_model(api.load_scene(path))
    assert np.allclose(model.rigid.centre[0], [2, 0, 0])
    assert np.allclose(model.rigid.inertia[0], 6 / 12 * 2 * np.eye(3))
    assert np.allclose(model.positions(model.y0)[0], [2, 0, 0])  # position places the shape origin


def test_parallel_axis_theorem_against_a_particle_sum():
    """I about a displaced point = I_cm + M (|d|² E - d dᵀ); checked on a cloud of point masses with the notes'
    discrete formulas I_xx = Σ m (y² + z²), I_xy = -Σ m x y, …"""
    rng = np.random.default_rng(3)
    points = rng.normal(size=(500, 3)) * [1.0, 0.5, 2.0]
    masses = rng.uniform(0.5, 1.5, 500)

    def tensor(r: np.ndarray) -> np.ndarray:
        x, y, z = r.T
        return np.array([[np.sum(masses * (y * y + z * z)), -np.sum(masses * x * y), -np.sum(masses * x * z)],
                         [-np.sum(masses * x * y), np.sum(masses * (x * x + z * z)), -np.sum(masses * y * z)],
                         [-np.sum(masses * x * z), -np.sum(masses * y * z), np.sum(masses * (x * x + y * y))]])

    centre = masses @ points / masses.sum()
    about_centre = tensor(points - centre)
    d = np.array([0.3, -1.2, 0.7])
    assert np.allclose(tensor(points - (centre - d)), mp.parallel_axis(about_centre, masses.sum(), d))


def test_rotated_inertia_is_r_i_r_transpose():
    """A box turned 90° about z swaps its x and y moments; any rotation keeps the eigenvalues."""
    mass, turned = rigid("{type: compound, parts: [{shape: {type: box, size: [1, 2, 3]}, "
                         "orientation: {axis: [0, 0, 1], angle: 90}}]}", "mass: 12")
    assert np.allclose(turned, np.diag([10, 13, 5]))
    mass, tilted = rigid("{type: compound, parts: [{shape: {type: box, size: [1, 2, 3]}, "
                         "orientation: {euler: [20, 35, -50]}}]}", "mass: 12")
    assert np.allclose(np.linalg.eigvalsh(tilted), [5, 10, 13])
    assert not np.allclose(tilted, np.diag(np.diag(tilted)))  # off-diagonal products of inertia appear


def test_compound_centre_of_mass_and_inertia():
    """Dumbbell of unequal spheres on an axis: c = Σ mᵢ cᵢ / M, and I⊥ = Σ (2/5 mᵢ rᵢ² + mᵢ dᵢ²)."""
    loaded = scene("""
        bodies:
          - name: dumbbell
            type: rigid
            density: 1000
            shape:
              type: compound
              parts:
                - {shape: {type: sphere, radius: 0.1}, offset: [-0.5, 0, 0]}
                - {shape: {type: sphere, radius: 0.2}, offset: [0.5, 0, 0]}
    """)
    model = api.compile_model(loaded)
    m1, m2 = 1000 * 4 / 3 * np.pi * 0.1**3, 1000 * 4 / 3 * np.pi * 0.2**3
    centre = (m1 * -0.5 + m2 * 0.5) / (m1 + m2)
    assert np.allclose(model.rigid.centre[0], [centre, 0, 0])
    perpendicular = 0.4 * m1 * 0.01 + m1 * (-0.5 - centre) ** 2 + 0.4 * m2 * 0.04 + m2 * (0.5 - centre) ** 2
    assert np.allclose(model.rigid.inertia[0], np.diag([0.4 * m1 * 0.01 + 0.4 * m2 * 0.04, perpendicular,
                                                        perpendicular]))
    assert model.rigid.mass[0] == pytest.approx(m1 + m2)


def test_compound_parts_may_give_their_own_mass():
    """Parts with a mass keep it; a body mass rescales the whole."""
    geometry = body_geometry(scene("""
        bodies:
          - {name: b, type: rigid, mass: 10, shape: {type: compound, parts: [
              {shape: {type: sphere, radius: 0.1}, offset: [1, 0, 0], mass: 1},
              {shape: {type: sphere, radius: 0.1}, offset: [-1, 0, 0], mass: 3}]}}
    """).spec.bodies[0])
    assert geometry.properties.mass == pytest.approx(10)
    assert np.allclose(geometry.properties.centre, [(1 - 3) / 4, 0, 0])


def test_submerged_part_of_a_tilted_cube_is_a_triangular_prism():
    """A cube of side a turned 45° about z, dipped to depth h from its lowest edge: V = h² a, centroid 2h/3 up."""
    a, h = 1.0, 0.3
    rotation = np.array([[np.cos(np.pi / 4), -np.sin(np.pi / 4), 0], [np.sin(np.pi / 4), np.cos(np.pi / 4), 0],
                         [0, 0, 1]])
    cube = box_mesh([a, a, a]).transformed(rotation, np.zeros(3))
    bottom = -a / np.sqrt(2)
    volume, moment = submerged_volume_and_moment(cube.triangles, np.zeros(12, int), 1, np.array([0, bottom + h, 0]),
                                                 np.array([0.0, 1.0, 0.0]))
    assert volume[0] == pytest.approx(h * h * a)
    assert np.allclose(moment[0] / volume[0], [0, bottom + 2 * h / 3, 0])


def test_unit_quaternion_conventions():
    """q = [w, x, y, z]: 90° about z takes x to y, and composition is the Hamilton product."""
    from animbatch import quaternion as q

    quarter = q.from_rotation_vector(np.array([0, 0, np.pi / 2]))
    assert np.allclose(q.rotate(quarter, np.array([1.0, 0, 0])), [0, 1, 0])
    half = q.multiply(quarter, quarter)
    assert np.allclose(q.to_matrix(half), np.diag([-1, -1, 1]))
    assert np.allclose(q.cross(np.array([1.0, 0, 0]), np.array([0, 1.0, 0])), [0, 0, 1])
