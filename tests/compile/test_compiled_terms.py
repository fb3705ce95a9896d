"""Only the effects a scene declares are compiled and evaluated."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from animbatch.cli import cli
from animbatch.compile.forces import FIELD_TERMS
from animbatch.compile.model import compile_scene
from animbatch.scene.schema import field_type_names
from animbatch.sim.forces import Drag, Gravitation, SpringForces, UniformGravity
from animbatch.sim.forces import springs as spring_module
from support.scenes import run, scene

PLAIN = """
    duration: 0.5
    bodies: [{name: a, velocity: [1, 2, 0]}, {name: b, position: [1, 0, 0]}, {name: c, position: [2, 0, 0]}]
    fields: [{type: gravity}]
"""
WITH_SPRING = PLAIN + """
    springs: [{between: [a, b], stiffness: 10}]
"""


def test_every_field_type_in_the_schema_has_a_force_term():
    """The schema's field types and the registry of force terms are the same set."""
    assert set(field_type_names()) == set(FIELD_TERMS)


def test_the_laws_with_a_particle_form_are_those_fields_may_name_emitters_for():
    """The table of laws gives a particle form to exactly the field types the scene format lets act on emitters."""
    from animbatch.compile.forces import LAWS
    from animbatch.scene.schema import PARTICLE_FIELD_TYPES

    assert {name for name, law in LAWS.items() if law.particles is not None} == set(PARTICLE_FIELD_TYPES)


def test_a_force_law_on_bodies_and_particles_is_its_own_module_and_one_table_row(monkeypatch):
    """The recipe of docs/architecture.md, followed in this test alone: a uniform push ``a`` written once (its term on
    bodies, its form on particles with its row of the compiled kernel's table) and added as one row of the table of
    laws moves a body as x = x0 + ½ a t², accelerates emitted particles by a in the numpy code, and gives the kernel
    the row of a uniform acceleration. Nothing else in animbatch is touched."""
    from dataclasses import dataclass
    from types import SimpleNamespace

    from animbatch.compile import forces
    from animbatch.compile.particles import _particle_fields
    from animbatch.compile.scene_builder import SceneModelBuilder
    from animbatch.sim.forces.gravity import build_gravity
    from animbatch.sim.forces.on_particles import ParticleLaw, Slots
    from animbatch.sim.integrate import integrator_for
    from animbatch.sim.kernels import particle_pool as kernel
    from animbatch.sim.model import Dynamics
    from animbatch.sim.particles.advance import Accelerations

    @dataclass(frozen=True, eq=False)
    class PushOnParticles(ParticleLaw):  # the law's particle form (its own module, in a real law)
        a: np.ndarray

        def describe(self) -> str:
            return "push"

        def add_acceleration(self, slots: Slots, out: np.ndarray) -> None:
            out += self.a

        @property
        def compiled(self) -> bool:
            return True

        def kernel_row(self, row: np.ndarray, kernel) -> None:
            row[kernel.KIND] = kernel.FIELD_GRAVITY  # the kernel's uniform acceleration
            row[kernel.VECTOR:kernel.VECTOR + 3] = self.a

    push = np.array([0.5, -2.0, 1.0])
    monkeypatch.setitem(forces.LAWS, "push", forces.Law(  # the table row
        lambda spec, bodies, index: build_gravity(bodies, index, g=np.asarray(spec.a, float)),
        lambda spec: PushOnParticles(np.asarray(spec.a, float))))
    spec = SimpleNamespace(type="push", a=push.tolist(), bodies=None)

    builder = SceneModelBuilder()
    builder.add_particle("p", mass=2.0, velocity=(1.0, 0.0, 0.0))
    builder.add_field(spec)
    model = builder.finalize(duration=1.0, fps=10)
    states = integrator_for(model, "DOP853", rtol=1e-10, atol=1e-12).integrate(
        Dynamics(model), model.y0, model.frame_times).states
    t = model.frame_times[:, None]
    np.testing.assert_allclose(model.positions(states)[:, 0], [1.0, 0.0, 0.0] * t + 0.5 * push * t ** 2, atol=1e-9)

    (law,) = _particle_fields([spec], "sparks")
    x, v = np.zeros((4, 3)), np.ones((4, 3))
    np.testing.assert_allclose(Accelerations((law,))(x, v, np.full(4, 1e-3), np.full(4, 0.01)), np.tile(push, (4, 1)))
    row = np.zeros(kernel.FIELD_COLUMNS)
    law.kernel_row(row, kernel)
    assert row[kernel.KIND] == kernel.FIELD_GRAVITY and np.array_equal(row[kernel.VECTOR:kernel.VECTOR + 3], push)


def test_three_particles_with_gravity_compile_one_term():
    """A scene with gravity only evaluates exactly one term: gravity."""
    model = compile_scene(scene(PLAIN).spec)
    assert [type(term) for term in model.force_terms] == [UniformGravity]
    assert model.springs is None


def test_each_declared_field_adds_exactly_its_term():
    """Terms appear in declaration order; springs add one term however many springs there are."""
    model = compile_scene(scene(PLAIN.replace("fields: [{type: gravity}]", "") + """
    fields:
      - {type: drag, model: quadratic, coefficient: 0.1}
      - {type: gravitation, G: 1}
      - {type: wind, velocity: [1, 0, 0], coefficient: 0.1}
    springs: [{between: [a, b], stiffness: 10}, {between: [b, c], stiffness: 10}]
    """).spec)
    assert [type(term) for term in model.force_terms] == [Drag, Gravitation, Drag, SpringForces]
    assert [term.label for term in model.force_terms] == ["drag", "gravitation", "wind", "spring"]


def test_scene_without_springs_never_runs_spring_code(monkeypatch):
    """With spring evaluation sabotaged, a spring-less scene still simulates; a scene with springs hits it."""
    calls = []

    def sabotaged(self, *args):
        calls.append(1)
        raise AssertionError("spring code evaluated")

    monkeypatch.setattr(spring_module.SpringForces, "spring_forces", sabotaged)
    for method in ("RK45", "verlet"):
        run(PLAIN, f"solver.method={method}")
    assert calls == []
    with pytest.raises(AssertionError, match="spring code evaluated"):
        run(WITH_SPRING)
    assert calls


def test_info_lists_compiled_terms_layout_and_masses(tmp_path):
    """'animbatch info' shows the compiled terms, the state layout, what was not compiled, and body masses."""
    path = tmp_path / "s.yaml"
    path.write_text(WITH_SPRING)
    result = CliRunner().invoke(cli, ["info", str(path)])
    assert result.exit_code == 0, result.output
    out = result.output
    assert "state      18 values" in out
    assert "y[0:9]  particle_position  (3 × 3) [m]" in out and "y[9:18]  particle_velocity  (3 × 3) [m/s]" in out
    assert "1. gravity" in out and "2. spring" in out and "1 spring (1 body–body, 0 body–anchor)" in out
    assert ("not compiled (not declared): aerodynamics, force, torque, angular_drag, buoyancy, drag, wind, "
            "gravitation, electromagnetic, coulomb, controller, dihedral") in out
    assert "a                         1        0.05" in out


def test_info_shows_rigid_mass_properties(tmp_path):
    """'animbatch info' lists each rigid body's mass, centre of mass, inertia tensor and principal moments."""
    path = tmp_path / "r.yaml"
    path.write_text("""
bodies:
  - name: bar
    type: rigid
    mass: 12
    shape: {type: compound, parts: [{shape: {type: box, size: [1, 2, 3]}, offset: [0.5, 0, 0]}]}
""")
    result = CliRunner().invoke(cli, ["info", str(path)])
    assert result.exit_code == 0, result.output
    assert "rigid      bar: mass 12 kg, volume 6 m³, centre of mass (0.5, 0, 0) m from the shape origin" in result.output
    assert "(13, 0, 0)  (0, 10, 0)  (0, 0, 5)" in result.output
    assert "principal moments (5, 10, 13) kg·m²" in result.output
    assert "y[0:3]  rigid_position  (1 × 3) [m]" in result.output and "rigid_orientation  (1 × 4)" in result.output


def test_particle_scenes_do_no_rigid_body_work(monkeypatch):
    """With quaternion maths sabotaged, a particle-only scene still runs with every kind of method."""
    from animbatch import quaternion

    def sabotaged(*args, **kwargs):
        raise AssertionError("rigid-body code evaluated")

    for name in ("to_matrix", "rate", "multiply", "from_rotation_vector"):
        monkeypatch.setattr(quaternion, name, sabotaged)
    for method in ("RK45", "verlet", "midpoint"):
        run(WITH_SPRING, f"solver.method={method}")


def test_buoyancy_is_computed_only_where_a_fluid_is_declared(monkeypatch):
    """A rigid scene without a fluid never computes submerged volumes; one with a fluid does."""
    from animbatch.sim.forces import buoyancy

    calls = []
    monkeypatch.setattr(buoyancy, "submerged_volume_and_moment", lambda *a, **k: calls.append(1) or 1 / 0)
    rigid = """
        duration: 0.2
        bodies: [{name: crate, type: rigid, shape: {type: box, size: [1, 1, 1]}, density: 500}]
        fields: [{type: gravity}]
    """
    run(rigid)
    assert calls == []
    with pytest.raises(ZeroDivisionError):
        run(rigid.replace("[{type: gravity}]", "[{type: gravity}, {type: buoyancy, level: 10}]"))


def test_info_lists_colliders_settings_and_material_pairs(tmp_path):
    """'animbatch info' shows every collider, the contact settings, and the coefficients of each pair of materials
    that can meet: by the combination rule (e = min, μ = geometric mean) unless material_pairs overrides it."""
    path = tmp_path / "c.yaml"
    path.write_text("""
bodies:
  - {name: ball, radius: 0.1, position: [0, 1, 0], material: steel}
colliders:
  - {type: plane, material: wood}
  - {type: box, position: [2, 0.5, 0], size: [1, 1, 1], material: ice, visible: false}
material_pairs:
  - {materials: [steel, ice], static_friction: 0.2}
contacts: {bodies: false, rest_speed: 0.02}
""")
    result = CliRunner().invoke(cli, ["info", str(path)])
    assert result.exit_code == 0, result.output
    out = result.output
    assert "bodies collide with colliders only; rest speed 0.02 m/s; slop 0.1 mm" in out
    assert "collider   1. plane  through (0, 0, 0) m, normal (0, 1, 0), wood" in out
    assert "collider   2. box    centre (2, 0.5, 0) m, size (1, 1, 1) m, ice, hidden" in out
    wood = [line for line in out.splitlines() if "steel – wood" in line][0].split()
    assert [float(v) for v in wood[3:6]] == pytest.approx([0.5, np.sqrt(0.78 * 0.38), np.sqrt(0.42 * 0.20)], abs=1e-3)
    ice = [line for line in out.splitlines() if "ice – steel" in line][0]
    assert ice.split()[4] == "0.2" and ice.endswith("(material_pairs)")


def test_info_says_when_no_contact_code_is_compiled(tmp_path):
    path = tmp_path / "p.yaml"
    path.write_text("bodies: [{name: a, position: [0, 1, 0]}]\n")
    result = CliRunner().invoke(cli, ["info", str(path)])
    assert "contacts   none compiled (no colliders and no 'contacts' section)" in result.output


CLOTH = """
    duration: 1.0
    bodies:
      - name: sheet
        type: cloth
        grid: {size: [1, 1], resolution: [6, 6]}
        density: 0.2
        position: [0, 1, 0]
        structural: {stiffness: 500, damping: 0.1}
        pin: [{corners: [top-left, top-right]}]
    fields: [{type: gravity}]
"""
UNUSED = """
    anchors:
      - {name: spare, position: [3, 0, 0]}
      - {name: drone, keyframes: [{time: 0, position: [0, 2, 0]}, {time: 1, position: [1, 2, 0]}]}
    materials: {rubbery: {restitution: 0.9, static_friction: 1.0, kinetic_friction: 0.8}}
    emitters: [{name: mist, rate: 50, source: {type: point, position: [5, 0, 0]}, lifetime: 1.0}]
    study: {rtols: [1.0e-6]}
"""


def test_declared_but_unused_kinds_add_nothing_to_the_right_hand_side(monkeypatch):
    """The same cloth plus things of other kinds that act on nothing in it (a fixed and a keyframed anchor no
    spring uses, a material nobody wears, a particle emitter, study settings): the same compiled terms and state,
    the same derivative, and not one keyframe evaluated per right-hand side (a moving anchor used to be evaluated
    by every spring term whether attached or not). benchmarks/run.py --only lean times both."""
    from animbatch.sim.model import Dynamics
    from animbatch.sim.motion import KeyframePath

    plain, extended = (compile_scene(scene(text).spec) for text in (CLOTH, CLOTH + UNUSED))
    assert [term.describe() for term in extended.force_terms] == [term.describe() for term in plain.force_terms]
    assert extended.layout == plain.layout and np.array_equal(extended.y0, plain.y0)
    evaluated = []
    for name in ("position", "velocity"):
        original = getattr(KeyframePath, name)
        monkeypatch.setattr(KeyframePath, name, lambda self, t, _f=original: evaluated.append(1) or _f(self, t))
    y = plain.y0 + np.random.default_rng(1).normal(scale=1e-3, size=plain.y0.shape)
    assert np.array_equal(Dynamics(extended).rhs(0.5, y), Dynamics(plain).rhs(0.5, y))
    assert evaluated == []
    moved = compile_scene(scene(CLOTH.replace("pin: [{corners: [top-left, top-right]}]",
                                              "pin: [{corners: [top-left], keyframes: [{time: 0, offset: [0, 0, 0]}, "
                                              "{time: 1, offset: [0.5, 0, 0]}]}]") + UNUSED).spec)
    Dynamics(moved).rhs(0.5, moved.y0)
    assert evaluated  # once a vertex is moved by keyframes, its path is evaluated
