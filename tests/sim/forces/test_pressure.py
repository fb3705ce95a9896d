"""Pressure inside closed cloths: F = P·A on each triangle is the gradient of p V (no net force, no net torque),
a gas keeps P V constant (a balloon breathes with its energy kept, and settles where its pressure meets the
outside's), a held gauge has the potential −p ΔV, a pump's keyframes do work, and open or mis-wound surfaces are
refused."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from animbatch import api
from animbatch.errors import SceneError
from animbatch.sim.forces.jacobian import ForceJacobian
from animbatch.sim.forces.pressure import Pressure
from animbatch.sim.model.dynamics import Dynamics
from support.paths import SCENES

OUTSIDE, GAUGE = 2000.0, 600.0  # [Pa]: a soft gas, so that its breathing is slow enough for a quick test


def balloon(tmp_path, pressure, *, extra="", structural=0.0, duration=3.0, method="DOP853"):
    """A closed ball of cloth (an icosphere of 42 vertices, radius 0.2 m, 0.5 kg/m²) with ``pressure``, no gravity."""
    trimesh.creation.icosphere(subdivisions=1, radius=1.0).export(tmp_path / "ball.obj")
    solver = ("{method: DOP853, rtol: 1.0e-9, atol: 1.0e-11}" if method == "DOP853"
              else f"{{method: {method}, dt: 0.0025}}")
    text = f"""name: balloon
duration: {duration}
fps: 20
solver: {solver}
bodies:
  - name: balloon
    type: cloth
    mesh: {{file: ball.obj, scale: 0.2}}
    density: 0.5
    structural: {{stiffness: {structural}}}
    pressure: {pressure}
    collide: false
{extra}"""
    (tmp_path / "balloon.yaml").write_text(text)
    return api.load_scene(tmp_path / "balloon.yaml")


def pressure_term(plan) -> Pressure:
    (term,) = [term for term in plan.model.force_terms if isinstance(term, Pressure)]
    return term


def volumes(plan, trajectory):
    term = pressure_term(plan)
    return np.array([term.volumes(positions)[0] for positions in trajectory.positions])


def test_the_force_is_the_gradient_of_p_v_with_no_net_force_or_torque(tmp_path):
    """On a crumpled ball (every vertex moved at random), each vertex's force is p ∂V/∂x (central differences of
    the enclosed volume), and they add up to no force and no torque."""
    plan = api.plan(balloon(tmp_path, f"{{gauge: {GAUGE}}}"))
    term = pressure_term(plan)
    x = term.deformables.initial_positions + np.random.default_rng(3).normal(scale=0.02, size=(42, 3))
    force = term.share @ term.face_forces(x, 0.0)
    step = 1e-6
    gradient = np.zeros_like(x)
    for vertex in range(len(x)):
        for axis in range(3):
            ahead, behind = x.copy(), x.copy()
            ahead[vertex, axis] += step
            behind[vertex, axis] -= step
            gradient[vertex, axis] = (term.volumes(ahead)[0] - term.volumes(behind)[0]) / (2 * step)
    np.testing.assert_allclose(force, GAUGE * gradient, atol=1e-6 * np.abs(force).max())
    np.testing.assert_allclose(force.sum(axis=0), 0, atol=1e-10)
    np.testing.assert_allclose(np.cross(x, force).sum(axis=0), 0, atol=1e-10)


def test_the_exact_derivatives_given_to_radau_and_bdf_are_the_forces_change(tmp_path):
    plan = api.plan(balloon(tmp_path, f"{{gauge: {GAUGE}}}"))
    term = pressure_term(plan)
    system = Dynamics(plan.model)
    state = system.kinematics(*system.split(plan.model.y0))
    jacobian = ForceJacobian(42)
    assert term.jacobian(0.0, state, jacobian) and not term.jacobian(0.0, state, ForceJacobian(42, definite=True))
    x = term.deformables.initial_positions
    direction = np.random.default_rng(5).normal(size=x.shape)
    step = 1e-6
    change = (term.share @ (term.face_forces(x + step * direction, 0.0) - term.face_forces(x - step * direction, 0.0))
              ) / (2 * step)
    np.testing.assert_allclose(jacobian.product("x", direction.ravel()), change.ravel(), atol=1e-6 * np.abs(change).max())


def test_a_gas_balloon_breathes_keeping_kinetic_energy_plus_the_gas_potential_of_p_v_constant(tmp_path):
    """Released at 600 Pa over the outside, the ball swells past where its pressure meets the outside's and back;
    K + U stays put with U(V) = −P₀ V₀ ln(V/V₀) + P_out (V − V₀), the work of a gas at constant temperature."""
    plan = api.plan(balloon(tmp_path, f"{{gauge: {GAUGE}, gas: true, outside: {OUTSIDE}}}", duration=1.0))
    trajectory = api.simulate(plan)
    volume = volumes(plan, trajectory)
    start = volume[0]
    assert volume.max() > 1.3 * start  # past the equilibrium (P0 / P_out = 1.3 V0) and back
    mass = plan.model.bodies.mass
    kinetic = 0.5 * np.einsum("i,fij,fij->f", mass, trajectory.velocities, trajectory.velocities)
    gas = -(OUTSIDE + GAUGE) * start * np.log(volume / start) + OUTSIDE * (volume - start)
    total = kinetic + gas
    assert np.abs(total - total[0]).max() < 1e-6 * np.abs(gas).max()
    assert trajectory.ledger["conservation"]["momentum"]["conserved"]


def test_a_gas_balloon_slowed_by_drag_settles_where_its_pressure_meets_the_outsides(tmp_path):
    """P V = P₀ V₀ and P = P_out at rest: V = (P_out + p₀) V₀ / P_out = 1.3 V₀."""
    plan = api.plan(balloon(tmp_path, f"{{gauge: {GAUGE}, gas: true, outside: {OUTSIDE}}}", duration=2.0,
                            extra="fields: [{type: drag, model: linear, coefficient: 0.1}]"))
    volume = volumes(plan, api.simulate(plan))
    assert volume[-1] / volume[0] == pytest.approx((OUTSIDE + GAUGE) / OUTSIDE, rel=1e-4)


def cushion(tmp_path, pressure, *, extra="", duration=2.0):
    """A closed cube of cloth (0.3 m, each face cut into 32 triangles, 0.5 kg/m²) with ``pressure``, no gravity."""
    cube = trimesh.creation.box(extents=(1.0, 1.0, 1.0)).subdivide().subdivide()
    cube.export(tmp_path / "cube.obj")
    (tmp_path / "cushion.yaml").write_text(f"""name: cushion
duration: {duration}
fps: 20
solver: {{method: DOP853, rtol: 1.0e-9, atol: 1.0e-11}}
bodies:
  - {{name: cushion, type: cloth, mesh: {{file: cube.obj, scale: 0.3}}, density: 0.5, pressure: {pressure},
     collide: false}}
{extra}""")
    return api.load_scene(tmp_path / "cushion.yaml")


def test_a_squeezed_gas_cube_pushes_back_as_p_v_constant_says(tmp_path):
    """A gas cube squeezed (or let out) to a volume V pushes on its walls with the gauge P₀ V₀ / V − P_out: over a
    closed surface Σ F·x = 3 p V (each triangle's p A n shared by its corners; ∮ x·n dA = 3 V), so the virial of the
    vertex forces is 3 (P₀ V₀ − P_out V), at every squeeze and whatever the shape."""
    plan = api.plan(cushion(tmp_path, f"{{gauge: {GAUGE}, gas: true, outside: {OUTSIDE}}}"))
    term = pressure_term(plan)
    rest = term.deformables.initial_positions
    start = term.volumes(rest)[0]
    assert start == pytest.approx(0.3**3, rel=1e-12)
    dent = np.random.default_rng(7).normal(scale=0.01, size=rest.shape)  # not a cube any more
    for scale in (0.5, 0.8, 1.0, 1.3, 1.6):
        x = scale * rest + dent
        volume = term.volumes(x)[0]
        force = term.share @ term.face_forces(x, 0.0)
        virial = np.einsum("vi,vi->", force, x)
        assert virial == pytest.approx(3 * ((OUTSIDE + GAUGE) * start - OUTSIDE * volume), rel=1e-9), scale
    # squeezed below P₀ V₀ / P_out it pushes out, let out beyond it pulls in
    assert (OUTSIDE + GAUGE) * start - OUTSIDE * term.volumes(0.5 * rest)[0] > 0
    assert (OUTSIDE + GAUGE) * start - OUTSIDE * term.volumes(1.6 * rest)[0] < 0


def test_an_inflated_gas_cube_settles_at_the_volume_where_its_pressure_meets_the_outsides(tmp_path):
    """The cube of cloth, no springs, released at 600 Pa over the outside and slowed by drag, bulges into a cushion
    and settles where P₀ V₀ / V = P_out: V = 1.3 V₀, whatever shape it takes."""
    plan = api.plan(cushion(tmp_path, f"{{gauge: {GAUGE}, gas: true, outside: {OUTSIDE}}}",
                            extra="fields: [{type: drag, model: linear, coefficient: 0.1}]"))
    volume = volumes(plan, api.simulate(plan))
    assert volume[-1] / volume[0] == pytest.approx((OUTSIDE + GAUGE) / OUTSIDE, rel=1e-4)


def test_a_held_gauge_swells_a_springy_ball_with_its_energy_kept_and_a_pump_does_work(tmp_path):
    """600 Pa at once: the ball rings about the volume where its springs hold the pressure, its energy kept with
    the potential −p ΔV. The same 600 Pa pumped in over 0.5 s: the ball swells slowly to that volume (the middle
    of the ringing one's swing) and stays, and the pump's work is reported as such."""
    held = api.plan(balloon(tmp_path, f"{{gauge: {GAUGE}}}", structural=2000.0, duration=0.75))
    trajectory = api.simulate(held)
    ringing = volumes(held, trajectory) / volumes(held, trajectory)[0]
    assert ringing.max() > 1.05
    energy = trajectory.ledger["conservation"]["energy"]
    assert energy["conserved"] and energy["drift"] < 1e-6  # −p ΔV accounts for the pressure's work
    pumped = api.plan(balloon(tmp_path, f"[{{time: 0, value: 0}}, {{time: 0.5, value: {GAUGE}}}]".join(
        ("{gauge: ", "}")), structural=2000.0, duration=0.75))
    trajectory = api.simulate(pumped)
    swell = volumes(pumped, trajectory) / volumes(pumped, trajectory)[0]
    assert np.all(np.diff(swell[:10]) > 0) and swell[1] < 1.01  # slowly, from 0 Pa
    middle = (ringing.min() + ringing.max()) / 2
    assert swell[-5:] == pytest.approx(np.full(5, middle), rel=0.01)
    energy = trajectory.ledger["conservation"]["energy"]
    assert not energy["conserved"] and "pressure does work that no potential accounts for" in energy["reason"]


def test_pressure_needs_a_closed_consistently_wound_surface(tmp_path):
    with pytest.raises(SceneError, match=r"bodies\[0\]\.pressure: 'sheet' cannot hold a pressure: its surface is "
                                         r"open: 16 edges border one triangle only"):
        api.parse_scene("""name: open
bodies:
  - {name: sheet, type: cloth, grid: {size: [1, 1], resolution: [5, 5]}, mass: 1,
     structural: {stiffness: 100}, pressure: {gauge: 100}}
""", filename="open.yaml")
    mesh = trimesh.creation.icosphere(subdivisions=1)
    faces = mesh.faces.copy()
    faces[0] = faces[0][::-1]  # one triangle wound the other way
    trimesh.Trimesh(mesh.vertices, faces, process=False).export(tmp_path / "ball.obj")
    (tmp_path / "bad.yaml").write_text("""name: bad
bodies:
  - {name: ball, type: cloth, mesh: {file: ball.obj}, mass: 1, structural: {stiffness: 100}, pressure: {gauge: 1}}
""")
    with pytest.raises(SceneError, match="not wound consistently: 3 edges run the same way"):
        api.load_scene(tmp_path / "bad.yaml")
    with pytest.raises(SceneError, match="with gas, gauge is the pressure at the start"):
        api.parse_scene("""name: g
bodies:
  - {name: ball, type: cloth, mesh: {file: ball.obj}, mass: 1, pressure: {gauge: [{time: 0, value: 1}], gas: true}}
""", filename="g.yaml", path=tmp_path / "g.yaml")


def test_the_bundled_beach_ball_falls_as_a_point_mass_until_it_lands():
    """Pressure adds no net force: the ball's centre of mass falls at g (and drifts at 0.6 m/s) until its lowest
    vertex reaches the floor, 0.95 m below; backward Euler's first-order error in free fall is g h t / 2."""
    loaded = api.load_scene(SCENES / "beach_ball.yaml", ["duration=0.4", "fps=10"])
    plan = api.plan(loaded)
    trajectory = api.simulate(plan)
    mass = plan.model.bodies.mass
    centre = np.einsum("i,fij->fj", mass, trajectory.positions) / mass.sum()
    t = trajectory.times
    h = plan.steps.dt  # [s]
    np.testing.assert_allclose(centre[:, 1], 1.2 - 9.81 * t**2 / 2, atol=9.81 * h * t[-1])
    np.testing.assert_allclose(centre[:, 0], 0.6 * t, atol=1e-9)
    assert trajectory.positions[:, :, 1].min() > 0  # not landed yet


def test_a_step_too_long_for_the_gas_is_refused_before_the_run_naming_the_gas():
    """Backward Euler takes pressure from the start of each step: past ω dt = 2 for the gas's breathing it would
    blow up (it used to, naming a vertex); it is refused before anything moves, with the step that holds it."""
    from animbatch.errors import SimulationError

    loaded = api.load_scene(SCENES / "beach_ball.yaml", ["solver.dt=0.00104167"])
    with pytest.raises(SimulationError, match=r"cannot follow the gas in 'ball' breathing .* Use solver\.dt ≤ "
                                              r"[0-9.e-]+ s, or an adaptive method .* Nothing was simulated"):
        api.simulate(loaded)
